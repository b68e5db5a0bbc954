"""Exercises whose function carries a state from call to call (the disturbance observer's
filter state z, the environment impedance's θ_env and θ̇_env; issue 50 item 2): a case
calls the function in a row, each call given the state the one before returned, and
compares the whole sequence. A state that resets every call, is never returned, is the
wrong output, or is kept apart from the arguments fails that case by name with a hint
that says so; the lab's own functions and a correct hand-written one pass it; the
planted law mistakes fail it without a state hint (the state is not their mistake).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from test_exercises import reference_file

from armlab.control.compliance import environment_step
from armlab.exercises import get
from armlab.exercises.control_set import observer_step
from armlab.exercises.core import RunCase, judge_run

STATE_HINT = "hint (state from call to call)"


def _sequence(name: str) -> RunCase:
    (case,) = [c for c in get(name).cases()
               if isinstance(c, RunCase) and c.name.startswith("in sequence")]
    return case


def _obs_returns_z_unchanged(z, current, qd, j_n, kt_n, g, dt):
    return z, observer_step(z, current, qd, j_n, kt_n, g, dt)[1]


def _obs_resets(z, current, qd, j_n, kt_n, g, dt):
    return observer_step(0.0, current, qd, j_n, kt_n, g, dt)


def _obs_estimate_as_state(z, current, qd, j_n, kt_n, g, dt):
    tau = observer_step(z, current, qd, j_n, kt_n, g, dt)[1]
    return tau, tau


class _ObsOwnState:
    """Keeps z itself, ignoring the z passed in."""

    def __init__(self) -> None:
        self.z = 0.0

    def __call__(self, z, current, qd, j_n, kt_n, g, dt):
        self.z, tau = observer_step(self.z, current, qd, j_n, kt_n, g, dt)
        return self.z, tau


def _env_returns_state_unchanged(m, d, k, kf, tau, q, qd, dt):
    return q, qd, environment_step(m, d, k, kf, tau, q, qd, dt)[2]


def _env_resets(m, d, k, kf, tau, q, qd, dt):
    return environment_step(m, d, k, kf, tau, 0.0 * q, 0.0 * qd, dt)


@pytest.mark.parametrize("name", ["disturbance_observer", "environment_impedance"])
def test_the_labs_own_function_passes_the_sequence(name):
    outcome = judge_run(_sequence(name), get(name).reference)
    assert outcome.passed, outcome.text


@pytest.mark.parametrize("name,planted,says", [
    ("disturbance_observer", _obs_returns_z_unchanged, "your z comes back as it went in"),
    ("disturbance_observer", _obs_resets, "does not filter from the z it is given"),
    ("disturbance_observer", _obs_estimate_as_state,
     "your new z (the filter's state) is the lab's τ_dis (the estimate)"),
    ("disturbance_observer", _ObsOwnState(), "does not filter from the z it is given"),
    ("environment_impedance", _env_returns_state_unchanged,
     "your θ_env and θ̇_env come back as they went in"),
    ("environment_impedance", _env_resets, "does not work from the θ_env and θ̇_env"),
], ids=["z-unchanged", "z-reset", "estimate-as-z", "own-z", "env-unchanged", "env-reset"])
def test_a_state_carried_wrong_fails_the_sequence_with_its_hint(name, planted, says):
    outcome = judge_run(_sequence(name), planted)
    assert not outcome.passed
    assert outcome.lines[0].startswith(f"FAIL  {_sequence(name).name}")
    assert STATE_HINT in outcome.text and says in outcome.text, outcome.text


@pytest.mark.parametrize("name", ["disturbance_observer", "environment_impedance"])
def test_a_planted_law_mistake_is_not_told_it_is_the_state(name):
    ex = get(name)
    for mistake in ex.mistakes:
        outcome = judge_run(_sequence(name), mistake.fn)
        if not outcome.passed:
            assert STATE_HINT not in outcome.text, (mistake.name, outcome.text)
            assert "the step itself is off" in outcome.text


#: a student's observer, written by hand, right but for the state it returns
STUDENT = '''\
EXERCISE = "disturbance_observer"
import math


def observer_step(z, current, qd, j_n, kt_n, g_dis, dt):
    a = 1.0 - math.exp(-g_dis * dt)
    u = kt_n * current + g_dis * j_n * qd
    z_new = z + a * (u - z)
    return RETURNED, z_new - g_dis * j_n * qd
'''


def _check(path: Path) -> tuple[subprocess.CompletedProcess, dict]:
    done = subprocess.run([sys.executable, "-m", "armlab.app", "check", path.name,
                           "--results", "results.json"], cwd=path.parent,
                          capture_output=True, text=True, timeout=300)
    return done, json.loads((path.parent / "results.json").read_text())


@pytest.mark.slow
def test_armlab_check_names_the_sequence_case_for_a_state_never_returned(tmp_path):
    """Through the real ``armlab check`` (the student's file in its child process): the
    hand-written observer passes every case; returning the old z fails the sequence case
    with its hint."""
    path = tmp_path / "observer.py"
    path.write_text(STUDENT.replace("RETURNED", "z_new"))
    done, results = _check(path)
    assert done.returncode == 0, done.stdout
    name = _sequence("disturbance_observer").name
    assert results["score"] == len(get("disturbance_observer").cases())
    assert any(name in json.dumps(t, ensure_ascii=False) for t in results["tests"])

    path.write_text(STUDENT.replace("RETURNED", "z"))
    done, results = _check(path)
    assert done.returncode == 1
    line = next(ln for ln in done.stdout.splitlines() if name in ln)
    assert line.startswith("FAIL  ")
    assert "your z comes back as it went in" in done.stdout
    assert "Traceback" not in done.stdout + done.stderr


@pytest.mark.slow
def test_the_reference_as_a_students_file_passes_through_the_boundary(tmp_path):
    done, results = _check(reference_file(tmp_path, "environment_impedance"))
    assert done.returncode == 0, done.stdout
    assert results["score"] == len(get("environment_impedance").cases())
