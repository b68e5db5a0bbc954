"""The OpenManipulator-X's gripper servo (ID 15): emulated, configured, driven from the
lesson's page, clamped, switched off by E-STOP; simulated too.

Over a real pseudo-terminal to ``armlab emulate --robot open_manipulator_x``: it serves
the arm's IDs 11..14 and the gripper's 15 (scan finds five XM430-W350, protocol 2.0);
the X-series backend puts ID 15 in current-based position control at the gripper's
gentle Goal Current; a headless page clicking the lesson's Open / Close buttons moves
servo 15, and the 3D view's fingers follow; a goal beyond the finger's range is clamped
and never sent; E-STOP switches servo 15's torque off; a map naming a gripper servo that
does not answer is refused naming it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from _emulator import emulator, goal_positions
from _helpers import client_of, wait_for

from armlab.app.arm.backends import make_backend
from armlab.app.lab.server import Lab, ServeOptions
from armlab.control.backend import BackendError
from armlab.control.commands import SetGripper
from armlab.control.loop import ControlLoop
from armlab.hardware.backends.gripper import (
    GRIPPER_CURRENT,
    OMX_CLOSED_ANGLE,
    OMX_OPEN_ANGLE,
    open_manipulator_gripper,
)
from armlab.hardware.backends.joint_map import default_joint_map, draft_joint_map, load_joint_map
from armlab.hardware.families.xseries.backend import XSeriesBackend
from armlab.hardware.families.xseries.table import XM430_W350, OperatingMode
from armlab.hardware.wire.scan import Found
from armlab.kinematics.catalog import load_robot

OMX = load_robot("open_manipulator_x")
GRIPPER = open_manipulator_gripper(OMX.urdf_path)
MARGIN = 0.1  # s of reply timeout: generous, the test machine is shared
SPEED = np.full(4, 1.0)
#: the emulator's real-time physics over a pseudo-terminal, or a served lab
REALTIME = pytest.mark.realtime


def test_the_finger_and_the_horn_follow_robotis_s_numbers():
    """The URDF's finger limits are the range; ROBOTIS's horn angles its ends, and a
    finger travel between them a horn angle on the line through them (as ROBOTIS's
    driver converts: ROBOTIS-GIT/open_manipulator, open_manipulator_x_description/
    ros2_control/open_manipulator_x_system.ros2_control.xacro, "dxl5" (ID 15):
    revolute_min 0.92 rad at prismatic_min -0.01 m, revolute_max -1.52 rad at
    prismatic_max 0.019 m)."""
    closed_rad, open_rad, closed_m, open_m = 0.92, -1.52, -0.01, 0.019  # ROBOTIS's
    assert (GRIPPER.servo_id, GRIPPER.joint) == (15, "gripper_left_joint")
    assert (GRIPPER.lower, GRIPPER.upper) == (closed_m, open_m)
    assert (OMX_CLOSED_ANGLE, OMX_OPEN_ANGLE) == (closed_rad, open_rad)
    assert GRIPPER.to_servo(GRIPPER.lower) == pytest.approx(closed_rad)
    assert GRIPPER.to_servo(GRIPPER.upper) == pytest.approx(open_rad)
    for x in (-0.005, 0.0045, 0.012):
        horn = closed_rad + (x - closed_m) * (open_rad - closed_rad) / (open_m - closed_m)
        assert GRIPPER.to_servo(x) == pytest.approx(horn, abs=1e-12)
    for x in (-0.01, 0.0, 0.005, 0.019):
        assert GRIPPER.to_finger(GRIPPER.to_servo(x)) == pytest.approx(x, abs=1e-12)
    assert GRIPPER.clamp(0.05) == 0.019 and GRIPPER.clamp(-1.0) == -0.010
    with pytest.raises(ValueError, match="finite"):
        GRIPPER.clamp(math.nan)


def test_a_drafted_map_names_the_fifth_servo_the_gripper(tmp_path):
    """``armlab scan --write-map`` on an OpenManipulator-X: four joints and a [gripper]
    table, which the map reader turns back into the same gripper servo."""
    found = [Found(i, 1020, "XM430-W350", 46, 1e6, 3, 0, 4095, -180.0, 179.9, 0, 2)
             for i in (11, 12, 13, 14, 15)]
    path = tmp_path / "omx.toml"
    path.write_text(draft_joint_map(found, OMX))
    jmap = load_joint_map(path, OMX)
    assert jmap.ids == (11, 12, 13, 14)
    g = jmap.gripper
    assert (g.servo_id, g.joint, g.lower, g.upper) == (15, GRIPPER.joint, -0.010, 0.019)
    assert (g.closed_angle, g.open_angle) == pytest.approx((OMX_CLOSED_ANGLE, OMX_OPEN_ANGLE))
    text = path.read_text().replace("id = 15", "id = 12")
    path.write_text(text)
    with pytest.raises(ValueError, match="duplicate servo IDs"):
        load_joint_map(path, OMX)


@REALTIME
def test_emulate_serves_the_gripper_servo_after_the_given_ids():
    """``--ids`` names the chain's servos; the gripper's takes the next ID."""
    from armlab.hardware.wire.scan import scan

    with emulator("--robot", "open_manipulator_x", "--ids", "1,2,3,4") as emu:
        found = scan(emu.port, (1_000_000,), ids=range(0, 8))
        assert "IDs 1, 2, 3, 4 and the gripper's 5" in emu.stderr()
    assert [(f.servo_id, f.model_number, f.protocol) for f in found] == \
        [(i, 1020, 2) for i in (1, 2, 3, 4, 5)]
    assert default_joint_map(OMX, ids=(1, 2, 3, 4)).gripper.servo_id == 5


@REALTIME
def test_the_gripper_is_configured_clamped_moved_and_switched_off(tmp_path):
    with emulator("--robot", "open_manipulator_x", log_dir=tmp_path) as emu:
        b = make_backend("serial", OMX, port=emu.port, timeout_margin=MARGIN)
        try:
            assert isinstance(b, XSeriesBackend) and b.n == 4
            assert b.gripper_range == (-0.010, 0.019)
            text = "\n".join(b.configuration)
            for step in ("servo 15 (gripper gripper_left_joint): torque off",
                         "servo 15 (gripper gripper_left_joint): operating mode 5 (current-based",
                         "servo 15 (gripper gripper_left_joint): goal current 100 (0.27 A"):
                assert step in text
            assert b.bus.read(15, "operating_mode") == OperatingMode.CURRENT_BASED_POSITION
            assert b.bus.read(15, "goal_current") == round(
                GRIPPER_CURRENT / XM430_W350.current_unit) == 100
            for i in (11, 12, 13, 14):  # the arm's servos keep the arm's torque bound
                assert b.bus.read(i, "goal_current") == 1193
            sent = b.bus.stats.transactions - b.bus.stats.retries
            state = b.read()
            assert b.bus.stats.transactions - b.bus.stats.retries == sent + 1  # one SYNC_READ
            assert state.gripper is not None and not state.gripper.torque_on
            b.set_torque(True)
            assert b.set_gripper(0.5) == 0.019  # far beyond open: clamped
            sent = b.bus.stats.transactions - b.bus.stats.retries
            b.write(state.position, SPEED)
            assert b.bus.stats.transactions - b.bus.stats.retries == sent + 1  # one SYNC_WRITE
            with pytest.raises(ValueError, match="finite"):
                b.set_gripper(math.inf)

            def finger() -> float:
                b.write(state.position, SPEED)
                return b.read().gripper.position

            wait_for(lambda: abs(finger() - 0.019) < 0.0005, 30, "the fingers open")
            b.set_gripper(-0.5)  # far beyond closed: clamped; closing on nothing
            wait_for(lambda: abs(finger() + 0.010) < 0.0005, 30, "the fingers at their limit")
            ends = sorted(XM430_W350.position_to_raw(a) for a in (OMX_CLOSED_ANGLE,
                                                                  OMX_OPEN_ANGLE))
            goals = goal_positions(emu.packets("rx"), 15)
            assert goals and ends[0] <= min(goals) and max(goals) <= ends[1]
            assert ends[0] in goals and ends[1] in goals  # both ends were asked for
            assert b.read().gripper.torque_on
            assert b.estop()
            wait_for(lambda: b.bus.read(15, "torque_enable") == 0, 10,
                     "the gripper's torque off")
            assert not b.read().gripper.torque_on
        finally:
            b.close()


@REALTIME
def test_a_gripper_servo_that_does_not_answer_is_named(tmp_path):
    path = tmp_path / "omx.toml"
    path.write_text('servo = "XM430-W350"\nprotocol = 2.0\n'
                    + "".join(f'[[joints]]\nname = "joint{k}"\nid = {10 + k}\n'
                              for k in range(1, 5))
                    + '[gripper]\nid = 20\njoint = "gripper_left_joint"\n')
    with emulator("--robot", "open_manipulator_x") as emu:
        with pytest.raises(BackendError, match=r"gripper's servo \(ID 20, "
                           r"gripper_left_joint\).*armlab scan"):
            make_backend("serial", OMX, port=emu.port, joint_map=str(path),
                         timeout_margin=MARGIN, retries=1)


@REALTIME
def test_the_lesson_opens_and_closes_the_gripper_on_the_servos():
    """What a teacher with an OpenManipulator-X does: serve it, click Open and Close; the
    servo's fingers move and the 3D view's fingers follow what it reports."""
    with emulator("--robot", "open_manipulator_x") as emu:
        lab = Lab(ServeOptions(robot="open_manipulator_x", backend="serial", port=emu.port,
                               http_port=0))
        try:
            lesson = lab.lesson
            assert isinstance(lesson.backend, XSeriesBackend)
            left = lesson.view.link_frames["gripper_left_link"]
            right = lesson.view.link_frames["gripper_right_link"]

            def finger() -> float:
                grip = lesson.loop.gripper
                return math.nan if grip is None else grip.position

            with client_of(lab.server, token=lab.token) as client:
                for button, goal in (("Open gripper", 0.019), ("Close gripper", -0.010)):
                    client.wait_for(lambda b=button: client.shows(b), 60.0, button)
                    client.click(button)
                    wait_for(lambda g=goal: abs(finger() - g) < 0.0005, 60,
                             lambda g=goal: f"servo 15's finger at {g} m (at {finger()})")
                    # the view's fingers: the left one along +y, the mimic along -y
                    wait_for(lambda: abs(left.position[1] - (0.021 + finger())) < 1e-6
                             and abs(right.position[1] - (-0.021 - finger())) < 1e-6, 30,
                             "the 3D view's fingers at the servo's position")
                client.wait_for(lambda: client.shows("gripper mm"), 30.0, "the slider")
                client.set_value("gripper mm", 5.0)
                wait_for(lambda: abs(finger() - 0.005) < 0.0005, 60, "the finger at 5 mm")
                assert lesson.loop.status.fault is None
                lesson.estop()
                wait_for(lambda: not lesson.loop.gripper.torque_on, 30,
                         "the gripper's torque off after E-STOP")
        finally:
            lab.close()


@pytest.mark.slow
def test_the_simulated_open_manipulator_x_has_its_gripper():
    """``--backend sim``: the same gripper servo in the simulated arm, driven by the loop."""
    backend = make_backend("sim", OMX)
    loop = ControlLoop(OMX, backend, realtime=False)
    try:
        loop.run_for(0.1)
        loop.post(SetGripper(0.019))
        loop.run_for(2.0)
        assert loop.gripper.position == pytest.approx(0.019, abs=5e-4)
        loop.post(SetGripper(-1.0))  # beyond closed: clamped, and said so
        loop.run_for(2.0)
        assert loop.gripper.position == pytest.approx(-0.010, abs=5e-4)
        assert "clamped" in loop.status.message
        assert loop.status.fault is None
    finally:
        backend.close()
