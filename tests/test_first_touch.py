"""A real arm's first touch: on servos of every family, emulated behind a real
pseudo-terminal and started away from zero (``armlab emulate --pose``), the served lab
starts where the arm is and no goal ever jumps.

For each family the page (a headless client) shows the measured pose on every joint
slider; torque coming on holds the arm where it is (it sinks under gravity only by its
servos' own droop, which the loop then takes back); a slider moved by +3° moves the arm
about 3° and no goal sent (read from the emulator's own log of the packets it received)
changes by more than 3° and a step from the goal before it; E-STOP then Reset holds the arm
where it is. An SO-101 with no calibration starts with its torque off, says so on the
page and in the log, and switches it on only when a person confirms.
"""

from __future__ import annotations

import logging
import math
import signal
import subprocess
import sys

import numpy as np
import pytest
from _emulator import ROOT, emulator, sync_goals
from _helpers import client_of, wait_for

from armlab.app.lab.server import Lab, ServeOptions
from armlab.control.trajectory import APPROACH_SPEED, approach_duration
from armlab.hardware.backends.joint_map import default_joint_map
from armlab.kinematics.catalog import load_robot

pytestmark = [pytest.mark.realtime, pytest.mark.timeout(300)]

#: each family's arm, a pose far from zero (degrees by joint name) and the joint moved
ARMS = {
    "sts": ("so101", {"shoulder_pan": -30.0, "shoulder_lift": 60.0, "elbow_flex": -45.0,
                      "wrist_flex": 30.0, "wrist_roll": 40.0}, "elbow_flex"),
    "xseries": ("open_manipulator_x", {"joint1": 35.0, "joint2": 40.0, "joint3": -60.0,
                                       "joint4": 45.0}, "joint3"),
}
#: °, the most a loaded joint sinks when its torque comes on (its servo's proportional
#: droop under the arm's weight, before the loop's integral of the error takes it back)
DROOP_DEG = 5.0
#: °, the joint slider's step (the page rounds the pose to it)
SLIDER_STEP = 0.5


def _servo_step(robot: str) -> float:
    """°, one position count of the robot's servos."""
    spec = default_joint_map(load_robot(robot)).spec
    return math.degrees(abs(spec.raw_to_position(1) - spec.raw_to_position(0)))


def _pose_arg(pose: dict[str, float]) -> str:
    return ",".join(f"{k}={v:g}" for k, v in pose.items())


def _q_deg(lesson) -> np.ndarray:
    snap = lesson.loop.recorder.snapshot(0.1)
    return np.degrees(snap["q"][-1]) if len(snap["t"]) else np.full(lesson.model.n, np.nan)


def _at_rest(lesson) -> None:
    """Wait until the arm moved less than a tenth of a degree over half a second."""
    last = [_q_deg(lesson), lesson.loop.status.t]

    def resting() -> bool:
        if lesson.loop.status.t - last[1] < 0.5:
            return False
        now = _q_deg(lesson)
        done = bool(np.max(np.abs(now - last[0])) < 0.1)
        last[:] = [now, lesson.loop.status.t]
        return done

    wait_for(resting, 60, "the arm at rest")


def _page_sliders(page, model) -> np.ndarray:
    """What the page's joint sliders show, degrees, in joint order."""
    return np.array([float(page.find(f"{name} °").value) for name in model.joint_names])


def _page_text(page) -> str:
    return " ".join(str(v) for el in list(page.gui.values()) for v in el.props.values()
                    if isinstance(v, str))


def _largest_goal_jump(packets: list[bytes], robot: str) -> float:
    """° of the largest change between two goals sent one after the other to a servo, in
    the emulator's received ``packets``."""
    model = load_robot(robot)
    jmap = default_joint_map(model)
    spec = jmap.spec
    worst = 0.0
    for goals in sync_goals(packets, jmap.protocol).values():
        a = np.degrees([spec.raw_to_position(g) for g in goals])
        if len(a) > 1:
            worst = max(worst, float(np.max(np.abs(np.diff(a)))))
    return worst


