"""Save run after the hand's, the quadruped's and the servo-arm lesson's commands saves that
run whole (issue 51, item 1): its commands, its label, the figures the lesson reports for
it (never another run's), from its first command to its end and a settling tail, even
after the loop's record has moved past it; and the compliance lesson's CSV download is the
run Save run saves (item 2). The lessons run headless on loop time (``realtime=False``) on
a real viser server on a free port; every wait polls loop time."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest
from _helpers import served_lesson, wait_for

from armlab.app.lessons import LessonContext
from armlab.app.lessons.arm import HISTORY_S
from armlab.app.lessons.run_files import FINISHED, LIVE, UNFINISHED
from armlab.control.run_track import LEAD_S, TAIL_S
from armlab.control.runs import read_run

pytestmark = pytest.mark.slow  # each waits out a loop's record window of loop time


def saved(lesson, robot: str):
    name, data = lesson.runs.save_file()
    assert name.endswith(".armlab-run.zip")
    return read_run(data, robot=robot, name=name)


def wait_loop(loop, until: float, what: str, timeout: float = 240.0) -> None:
    """Poll the loop's time until it passes ``until`` s (its faults said)."""
    wait_for(lambda: loop.status.t > until or bool(getattr(loop.status, "fault", "")),
             timeout, what)
    assert not getattr(loop.status, "fault", ""), loop.status.fault


def finished(lesson, label: str, timeout: float = 240.0) -> None:
    wait_for(lambda: lesson.runs.run_label == label and lesson.runs.going_on is None,
             timeout, f"the run {label!r} to be over")


def check_span(run, *, t0: float, period: float) -> None:
    """The file is the run: from its lead before the first command to its end and tail,
    every period, not the record's window saved later."""
    about = run.extra["run"]
    assert about["state"] == FINISHED and about["label"] != LIVE
    assert run.t[0] <= t0 + 1e-9 and run.t[0] >= t0 - LEAD_S - period
    end = about["finished_at_s"]
    assert end + TAIL_S - 2 * period <= run.t[-1] <= end + TAIL_S + 2 * period
    assert np.allclose(np.diff(run.t), period, rtol=1e-4)  # none lost
    assert "lost_samples" not in about and "cut" not in about


# ----------------------------------------------------------------------------- the hand


@pytest.fixture
def hand():
    from armlab.app.lessons.hand import build

    with served_lesson(build, LessonContext(realtime=False)) as handle:
        yield handle


def test_a_grasp_saved_after_the_hands_record_moved_on_is_the_grasp(hand):
    from armlab.app.lessons.hand import GRASP_RUN, OPEN_RUN

    loop = hand.loop
    t0 = loop.status.t
    hand.close_hand()
    finished(hand, GRASP_RUN)
    shown = hand.run_figures()  # what the page (and a class overview) shows for it
    assert shown["grasp_held"] == 1.0
    window_s = loop.capacity * loop.dt
    wait_loop(loop, loop.status.t + window_s + TAIL_S, "the grasp to leave the record")
    assert loop.snapshot()["t"][0] > hand.runs.run_t0  # the record holds none of it
    run = saved(hand, "hand")
    assert run.extra["run"]["label"] == GRASP_RUN
    assert [c["kind"] for c in run.commands] == ["CloseHand"]
    check_span(run, t0=hand.runs.run_t0, period=loop.dt)
    assert t0 <= run.commands[0]["t"] == hand.runs.run_t0
    assert run.figures == hand.grasp_figures()
    assert run.figures["grasp_force_n"] == shown["grasp_force_n"]
    assert run.figures["grasp_peak_n"] == shown["grasp_peak_n"]
    assert run.figures["grasp_held"] == shown["grasp_held"]
    assert set(run.lesson_signals) >= {"current", "force"}
    # the grasp's rows are its own: the force rose to the limit during it
    assert np.nanmax(run.signals["force"]) >= 0.9 * loop.params.force_limit
    # an open is a run of its own: no grasp's figure in its file
    hand.open_hand()
    finished(hand, OPEN_RUN)
    run = saved(hand, "hand")
    assert run.extra["run"]["label"] == OPEN_RUN and run.figures == {}
    assert [c["kind"] for c in run.commands] == ["OpenHand"]


