"""The contact challenge (issue 54 item 4): "touch the wall with a peak of at most P and a
steady force within Y % of F", judged on the server from the wall's force the control loop
records every period.

Its run is ``armlab experiment contact``'s, started from the challenge's own state (the
simulated arm put back at the thesis line's start at rest, the wall kept in its world), so
the same gains score the same figures every time, whatever ran before, and agree with the
experiment's for the same wall (one function, ``contact_figures``, measures both).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from _helpers import wait_for

from armlab.app.arm.backends import make_backend
from armlab.app.lab.server import Lab, ServeOptions
from armlab.control.challenges import PRESETS, judge
from armlab.control.experiments.contact import run_contact
from armlab.control.params import DEFAULT
from armlab.control.runs import read_run
from armlab.kinematics.catalog import load_robot

CONTACT = PRESETS["contact"]
FIGURES = {"contact_peak_n": "peak_force_n", "contact_steady_n": "steady_force_n"}


def experiment(params) -> dict:  # noqa: ANN001
    """``armlab experiment contact`` for the challenge's wall, with ``params``."""
    spec = CONTACT.run
    return run_contact(load_robot("receptionist_arm"),
                       lambda model, **kw: make_backend("sim", model, **kw), params,
                       controller="compliance" if params.compliance else "pd",
                       wall=spec.wall_cm / 100.0, depth=spec.depth_cm / 100.0,
                       stiffness=spec.stiffness, damping=spec.damping)


def challenge_run(lesson, start) -> dict[str, float | None]:  # noqa: ANN001
    done = len(lesson.challenge_results())
    start()
    wait_for(lambda: len(lesson.challenge_results()) > done, 120,
             lambda: f"the contact challenge measured ({lesson.last_run_text!r})")
    return lesson.challenge_results()[-1][1]


@pytest.mark.slow
@pytest.mark.realtime
def test_the_same_gains_score_the_same_as_the_experiment_and_are_judged_on_the_server():
    with Lab(ServeOptions(http_port=0)) as lab:
        lesson, desk = lab.lesson, lab.challenges
        wait_for(lambda: lesson.rig.loop.status.t > 0.3, 60, "the arm running")
        desk.set_challenge(CONTACT)
        runs = [challenge_run(lesson, desk.run)]
        lesson.run_step(joint=1, step_deg=10.0)  # something else in between
        wait_for(lambda: lesson.experiment.done, 60, "a step of its own")
        runs.append(challenge_run(lesson, desk.run))
        ref = experiment(DEFAULT)
        # same gains, same figures, every bit; and the experiment's for the same wall (to
        # the last bits of the loop's time sums)
        assert {f: runs[0][f] for f in FIGURES} == {f: runs[1][f] for f in FIGURES}
        for figure, key in FIGURES.items():
            assert runs[0][figure] is not None
            assert runs[0][figure] == pytest.approx(ref[key], rel=1e-9), figure
        assert lesson.run_tags()["contact_peak_n"] == "contact"
        # Save run keeps the challenge's run with the wall's force (version 3), its
        # figures those judged; the page's export draws it, the CSV has its columns
        saved = read_run(lesson.runs.save_file()[1], robot="receptionist_arm")
        assert saved.version == 3 and saved.signals["f_contact"].shape == (len(saved.t), 1)
        assert saved.figures["contact_peak_n"] == runs[1]["contact_peak_n"]
        assert float(np.nanmax(saved.signals["f_contact_peak"])) == pytest.approx(
            runs[1]["contact_peak_n"], rel=1e-12)
        assert lesson.runs.export_file()[1].lower().startswith(b"<!doctype html")
        header = lesson.runs.run_csv()[1].splitlines()
        assert any(line.endswith("f_contact_N,f_contact_peak_N") for line in header[:4])
        desk.read()
        best = desk.log.best(CONTACT)
        assert best is not None and best[1] == judge(CONTACT, runs[1])
        assert not best[1].passed  # the lab's default gains press too lightly
        (steady,) = [c for c in best[1].checks if not c.ok]
        assert steady.threshold.figure == "contact_steady_n"
        # the wall the challenge put in goes once it is over (the tab's Wall is unticked)
        wait_for(lambda: lesson.rig.backend.wall_setting() is None, 30, "the wall gone")
        # K_env 32, D_env 20: the preset's passing gains, as the experiment measures them
        stiffer = replace(DEFAULT, k_env=32.0, d_env=20.0)
        lesson.gains.set_params(stiffer)
        wait_for(lambda: lesson.rig.loop.params == stiffer, 30, "the gains in force")
        firm = challenge_run(lesson, desk.run)
        ref = experiment(stiffer)
        assert firm["contact_steady_n"] == pytest.approx(ref["steady_force_n"], rel=1e-9)
        assert judge(CONTACT, firm).passed
        desk.read()
        assert desk.log.best(CONTACT)[1].passed
