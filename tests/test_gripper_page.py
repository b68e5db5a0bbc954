"""The arm lesson's gripper controls say what the robot's gripper is, on a real viser server
on a free port with a headless page: the SO-101's revolute jaw in degrees (its slider's
ends the URDF's -10°..100°, a slider goal in degrees reaching the jaw in rad) and its
STS3215's grip bounded by a Torque Limit (no current mode); the OpenManipulator-X's sliding
finger in mm and its XM430's current-based position control; the loop's note on a
gripper goal speaks the same unit.
"""

from __future__ import annotations

import math

import pytest
from _helpers import client_of, served_lesson, wait_for

from armlab.app.lessons import LessonContext
from armlab.app.lessons.arm import build


def _markdown(client, words: str) -> str:
    """The page's markdown that contains ``words`` ("" when none does yet)."""
    with client._lock:
        texts = [str(e.props.get("_markdown", "")) for e in client.gui.values()]
    return next((t for t in texts if words in t), "")


@pytest.mark.parametrize("robot, label, ends, note, not_said, readout", [
    ("so101", "gripper °", (-10.0, 100.0), "in position control held to a Torque Limit",
     "current-based", "Gripper: jaw "),
    ("open_manipulator_x", "gripper mm", (-10.0, 19.0), "current-based position control",
     "Torque Limit", "Gripper: finger "),
])
def test_the_gripper_controls_say_what_the_robot_s_gripper_is(
        robot, label, ends, note, not_said, readout):
    """The slider's unit and ends, the readout and the Teach tab's note follow the robot's
    finger joint (revolute: degrees; prismatic: mm) and its servo family; a slider goal
    in the page's unit moves the simulated gripper there in the URDF's units."""
    with served_lesson(build, LessonContext(robot=robot)) as lesson:
        revolute = robot == "so101"
        assert lesson.gripper.revolute is revolute
        scale = math.degrees(1.0) if revolute else 1e3  # the page's unit per URDF unit
        with client_of(lesson.server) as client:
            client.wait_for(lambda: client.shows(label), 60.0, f"the {label!r} slider")
            slider = client.find(label)
            assert (slider.props["min"], slider.props["max"]) == pytest.approx(ends, abs=0.05)
            client.wait_for(lambda: bool(_markdown(client, "**Gripper**")), 60.0,
                            "the Teach tab's gripper note")
            teach = _markdown(client, "**Gripper**")
            assert note in teach and not_said not in teach
            assert ("jaw's angle, in degrees" if revolute else "one finger, in mm") in teach
            client.wait_for(lambda: bool(_markdown(client, readout)), 60.0, readout)
            goal = 45.0 if revolute else 5.0  # degrees of the jaw, mm of the finger
            client.set_value(label, goal)

            def shown() -> float:
                grip = lesson.loop.gripper
                return math.nan if grip is None else grip.position * scale

            wait_for(lambda: abs(shown() - goal) < 1.0, 60.0,
                     lambda: f"the gripper at {goal} {label.split()[1]} (at {shown()})")
            said = "gripper: jaw to +45.0°" if revolute else "gripper: finger to +5.0 mm"
            assert lesson.loop.status.message == said  # the loop's words, in the same unit
        assert lesson.loop.status.fault is None
