"""The any-arm lesson's compliance controls and spare joints, served by the real lab on a
free port and driven by a headless client sending what a browser sends
(armlab.app.testing.wsclient).

The shipped OpenManipulator-X (4 joints, one spare for a hand position) and the 5-joint
arm of tests/data/five_joint_arm.urdf (two spare), simulated, their loops run as fast as
they go (``realtime=False``: every wait on them is in loop time, so the same periods take a
third of the wall time); a 2-joint arm has no spare joint and is told so; a student's private copy
(``armlab serve --classroom``, "My arm") has the same controls on its own arm.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.page.inputs import LIMIT_TITLE
from armlab.control.params import DEFAULT
from armlab.kinematics.redundancy import joint_limit_criterion
from tests._helpers import client_of, hand_at_rest, wait_for

pytestmark = pytest.mark.realtime  # served labs whose loops run on the wall clock

DATA = Path(__file__).with_name("data")
KP = "Kp (1/s²)"
AIM = "Spare joints aim"
LIMITS = "away from the joint limits"


@pytest.fixture(scope="module")
def omx():
    with Lab(ServeOptions(robot="open_manipulator_x", http_port=0, realtime=False)) as lab:
        yield lab


@pytest.fixture
def page(omx):
    with client_of(omx.server, token=omx.token) as client:
        client.wait_for(lambda: client.shows(KP) and client.shows(AIM), 60.0,
                        "the Gains and Spare joints tabs")
        yield client
        lesson = omx.lesson  # leave the arm as the next test expects it
        lesson.controls.gains.set_params(DEFAULT)
        client.set_value(AIM, "off (plain RMRC)")
        wait_for(lambda: lesson.loop.params == DEFAULT and lesson.loop.spare_joints.aim == "off",
                 30.0, "the default gains and no spare-joint aim")


def _q(lesson) -> np.ndarray:  # noqa: ANN001
    snap = lesson.loop.recorder.snapshot(0.1)
    return snap["q"][-1] if len(snap["t"]) else np.full(lesson.model.n, np.nan)


def _hand(lesson) -> np.ndarray:  # noqa: ANN001
    return lesson.model.fk(_q(lesson))[:3, 3]


def _settle(lesson, q: np.ndarray) -> None:  # noqa: ANN001
    """Move to ``q`` (what a joint slider does) and wait until the arm is there."""
    lesson.move_to(q)
    wait_for(lambda: np.abs(_q(lesson) - q).max() < math.radians(2.0), 60.0,
             lambda: f"the arm at {np.degrees(q).round(1)}°, at {np.degrees(_q(lesson))}°")


# the tests with a lab of their own come first: the shared lab's loop, running as fast
# as it goes, is not yet started while theirs run


def test_a_five_joint_urdf_arm_has_the_controls_and_two_spare_joints():
    with Lab(ServeOptions(robot=str(DATA / "five_joint_arm.urdf"), http_port=0,
                          realtime=False)) as lab, \
            client_of(lab.server, token=lab.token) as page:
        page.wait_for(lambda: page.shows(AIM) and page.shows("Push") and page.shows("Joint"),
                      60.0, "the controls")
        assert any("**2 spare**" in str(e.props.get("_markdown", "")) for e in page.gui.values())
        # five long joint names: the charts' joint picker is a dropdown, all joints in it
        assert page.find("Joint").kind == "GuiDropdownMessage"
        loop = lab.lesson.loop
        page.set_value(KP, 15.0)
        wait_for(lambda: loop.params.kp == 15.0, 30.0, "Kp 15 in the loop")
        page.set_value("Joint", "elbow")
        wait_for(lambda: lab.lesson.controls.plots.joint == 3, 30.0, "the elbow charted")
        _spare_joints_do_their_job(lab, page, np.array([0.2, 0.5, 1.5, 2.2, 0.4]),
                                   np.array([0.03, -0.03, 0.02]))


def test_a_two_joint_arm_is_told_it_has_no_spare_joint():
    with Lab(ServeOptions(robot=str(DATA / "two_joint_arm.urdf"), http_port=0)) as lab, \
            client_of(lab.server, token=lab.token) as page:
        page.wait_for(lambda: page.shows(KP), 60.0, "the Gains tab")
        page.wait_for(lambda: any("No spare joints" in str(e.props.get("_markdown", ""))
                                  for e in page.gui.values()), 30.0, "the reason")
        assert not page.shows(AIM)


def test_a_students_own_copy_has_the_controls_on_its_own_arm():
    with Lab(ServeOptions(robot="open_manipulator_x", http_port=0, classroom=True)) as lab:
        shared = lab.lesson.loop
        before = set(lab.server.get_clients())
        with client_of(lab.server, token=lab.token) as page:
            (cid,) = set(lab.server.get_clients()) - before
            page.wait_for(lambda: page.shows("View"), 60.0, "the View switch")
            page.set_value("View", "My arm")
            wait_for(lambda: lab.room.private_lesson(cid) is not None, 60.0, "the own lesson")
            mine = lab.room.private_lesson(cid)
            assert mine.loop is not shared
            wait_for(lambda: mine.loop.status.active and np.all(np.isfinite(_q(mine))), 60.0,
                     "the own arm held")
            page.wait_for(lambda: mine.controls.gains.sliders["kp"].handle._impl.uuid
                          in page.gui, 60.0, "the own Kp slider on the page")
            page.set_value(mine.controls.gains.sliders["kp"].handle, 14.0)
            wait_for(lambda: mine.loop.params.kp == 14.0, 30.0, "Kp 14 in the own loop")
            assert shared.params.kp == DEFAULT.kp
            before_hand = hand_at_rest(mine)  # Kp 14 sags it a little under gravity first
            page.click(mine.controls.pushes.button)  # 2 N down for 1.5 s
            wait_for(lambda: np.linalg.norm(_hand(mine) - before_hand) > 0.01, 30.0,
                     "the own arm pushed")
            wait_for(lambda: np.linalg.norm(_hand(mine) - before_hand) < 0.005, 60.0,
                     "the own arm back")
            page.set_value(mine.controls.aim, LIMITS)
            wait_for(lambda: mine.loop.spare_joints.aim == "limits", 30.0,
                     "the aim in the own loop")
            assert shared.spare_joints.aim == "off"


def test_a_kp_change_reaches_the_loop(omx, page):
    loop = omx.lesson.loop
    page.set_value(KP, 12.5)
    wait_for(lambda: loop.params.kp == 12.5, 30.0, "Kp 12.5 in the loop")
    page.set_value("Preset", "thesis Table 4.1")
    wait_for(lambda: loop.params.kp == pytest.approx(3.8) and loop.params.law == "2.26", 30.0,
             "the Table 4.1 preset in the loop")
    page.wait_for(lambda: page.find(KP).value == pytest.approx(3.8), 30.0, "the Kp slider 3.8")


def test_a_gain_past_its_range_is_set_to_its_end_and_the_page_told_so(omx, page):
    """The page's one rule for a typed number: past the range, the nearest end is applied
    and the message names that value (the field itself clamps to it on blur)."""
    loop = omx.lesson.loop
    kp = loop.params.kp
    seen = len(page.notifications)
    page.set_value(KP, -5.0)  # (past the top, Kp 200, is more than this arm follows)
    page.wait_for(lambda: len(page.notifications) > seen, 30.0, "a notification")
    wait_for(lambda: loop.params.kp == 0.0, 30.0, "Kp 0 in the loop")
    title, body = page.notifications[seen]
    assert title == LIMIT_TITLE and body == (
        "Kp: -5 is below the smallest value, 0; set to 0."), page.notifications[seen:]
    # the typer's field shows the value applied once the typing pauses
    page.wait_for(lambda: page.find(KP).value == pytest.approx(0.0), 30.0, "the field 0")
    page.set_value(KP, kp)
    wait_for(lambda: loop.params.kp == kp, 30.0, "Kp back")
    assert loop.status.fault is None


@pytest.mark.parametrize("bad", [float("nan")])
def test_a_bad_kp_is_refused_with_one_notification(omx, page, bad):
    loop = omx.lesson.loop
    kp = loop.params.kp
    seen = len(page.notifications)
    page.set_value(KP, bad)
    page.wait_for(lambda: len(page.notifications) > seen, 30.0, "a notification")
    page.wait_for(lambda: page.find(KP).value == pytest.approx(kp), 30.0, "the slider put back")
    page.set_value(KP, kp + 1.0)  # a good value after it: the bad one's messages are all in
    wait_for(lambda: loop.params.kp == kp + 1.0, 30.0, "the good value in the loop")
    new = page.notifications[seen:]
    assert len(new) == 1 and new[0][0] == "Value refused" and "Kp" in new[0][1], new
    assert loop.status.fault is None


def test_a_push_moves_the_hand_and_it_comes_back(omx, page):
    lesson = omx.lesson
    wait_for(lambda: np.all(np.isfinite(_q(lesson))), 30.0, "the arm read")
    before = hand_at_rest(lesson)
    page.set_value("Direction", "down (with gravity)")
    page.set_value("Push force (N)", 3.0)
    page.set_value("Duration (s)", 2.0)
    wait_for(lambda: lesson.controls.pushes.duration == 2.0
             and lesson.controls.pushes.force == 3.0, 30.0, "3 N for 2 s in the lesson")
    page.click("Push")
    # the status says so only while the push acts: look for it first
    wait_for(lambda: "pushing 3 N" in lesson.status.content, 30.0, "the status saying so")
    wait_for(lambda: before[2] - _hand(lesson)[2] > 0.01, 30.0,
             lambda: f"the hand pushed 1 cm down (it is {_hand(lesson) - before} m off)")
    wait_for(lambda: np.linalg.norm(_hand(lesson) - before) < 0.005, 60.0,
             lambda: f"the hand back (it is {_hand(lesson) - before} m off)")
    wait_for(lambda: "gave way" in lesson.controls.pushes.result.content, 60.0,
             "the push's figures beside the button")
    assert lesson.loop.status.fault is None


def _drag_to(page, lesson, goal: np.ndarray) -> float:  # noqa: ANN001
    """Drag the target from the hand to ``goal`` and wait for the hand there; returns
    the joint-limit criterion once the arm has stopped moving."""
    start = _hand(lesson)
    page.move_gizmo("/arm_target_base/target",
                    [tuple(start + f * (goal - start)) for f in (0.3, 0.6, 1.0)])
    wait_for(lambda: np.linalg.norm(_hand(lesson) - goal) < 0.003, 60.0,
             lambda: f"the hand on the target ({_hand(lesson) - goal} m off)")

    def criterion() -> float:
        loop = lesson.loop
        return joint_limit_criterion(_q(lesson), loop.lower, loop.upper)

    last = [criterion(), lesson.loop.status.t]

    def still() -> bool:  # no change of the criterion over a second of loop time
        if lesson.loop.status.t - last[1] < 1.0:
            return False
        now = criterion()
        done = abs(now - last[0]) < 0.002
        last[:] = [now, lesson.loop.status.t]
        return done

    wait_for(still, 120.0, "the arm to stop moving")
    return criterion()


def _spare_joints_do_their_job(lab, page, q0: np.ndarray, offset: np.ndarray) -> None:  # noqa: ANN001
    lesson = lab.lesson
    _settle(lesson, q0)
    goal = lesson.model.fk(q0)[:3, 3] + offset
    h_off = _drag_to(page, lesson, goal)
    _settle(lesson, q0)  # a joint slider: the target is let go of
    page.set_value(AIM, LIMITS)
    wait_for(lambda: lesson.loop.spare_joints.aim == "limits", 30.0, "the aim in the loop")
    h_on = _drag_to(page, lesson, goal)
    assert np.linalg.norm(_hand(lesson) - goal) < 0.003
    assert h_on > h_off + 0.05, (h_off, h_on)  # farther from the limits than without
    assert "manipulability w" in lesson.controls.spare_readout.content
    assert lesson.loop.status.fault is None


def test_spare_joints_keep_the_hand_on_the_target_and_leave_the_limits(omx, page):
    _spare_joints_do_their_job(omx, page, np.array([0.3, -1.2, 0.6, 1.6]),
                               np.array([0.03, -0.03, 0.02]))


def test_home_brings_the_arm_back_at_the_approach_speed(omx, page):
    """After a move far from home, **Home** moves every joint back to its zero, its command
    never faster than the lab's approach speed (Reset only holds the arm where it is)."""
    from armlab.control.trajectory import APPROACH_SPEED

    lesson = omx.lesson
    _settle(lesson, np.radians([40.0, -30.0, 30.0, 20.0]))
    t0 = lesson.loop.status.t
    page.click("Home")
    wait_for(lambda: lesson.loop.status.trajectory is not None, 30.0, "the move home")
    wait_for(lambda: lesson.loop.status.trajectory is None, 60.0, "the arm home")
    wait_for(lambda: np.abs(_q(lesson)).max() < math.radians(2.0), 60.0,
             lambda: f"the arm at zero ({np.degrees(_q(lesson))})")
    snap = lesson.loop.recorder.snapshot(lesson.loop.status.t - t0)
    t, q_cmd = snap["t"], snap["q_cmd"]
    ok = np.isfinite(q_cmd).all(axis=1)
    speed = np.abs(np.diff(q_cmd[ok], axis=0)) / np.diff(t[ok])[:, None]
    assert speed.max() <= APPROACH_SPEED * 1.01, speed.max()