def test_a_grasp_saved_before_it_settled_is_marked_unfinished(hand):
    from armlab.app.lessons.hand import GRASP_RUN

    hand.close_hand()
    run = saved(hand, "hand")  # at once: the fingers have not touched yet
    about = run.extra["run"]
    assert about["label"] == GRASP_RUN and about["state"] == UNFINISHED
    assert run.figures == {}


# ------------------------------------------------------------------------ the quadruped


@pytest.fixture
def quadruped():
    from armlab.app.lessons.quadruped import build

    with served_lesson(build, LessonContext(robot="quadruped", realtime=False)) as handle:
        yield handle


def test_a_walk_saved_after_the_record_moved_on_is_the_walk_with_its_eq41_error(quadruped):
    lesson, loop = quadruped, quadruped.loop
    lesson.walk("forward")
    label = f"{lesson.spec.gait} forward"
    wait_for(lambda: loop.status.walking and not loop.status.standing_up, 120.0, "walking")
    start = loop.state.phase
    wait_for(lambda: loop.state.phase >= start + 1.0, 120.0, "a gait cycle")
    lesson.walk("left")  # a turn while it walks: a command inside the same walk
    t_turn = loop.status.t
    wait_loop(loop, t_turn + 1.0, "the turn")
    assert lesson.runs.going_on == label
    lesson.stop()
    finished(lesson, label)
    shown = lesson.run_figures()["eq41_error_pct"]
    assert shown is not None and math.isfinite(shown)
    run_t0 = lesson.runs.run_t0
    wait_loop(loop, loop.status.t + 20.0 + TAIL_S, "the walk to leave the 20 s record")
    assert loop.snapshot()["t"][0] > run_t0
    run = saved(lesson, "quadruped")
    assert run.extra["run"]["label"] == label
    kinds = [c["kind"] for c in run.commands]
    assert kinds[0] == "Walk" and kinds.count("Walk") == 2 and "StopWalking" in kinds
    assert run.commands[0]["command"] == "forward" and run.commands[1]["command"] == "left"
    period = float(np.median(np.diff(run.t)))
    check_span(run, t0=run_t0, period=period)
    assert run.figures == {"eq41_error_pct": shown}
    assert np.isfinite(run.signals["q"]).all()  # the servos' readings, the whole walk


# ----------------------------------------------------------------- the servo-arm lesson


@pytest.fixture
def arm():
    from armlab.app.lessons.arm import build

    with served_lesson(build, LessonContext(robot="open_manipulator_x", realtime=False)) \
            as handle:
        wait_for(lambda: handle.loop.status.active, 60.0, "the arm to hold")
        yield handle


def test_a_joint_move_and_home_saved_later_are_those_moves(arm):
    from armlab.app.lessons.arm import HOME_RUN

    loop, period = arm.loop, float(arm.loop.params.period)
    arm.move_joint(1, math.radians(20.0))
    label = f"joint {arm.model.joint_names[1]}"
    finished(arm, label)
    t0 = arm.runs.run_t0
    wait_loop(loop, loop.status.t + HISTORY_S + TAIL_S, "the move to leave the record")
    assert loop.recorder.snapshot()["t"][0] > t0
    run = saved(arm, arm.model.name)
    assert run.extra["run"]["label"] == label
    (move,) = run.commands
    assert move["kind"] == "RunTrajectory" and move["t"] == t0
    check_span(run, t0=t0, period=period)
    assert run.figures == {}  # a move measures nothing (the page shows no figure)
    j = run.joint_names.index(arm.model.joint_names[1])
    assert math.degrees(run.signals["q"][-1, j]) == pytest.approx(20.0, abs=2.0)
    arm.home()
    finished(arm, HOME_RUN)
    run = saved(arm, arm.model.name)
    assert run.extra["run"]["label"] == HOME_RUN and run.figures == {}
    assert [c["kind"] for c in run.commands] == ["RunTrajectory"]


