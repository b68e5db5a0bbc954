"""The lab's process for headless runs (:mod:`armlab.app.arm.off_server`): a page's
comparison runs in a spawned process, not the server's; calls beyond the bound are told
to try again; a process that is killed is replaced and the server goes on."""

from __future__ import annotations

import os
import signal
import time

import pytest
from _helpers import wait_for

from armlab.app.arm import off_server
from armlab.control.experiments.contact import compare_contact, run_contact
from armlab.control.params import DEFAULT
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.slow  # (a spawned interpreter, and two contact runs)

#: s a spawned interpreter may take to import the lab on a busy machine
START_S = 120.0


def test_a_comparison_runs_in_another_process_with_the_experiments_figures():
    model = load_robot("receptionist_arm")
    wall = {"wall": 0.12, "depth": 0.08, "stiffness": 2e4, "damping": 50.0}
    there = off_server.submit(off_server.compare_on_sim, model, DEFAULT, wall)
    assert off_server.submit(os.getpid).result(timeout=START_S) != os.getpid()
    here = compare_contact(lambda c: run_contact(
        model, lambda m, q0: SimBackend(m, q0=q0), DEFAULT, controller=c, **wall))
    assert there.result(timeout=START_S)["rows"] == here["rows"]


def test_calls_past_the_bound_are_refused_and_a_killed_process_is_replaced(monkeypatch):
    off_server.submit(os.getpid).result(timeout=START_S)  # (made)
    monkeypatch.setattr(off_server, "MAX_QUEUED", 2)
    held = [off_server.submit(time.sleep, 0.5) for _ in range(2)]
    with pytest.raises(ValueError, match="try again"):
        off_server.submit(time.sleep, 0.5)
    for f in held:
        f.result(timeout=START_S)
    child = off_server.submit(os.getpid).result(timeout=START_S)
    os.kill(child, signal.SIGKILL)
    answers: list[object] = []

    def replaced() -> bool:  # a call fails once it is seen dead, then one is answered anew
        try:
            answers.append(off_server.submit(os.getpid).result(timeout=START_S))
        except (ValueError, RuntimeError) as exc:
            answers.append(str(exc))
        return isinstance(answers[-1], int)

    wait_for(replaced, START_S, lambda: f"a new process (answers: {answers})")
    assert answers[-1] not in (child, os.getpid())
    assert all(isinstance(a, int) or "ended" in a for a in answers), answers
