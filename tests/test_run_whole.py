"""Save run saves the last run whole (issue 51, item 1): a step saved a minute after it
holds the step's command, its own figures (those the page showed) and its time; a save
while a run goes on says so; with no run the live window is labelled so; the file says
who, which law, which backend, the gain changes and the lab's version. The lessons run
headless on loop time (``realtime=False``); the waits poll loop time."""

from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np
import pytest
from _helpers import served_lesson, wait_for

from armlab.app.lessons import LessonContext
from armlab.app.lessons.compliance import build
from armlab.app.lessons.run_files import FINISHED, LIVE, UNFINISHED
from armlab.control.recorder import Recorder
from armlab.control.run_track import MAX_RUN_ROWS, TAIL_S, RunTrack
from armlab.control.runs import lab_version, read_run

ROBOT = "receptionist_arm"


@pytest.fixture
def lesson():
    with served_lesson(build, LessonContext(realtime=False, who=lambda cid: f"Ada {cid}")) \
            as handle:
        wait_for(lambda: handle.rig.loop.status.active, 60.0, "the arm to hold")
        yield handle


def saved(lesson, by: int | None = None):
    name, data = lesson.runs.save_file(by=by)
    return read_run(data, robot=ROBOT, name=name)


def loop_time(lesson) -> float:
    return lesson.rig.loop.status.t


@pytest.mark.slow
def test_a_step_saved_a_minute_later_is_the_step_with_its_own_figures(lesson):
    loop = lesson.rig.loop
    lesson.gains.params  # noqa: B018  (the gains the arm runs)
    lesson.run_step()
    exp = lesson.experiment
    wait_for(lambda: exp.done, 120.0, "the step to be measured")
    shown = lesson.measured_pd  # what the page showed beside the Step button
    assert shown is not None and shown.overshoot_pct is not None
    # a gain change after the step (and its tail) is not in the step's file
    wait_for(lambda: lesson.runs._run.track.closed, 60.0, "the step's settling tail")
    kp = loop.params.kp
    lesson._apply_params(dataclasses.replace(loop.params, kp=kp + 1.0))
    wait_for(lambda: loop_time(lesson) > exp.t0 + 60.0, 300.0, "a minute of loop time")
    run = saved(lesson, by=7)
    about = run.extra["run"]
    assert about["state"] == FINISHED and about["label"].startswith("step ")
    # its commands hold the step, at its time
    steps = [c for c in run.commands if c["kind"] == "RunTrajectory"]
    assert len(steps) == 1 and steps[0]["t"] == pytest.approx(exp.t0)
    # its time covers it: from before the step to its end and the settling tail, no more
    period = loop.params.period
    assert run.t[0] <= exp.t0 <= exp.ready_at <= run.t[-1]
    assert run.t[-1] <= about["finished_at_s"] + TAIL_S + 2 * period
    assert run.t[-1] < exp.t0 + 30.0  # not the recorder's window, a minute later
    assert np.allclose(np.diff(run.t), period, rtol=1e-6)  # every period, none lost
    assert "lost_samples" not in about and "cut" not in about
    # its own figures, equal to what the page showed; none of another run's
    assert run.figures["overshoot_pct"] == shown.overshoot_pct
    assert run.figures["settling_s"] == shown.settling_time_s
    assert run.figures["peak_time_s"] == shown.peak_time_s
    assert "max_error_deg" not in run.figures
    assert run.params["kp"] == kp  # the gains the step ran with
    changes = run.extra["gain_changes"]
    assert changes == []  # the change came after the run's end
    assert run.extra["law"] == {"by": "lab", "law": run.params["law"]}
    assert run.extra["backend"]["kind"] == "simulated"
    assert run.extra["student"] == "Ada 7"
    assert run.lab_version == lab_version()


@pytest.mark.slow
def test_a_save_while_the_run_goes_on_is_marked_unfinished(lesson):
    lesson.run_line()
    loop = lesson.rig.loop
    wait_for(lambda: loop.status.trajectory is not None, 60.0, "the line to run")
    run = saved(lesson)
    about = run.extra["run"]
    assert about["state"] == UNFINISHED and about["label"] == "thesis line"
    assert run.figures == {}  # nothing measured yet: no figure of another run
    assert [c["kind"] for c in run.commands][:1] == ["RunTrajectory"]
    assert run.t[-1] <= loop_time(lesson)
    # a gain changed during the run: in its file, with its time (seen at the lesson's
    # tick: one is made here, at once, rather than waiting for the publisher's)
    kv = loop.params.kv + 0.5
    before = loop_time(lesson)
    lesson._apply_params(dataclasses.replace(loop.params, kv=kv))
    changed_at = loop_time(lesson)
    lesson.runs.tick()
    wait_for(lambda: lesson.experiment.done, 120.0, "the line to end")
    run = saved(lesson)
    assert run.extra["run"]["state"] == FINISHED
    (change,) = run.extra["gain_changes"]
    assert change["kv"] == kv and before <= change["t"] <= changed_at + 0.5
    assert run.params["kv"] == kv - 0.5  # the gains the run began with
    assert set(run.figures) == {"max_error_deg"}
    assert run.figures["max_error_deg"] == lesson.run_figures()["max_error_deg"]


def test_with_no_run_the_live_window_is_saved_and_labelled_so(lesson):
    wait_for(lambda: len(lesson.rig.loop.recorder) > 10, 60.0, "a few samples")
    run = saved(lesson)
    assert run.extra["run"]["state"] == LIVE and run.extra["run"]["label"] == LIVE
    assert run.figures == {}
    assert "student" not in run.extra  # saved from Python: no page