def test_a_target_drag_is_one_run_over_when_let_go(arm):
    from armlab.app.lessons.arm import TARGET_RUN

    hand = arm.model.fk(arm.loop.recorder.snapshot(0.1)["q"][-1])[:3, 3]
    for k in range(1, 4):  # a drag: several moves of the target
        arm.set_target(hand + np.array([0.0, 0.0, 0.005 * k]))
    assert arm.runs.going_on == TARGET_RUN
    arm.target_released()
    run = saved(arm, arm.model.name)
    assert run.extra["run"]["label"] == TARGET_RUN
    assert [c["kind"] for c in run.commands] == ["SetTarget"] * 3
    assert run.figures == {}


def test_a_push_saved_later_has_the_figures_the_push_tab_showed(arm):
    from armlab.app.lessons.arm_controls import PUSH_RUN

    loop, period = arm.loop, float(arm.loop.params.period)
    arm.controls.push()
    finished(arm, PUSH_RUN)
    push, figures = arm.controls.push_figures
    assert push is arm.controls.last_push
    shown = arm.controls.pushes.result.content
    assert f"**{figures['hand_gave_way_cm']:.1f} cm**" in shown
    wait_loop(loop, loop.status.t + HISTORY_S + TAIL_S, "the push to leave the record")
    run = saved(arm, arm.model.name)
    assert run.extra["run"]["label"] == PUSH_RUN
    assert [c["kind"] for c in run.commands] == ["Push"]
    check_span(run, t0=push.t0, period=period)
    assert run.figures == figures and run.figures["hand_gave_way_cm"] > 0.0


# ------------------------------------------------ the compliance lesson's CSV download


@pytest.fixture
def compliance():
    from armlab.app.lessons.compliance import build

    with served_lesson(build, LessonContext(realtime=False)) as handle:
        wait_for(lambda: handle.rig.loop.status.active, 60.0, "the arm to hold")
        yield handle


def csv_rows(data: bytes) -> tuple[list[str], list[str], np.ndarray]:
    lines = data.decode().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    rows = list(csv.reader(io.StringIO("\n".join(ln for ln in lines
                                                 if not ln.startswith("#")))))
    body = np.array([[float(v) if v else np.nan for v in r] for r in rows[1:]])
    return head, rows[0], body


def test_the_csv_download_is_the_run_save_run_saves(compliance):
    lesson, loop = compliance, compliance.rig.loop
    name, data = lesson.csv_bytes()  # no run yet: the live window, labelled so
    head, _, _ = csv_rows(data)
    assert "live-window" in name and any(f"run: {LIVE} ({LIVE})" in ln for ln in head)
    lesson.run_line()
    wait_for(lambda: loop.status.trajectory is not None, 60.0, "the line to run")
    name, data = lesson.csv_bytes()  # while it runs: up to now, marked unfinished
    head, _, body = csv_rows(data)
    assert "thesis-line" in name and any(f"({UNFINISHED})" in ln for ln in head)
    wait_for(lambda: lesson.runs.run_label == "thesis line" and lesson.runs.going_on is None,
             240.0, "the line to end")
    wait_for(lambda: lesson.runs._run.track.closed, 240.0, "the line's settling tail")
    from armlab.app.lessons import compliance as module

    wait_loop(loop, loop.status.t + module.HISTORY_S + 1.0, "the line to leave the record")
    run = saved(lesson, "receptionist_arm")
    name, data = lesson.csv_bytes()
    head, cols, body = csv_rows(data)
    assert any(f"run: thesis line ({FINISHED})" in ln for ln in head)
    assert any("kp=" in ln and "law=" in ln for ln in head)
    assert cols[0] == "t_s" and cols[1] == "wall_time_s"
    # the same rows as the saved run: its span, every sample
    assert len(body) == len(run.t)
    np.testing.assert_allclose(body[:, 0], run.t, rtol=1e-9, atol=1e-6)
    j = cols.index("q_theta2_rad")
    k = run.joint_names.index("theta2")
    np.testing.assert_allclose(body[:, j], run.signals["q"][:, k], rtol=1e-5, atol=1e-9)