def _drafted_map(port: str, robot: str, path) -> str:
    """The README's step 2: ``armlab scan --write-map`` on the port; the map's path."""
    run = subprocess.run(
        [sys.executable, "-m", "armlab.app", "scan", "--port", port, "--ids", "0-16",
         "--baud", "1000000", "--timeout", "0.3", "--robot", robot, "--write-map", str(path)],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "calibrated = false" in path.read_text()
    return str(path)


@pytest.mark.parametrize(("family", "drafted"),
                         [("sts", False), ("sts", True), ("xseries", False)],
                         ids=["so101", "so101-drafted-map", "open_manipulator_x"])
def test_the_page_starts_where_the_arm_is_and_no_goal_jumps(family, drafted, tmp_path,
                                                            caplog):
    """(The drafted map: the README's first-run steps, followed literally.)"""
    robot, pose, moved = ARMS[family]
    model = load_robot(robot)
    step = _servo_step(robot)
    want = np.array([pose[name] for name in model.joint_names])
    with emulator("--robot", robot, "--dt", "0.002", "--pose", _pose_arg(pose),
                  log_dir=tmp_path) as emu, \
            caplog.at_level(logging.INFO, logger="armlab"):
        joint_map = _drafted_map(emu.port, robot, tmp_path / "arm.toml") if drafted else None
        with Lab(ServeOptions(robot=robot, backend="serial", port=emu.port,
                              joint_map=joint_map, http_port=0)) as lab, \
                client_of(lab.server, token=lab.token) as page:
            lesson = lab.lesson
            # the page shows the arm's pose on every slider, never zero
            page.wait_for(lambda: page.shows(f"{model.joint_names[0]} °"), 60.0,
                          "the joint sliders")
            shown = _page_sliders(page, model)
            assert np.max(np.abs(shown - want)) <= SLIDER_STEP, (shown, want)
            uncalibrated = family == "sts"  # the SO-101 with no calibration, no map
            if uncalibrated:
                page.wait_for(lambda: "confirm the arm is clear" in _page_text(page), 60.0,
                              "the page saying the torque is off until confirmed")
                assert "uncalibrated" in _page_text(page)
                assert any("uncalibrated" in r.getMessage() and "--calibrate" in r.getMessage()
                           for r in caplog.records), "the terminal was not told"
                wait_for(lambda: lesson.loop.status.steps > 50, 60, "the loop watching")
                assert not lesson.loop.status.torque_on
                assert sync_goals(emu.packets("rx"), "sts") == {}, "a goal went out"
                with pytest.raises(ValueError, match="confirm the arm is clear"):
                    lesson.move_joint(model.joint_names.index(moved), 0.0)
                page.click("Torque on: the arm is clear")
            wait_for(lambda: lesson.loop.status.active, 60, "the arm held")
            start = _q_deg(lesson)
            assert np.max(np.abs(start - want)) <= DROOP_DEG, (start, want)
            # the loop takes the droop back: the arm comes to rest at its pose
            wait_for(lambda: np.max(np.abs(_q_deg(lesson) - want)) <= 1.0 + step, 60,
                     lambda: f"the arm back at its pose ({_q_deg(lesson)} vs {want})")
            # +3° on one slider moves that joint 3°, nothing else
            j = model.joint_names.index(moved)
            at = _q_deg(lesson)
            target = float(_page_sliders(page, model)[j]) + 3.0
            page.set_value(f"{moved} °", target)
            wait_for(lambda: lesson.loop.status.trajectory is not None, 30, "the move posted")
            wait_for(lambda: lesson.loop.status.trajectory is None, 30, "the move done")
            expected = at.copy()
            expected[j] = target
            # the other joints sink a little while the moved one shifts their load, and
            # come back: the arm rests with that one joint 3° on
            wait_for(lambda: np.max(np.abs(_q_deg(lesson) - expected)) <= 1.0 + step, 60,
                     lambda: f"the arm at rest {expected} ({_q_deg(lesson)})")
            after = _q_deg(lesson)
            assert abs(after[j] - at[j]) <= 3.0 + SLIDER_STEP + 1.0 + step, (at, after)
            # no goal jumped while the torque was on
            sent = emu.packets("rx")
            assert _largest_goal_jump(sent, robot) <= 3.0 + step, \
                _largest_goal_jump(sent, robot)
            # E-STOP (the arm, unpowered, sinks), then Reset: held where it is then, the
            # sliders on the arm
            said = len(caplog.records)
            lab.estop()
            wait_for(lambda: lesson.loop.status.estopped, 30, "the E-STOP")
            # the page's press and the loop both send the torque-off: one line is said
            lines = [r for r in caplog.records[said:] if r.levelno >= logging.WARNING
                     and "torque off sent" in r.getMessage()]
            assert len(lines) == 1, [r.getMessage() for r in caplog.records[said:]]
            _at_rest(lesson)  # the unpowered arm sinks, maybe onto a stop
            lo, hi = np.degrees(lesson.loop.lower), np.degrees(lesson.loop.upper)
            # (a slider ends at its joint's limit, on its step, for an arm sunk past it)
            wait_for(lambda: np.max(np.abs(_page_sliders(page, model)
                                           - np.clip(_q_deg(lesson), lo, hi)))
                     <= SLIDER_STEP + step, 30, lambda: f"the sliders on the stopped arm "
                     f"({_page_sliders(page, model)} vs {_q_deg(lesson)})")
            before = len(emu.packets("rx"))
            page.click("Reset (after E-STOP or a fault)")
            wait_for(lambda: lesson.loop.status.active, 60, "the arm held again")
            held, t_held = _q_deg(lesson), lesson.loop.status.t
            wait_for(lambda: lesson.loop.status.t > t_held + 1.0, 30, "a second held")
            if np.all((held > lo + DROOP_DEG) & (held < hi - DROOP_DEG)):
                # (an arm that sank past a joint limit is brought back inside it)
                assert np.max(np.abs(_q_deg(lesson) - held)) <= DROOP_DEG, \
                    (held, _q_deg(lesson))
            wait_for(lambda: np.max(np.abs(_page_sliders(page, model) - held))
                     <= SLIDER_STEP + DROOP_DEG, 30, "the sliders on the arm after Reset")
            sent = emu.packets("rx")[before:]
            assert _largest_goal_jump(sent, robot) <= 3.0 + step, \
                _largest_goal_jump(sent, robot)


def test_the_thesis_arm_is_held_where_it_is_and_its_line_approached_at_the_bound(tmp_path):
    """Protocol 1.0 (RX-24F, the compliance lesson): the loop holds the arm where it was
    left, no goal jumps, and Run thesis line reaches the line's start, far away, no faster
    than the lab's approach speed (0.5 rad/s at the peak of a minimum-jerk move)."""
    robot, pose = "receptionist_arm", {"theta1": 30.0, "theta0": -50.0, "theta2": 70.0}
    model = load_robot(robot)
    want = np.array([pose[n] for n in model.joint_names])
    step = _servo_step(robot)
    with emulator("--robot", robot, "--pose", _pose_arg(pose), log_dir=tmp_path) as emu, \
            Lab(ServeOptions(robot=robot, backend="serial", port=emu.port,
                             http_port=0)) as lab:
        lesson = lab.lesson
        loop, line = lesson.rig.loop, lesson.rig.line
        wait_for(lambda: loop.status.active, 60, "the arm held")
        t_on = loop.status.t
        wait_for(lambda: loop.status.t > t_on + 1.0, 30, "a second held")
        snap = loop.recorder.snapshot(0.5)
        assert np.max(np.abs(np.degrees(snap["q_cmd"][-1]) - want)) <= step, snap["q_cmd"][-1]
        assert np.max(np.abs(np.degrees(snap["q"]) - want)) <= DROOP_DEG
        lesson.run_line()
        wait_for(lambda: loop.status.trajectory is not None, 30, "the line running")
        wait_for(lambda: loop.status.trajectory is None, 120, "the line done")
        assert loop.status.fault is None, loop.status.fault
        timed = [(t, raw) for t, tag, raw in emu.timed() if tag == "rx"]
    spec = default_joint_map(model).spec
    by_id: dict[int, list[tuple[float, float]]] = {}
    for t, raw in timed:
        for servo, goals in sync_goals([raw], 1).items():
            by_id.setdefault(servo, []).extend((t, spec.raw_to_position(g)) for g in goals)
    assert _largest_goal_jump([raw for _, raw in timed], robot) <= 3.0 + step
    q_start = np.radians(want)
    duration = approach_duration(q_start, line.q[0], speed=APPROACH_SPEED)
    assert duration > 2.0, "the line's start is far from the pose"
    for servo, pts in by_id.items():
        t, a = np.array(pts).T
        moving = np.flatnonzero(np.abs(a - a[0]) > 2 * math.radians(step))
        assert len(moving), f"servo {servo} never moved"
        t0 = t[moving[0]]
        window = (t >= t0) & (t <= t0 + duration)
        tw, aw = t[window], a[window]
        # over 0.25 s, so the period's jitter and the 0.29° steps do not count
        k = np.searchsorted(tw, tw + 0.25)
        ok = k < len(tw)
        speed = np.abs(aw[k[ok]] - aw[ok]) / (tw[k[ok]] - tw[ok])
        assert speed.max() <= 1.2 * APPROACH_SPEED, (servo, speed.max())


def test_a_link_lost_with_the_torque_already_off_says_so_and_does_not_alarm():
    """E-STOP first, then the cable pulled: nothing holds the arm, so the lab says the
    link is down and the torque was already off, never "Torque off could not be sent"."""
    from armlab.app.lessons._loop_state import UNSENT_BANNER, stopped_state

    robot, pose, _ = ARMS["xseries"]
    with emulator("--robot", robot, "--pose", _pose_arg(pose)) as emu, \
            Lab(ServeOptions(robot=robot, backend="serial", port=emu.port,
                             http_port=0)) as lab:
        loop = lab.lesson.loop
        wait_for(lambda: loop.status.active, 60, "the arm held")
        lab.estop()
        wait_for(lambda: loop.status.estopped and not loop.status.torque_on, 30, "E-STOP")
        emu.stop(signal.SIGKILL)
        wait_for(lambda: loop.status.link_down, 60, "the loop to notice the lost link")
        lab.estop()  # pressed again: the link is gone
        wait_for(lambda: "already off" in loop.status.message, 30,
                 lambda: f"the message saying so ({loop.status.message!r})")
        st = loop.status
        assert not st.torque_off_unsent, st
        assert stopped_state(st) != UNSENT_BANNER
        assert "already off" in (st.fault or ""), st.fault
