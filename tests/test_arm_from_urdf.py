"""Your own arm: scan -> joint map -> serve a URDF -> a slider reaches the servos.

The 2-joint arm of tests/data/two_joint_arm.urdf runs end to end over a real
pseudo-terminal to the protocol-1.0 emulator (``armlab emulate`` as a subprocess),
``armlab scan --write-map`` as a subprocess, and the lab's real viser server with a
headless client moving a slider.
"""

from __future__ import annotations

import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons.arm import check_servo_arm
from armlab.hardware.backends.joint_map import draft_joint_map, load_joint_map
from armlab.hardware.wire.scan import Found
from armlab.kinematics import load_robot
from tests._emulator import ROOT, emulator
from tests._helpers import client_of, confirm_clear, wait_for

DATA = Path(__file__).with_name("data")
TWO = DATA / "two_joint_arm.urdf"


def _found(servo_id: int, model: str = "AX-12A", number: int = 12, cw: float = -150.0,
           ccw: float = 150.0) -> Found:
    return Found(servo_id=servo_id, model_number=number, model=model, firmware=1,
                 baud=1e6, baud_value=1, cw_limit=0 if cw == ccw == 0 else 1,
                 ccw_limit=0 if cw == ccw == 0 else 1023, cw_limit_deg=cw,
                 ccw_limit_deg=ccw, error=0)


def test_draft_names_joints_in_id_order_and_narrows_to_the_urdf(tmp_path):
    model = load_robot(TWO)
    text = draft_joint_map([_found(22, cw=-100.0, ccw=120.0), _found(21)], model)
    data = tomllib.loads(text)
    assert data["servo"] == "AX-12A" and data["protocol"] == 1.0 and data["baud"] == 1_000_000
    assert [(j["name"], j["id"]) for j in data["joints"]] == [("yaw", 21), ("elbow", 22)]
    # yaw: servo ±150°, URDF ±2.6 rad = ±148.97°; elbow: servo -100..120, URDF ±1.8 rad
    assert data["joints"][0]["lower_deg"] == pytest.approx(-math.degrees(2.6), abs=1e-3)
    assert data["joints"][1]["lower_deg"] == pytest.approx(-100.0, abs=1e-3)
    assert data["joints"][1]["upper_deg"] == pytest.approx(math.degrees(1.8), abs=1e-3)
    path = tmp_path / "map.toml"
    path.write_text(text)
    loaded = load_joint_map(path, model)
    assert loaded.ids == (21, 22)


@pytest.mark.parametrize("found,words", [
    ([_found(21)], "joint 'elbow' of two_joint_arm has no servo"),
    ([_found(21), _found(22), _found(23)], "servo ID 23 has no joint"),
    ([_found(21), _found(22, model="unknown", number=9999)],
     "servo ID 22: unknown servo model number 9999; known: 12 (AX-12A), 24 (RX-24F), "
     "1060 (XL430-W250), 1020 (XM430-W350), 1200 (XL330-M288)"),
    ([_found(21), _found(22, model="RX-24F", number=24)], "ID 22: RX-24F"),
    ([_found(21), _found(22, cw=110.0, ccw=140.0)], "joint 'elbow' (servo ID 22)"),
])
def test_a_map_that_disagrees_with_the_urdf_names_joint_and_servo(found, words):
    with pytest.raises(ValueError) as info:
        draft_joint_map(found, load_robot(TWO))
    assert words in str(info.value)


def test_a_map_limit_outside_the_servo_range_names_joint_and_servo(tmp_path):
    path = tmp_path / "map.toml"
    path.write_text('servo = "AX-12A"\n[[joints]]\nname = "yaw"\nid = 21\n'
                    '[[joints]]\nname = "elbow"\nid = 22\nupper_deg = 170\n')
    with pytest.raises(ValueError, match=r"joint 'elbow' \(servo ID 22, AX-12A\): upper limit "
                       r"\+170.0 deg is outside the servo's range ±150.0 deg"):
        load_joint_map(path, load_robot(TWO))
    path.write_text('servo = "XC330-T288"\n[[joints]]\nname = "yaw"\nid = 21\n')
    with pytest.raises(ValueError, match="unknown servo model 'XC330-T288'; known: AX-12A, "
                                         "RX-24F, XL430-W250, XM430-W350, XL330-M288"):
        load_joint_map(path, load_robot(TWO))
    # an X-series map names its protocol, or none; never the other one
    path.write_text('servo = "XM430-W350"\nprotocol = 1.0\n[[joints]]\nname = "yaw"\nid = 21\n'
                    '[[joints]]\nname = "elbow"\nid = 22\n')
    with pytest.raises(ValueError, match="protocol 1.0 but the XM430-W350 speaks protocol 2.0"):
        load_joint_map(path, load_robot(TWO))


def test_a_chain_the_lab_cannot_drive_names_the_joint():
    mobile = DATA / "mobile_manipulator.urdf"
    with pytest.raises(ValueError, match="joint 'finger_left_joint' is prismatic"):
        check_servo_arm(load_robot(mobile, tip_link="finger_left_link"))
    check_servo_arm(load_robot(mobile, tip_link="tcp_link"))  # 4 revolute joints: fine


@pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal
def test_two_joint_arm_scan_map_serve_slider_reaches_the_servos(tmp_path):
    map_path = tmp_path / "two.toml"
    with emulator("--robot", str(TWO), "--ids", "21,22") as emu:
        scan = subprocess.run(
            [sys.executable, "-m", "armlab.app", "scan", "--port", emu.port, "--ids", "18-25",
             "--baud", "1000000", "--write-map", str(map_path), "--robot", str(TWO)],
            cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert scan.returncode == 0, scan.stderr
        data = tomllib.loads(map_path.read_text())
        assert [(j["name"], j["id"]) for j in data["joints"]] == [("yaw", 21), ("elbow", 22)]

        lab = Lab(ServeOptions(robot=str(TWO), backend="serial", port=emu.port,
                               joint_map=str(map_path), http_port=0))
        try:
            lesson = lab.lesson
            assert lab.lesson_name == "arm" and lesson.model.joint_names == ("yaw", "elbow")
            assert lesson.backend.map.ids == (21, 22)
            # a drafted map is not calibrated: torque off until a person confirms
            wait_for(lambda: lesson.loop.status.held_off is not None, 60, "the torque held off")
            confirm_clear(lesson)
            with client_of(lab.server, token=lab.token) as client:
                client.wait_for(lambda: client.shows("elbow °"), 60.0,
                                "the elbow slider")
                client.set_value("elbow °", 40.0)

                def measured() -> np.ndarray:
                    snap = lesson.loop.recorder.snapshot(0.1)
                    return snap["q"][-1] if len(snap["t"]) else np.full(2, np.nan)

                # The servos (read back over the pty) turn the elbow to 40°, the yaw stays.
                wait_for(lambda: abs(math.degrees(measured()[1]) - 40.0) < 2.0, 60.0,
                         "the elbow servo to reach 40°")
                assert abs(math.degrees(measured()[0])) < 2.0
                assert lesson.loop.status.fault is None
        finally:
            lab.close()


@pytest.mark.slow
def test_dragging_the_hand_target_moves_open_manipulator_x_there():
    """The IK target drag on the shipped OpenManipulator-X, simulated, through the page."""
    from armlab.app.lessons import LessonContext
    from armlab.app.lessons.arm import build
    from tests._helpers import served_lesson

    with served_lesson(build, LessonContext(robot="open_manipulator_x")) as lesson:
        model = lesson.model

        def hand() -> np.ndarray:
            snap = lesson.loop.recorder.snapshot(0.1)
            return model.fk(snap["q"][-1])[:3, 3] if len(snap["t"]) else np.full(3, np.nan)

        wait_for(lambda: np.all(np.isfinite(hand())), 30.0, "the loop's first period")
        start = hand()
        goal = start + np.array([-0.06, 0.05, -0.04])
        with client_of(lesson.server) as client:
            client.move_gizmo("/arm_target_base/target",
                              [tuple(start + f * (goal - start)) for f in (0.3, 0.6, 1.0)])
            wait_for(lambda: np.linalg.norm(hand() - goal) < 0.003, 60.0,
                     "the hand to reach the dragged target")
        assert lesson.loop.status.fault is None


@pytest.mark.slow
def test_the_so101_opens_in_the_arm_lesson_and_follows_a_dragged_target():
    """The shipped SO-101 (five STS3215 joints, simulated): the arm lesson takes it by name,
    and the hand follows the IK target dragged 3 cm through the page."""
    from armlab.app.lessons import LessonContext
    from armlab.app.lessons import arm as arm_lesson
    from tests._helpers import served_lesson

    assert arm_lesson.LESSON.works_with("so101")
    with served_lesson(arm_lesson.build, LessonContext(robot="so101")) as lesson:
        model = lesson.model
        assert model.n == 5

        def hand() -> np.ndarray:
            snap = lesson.loop.recorder.snapshot(0.1)
            return model.fk(snap["q"][-1])[:3, 3] if len(snap["t"]) else np.full(3, np.nan)

        wait_for(lambda: np.all(np.isfinite(hand())), 30.0, "the loop's first period")
        start = hand()
        goal = start + np.array([0.0, 0.02, -0.02])
        with client_of(lesson.server) as client:
            client.move_gizmo("/arm_target_base/target",
                              [tuple(start + f * (goal - start)) for f in (0.5, 1.0)])
            wait_for(lambda: np.linalg.norm(hand() - goal) < 0.003, 60.0,
                     "the hand to reach the dragged target")
        assert lesson.loop.status.fault is None


def test_teach_tab_names_default_and_narrowed_limits():
    from armlab.app.lessons.arm import limits_markdown

    model = load_robot(DATA / "mobile_manipulator.urdf", tip_link="tcp_link")
    half = math.radians(150.0)  # an AX-12A's range narrows the ±180° default and ±3 rad
    lower = np.maximum(model.lower, -half)
    upper = np.minimum(model.upper, half)
    rows = limits_markdown(model, lower, upper).splitlines()[2:]
    assert rows[0] == "| shoulder_pan_joint | -143.2 | +143.2 | URDF |"
    assert rows[2] == ("| elbow_joint | -150.0 | +150.0 | default ±180° (continuous, "
                       "no limit) |")
    assert rows[3] == "| wrist_joint | -150.0 | +150.0 | URDF narrowed to the servo |"