def test_a_run_keeps_only_new_rows_and_stops_at_its_bound():
    rec = Recorder(1, 100)
    for k in range(10):
        rec.append(k * 0.1, {"q": np.array([k])})
    track = RunTrack(rec, t0=0.9, period=0.1)  # the lead: 0.5 s before
    assert track.rows == 6
    for k in range(10, 150):  # past the recorder's window, pulled as it goes
        rec.append(k * 0.1, {"q": np.array([k])})
        if k % 50 == 0:
            track.pull()
    snap = track.snapshot()
    assert np.allclose(snap["t"], np.arange(4, 150) * 0.1)
    assert track.lost == 0 and not track.finished
    track.finish(14.9)
    for k in range(150, 200):
        rec.append(k * 0.1, {"q": np.array([k])})
    track.pull()
    assert track.closed and not track.cut
    assert snap["t"][0] == pytest.approx(0.4)
    assert track.snapshot()["t"][-1] == pytest.approx(14.9 + TAIL_S)
    # the bound: a run that goes on is cut at MAX_RUN_ROWS (or MAX_RUN_S) and says so
    big = Recorder(1, 2 * MAX_RUN_ROWS)
    long = RunTrack(big, t0=0.0, period=0.001)
    for k in range(MAX_RUN_ROWS + 10):
        big.append(k * 0.001, {"q": np.array([0.0])})
    long.pull()
    assert long.rows == MAX_RUN_ROWS and long.cut and long.closed
    # rows the recorder dropped before a pull are counted, never invented
    small = Recorder(1, 10)
    late = RunTrack(small, t0=0.0, period=0.1)
    for k in range(30):
        small.append(k * 0.1, {"q": np.array([0.0])})
    late.pull()
    assert late.lost == 20 and late.rows == 10


@pytest.mark.slow
def test_the_students_law_is_in_the_file_with_its_hash(tmp_path):
    from test_serve_exercise import law_file

    from armlab.app.lab.server import Lab, ServeOptions

    path = law_file(tmp_path)
    with Lab(ServeOptions(http_port=0, exercise=str(path), realtime=False)) as lab:
        lesson = lab.lesson
        wait_for(lambda: lesson.rig.loop.status.active, 60.0, "the arm to hold")
        lesson.run_step()
        wait_for(lambda: lesson.experiment.done, 120.0, "the step to be measured")
        run = saved(lesson)
    law = run.extra["law"]
    data = path.read_bytes()
    assert law["by"] == "student" and law["file"] == path.name
    assert law["sha256"] == hashlib.sha256(data).hexdigest()
    assert law["source"] == data.decode()
    assert law["exercise"] == "compliance_law"
    assert run.extra["run"]["label"].startswith("step ")
    # its figures, if the step was measured (a loaded machine may hold the student's law
    # past its budget, and the step then measures nothing): the step's own
    assert set(run.figures) <= {"overshoot_pct", "peak_time_s", "settling_s", "rise_time_s",
                                "step_joint"}
    assert all(v is None or math.isfinite(v) for v in run.figures.values())


def test_the_backend_and_law_facts_say_what_they_know():
    from types import SimpleNamespace

    from armlab.app.lessons.run_facts import GainLog, backend_json, law_json

    serial = SimpleNamespace(map=SimpleNamespace(servo="RX-24F", joints=[
        SimpleNamespace(servo_id=i) for i in (1, 2, 3)]), bus=SimpleNamespace(baud=1_000_000))
    assert backend_json("serial", port="/dev/ttyUSB0", backend=serial) == {
        "kind": "serial", "port": "/dev/ttyUSB0", "servos": "RX-24F", "servo_ids": [1, 2, 3],
        "baud": 1_000_000}
    sim = SimpleNamespace(specs=[SimpleNamespace(name="RX-24F")] * 3)
    assert backend_json("sim", backend=sim) == {"kind": "simulated", "servos": "RX-24F"}
    assert backend_json("sim") == {"kind": "simulated"}  # nothing claimed it does not know
    gone = SimpleNamespace(path="/nowhere/law.py", exercise=SimpleNamespace(name="x"))
    assert law_json(gone)["by"] == "student" and "sha256" not in law_json(gone)
    log = GainLog()
    log.see({"kp": 20.0, "kv": 5.0}, t=0.0)
    log.see({"kp": 20.0, "kv": 5.0}, t=1.0)
    log.see({"kp": 25.0, "kv": 5.0}, t=2.0)
    assert log.between(0.0) == [{"t": 2.0, "kp": 25.0}] and log.between(0.0, 1.5) == []


@pytest.mark.slow
def test_a_challenge_run_is_the_run_save_run_saves(lesson):
    """After a step challenge's run, Save run holds that run (from its restart, labelled
    as the challenge's), with the figures it was judged on."""
    from armlab.control.challenges import PRESETS

    lesson.run_challenge(PRESETS["step"])
    wait_for(lambda: lesson.challenges.pending is None and lesson.runs._run is not None
             and lesson.runs._run.label.startswith("challenge "), 300.0,
             "the challenge's run measured")
    run = saved(lesson)
    about = run.extra["run"]
    assert about["label"].startswith("challenge ") and about["state"] == FINISHED
    judged = lesson.challenges.results[-1][1]
    assert run.figures["overshoot_pct"] == judged["overshoot_pct"]
    assert run.t[0] <= lesson.run_start <= run.t[-1]
