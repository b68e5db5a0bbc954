"""A joint map naming the wrong servo family: the servos on the port speak the other
protocol, and opening the backend says so in one line instead of "no reply".

Over a real pseudo-terminal with ``armlab emulate``: the thesis arm's protocol-1.0 servos
opened with the X-series backend (a map naming XM430-W350), and the OpenManipulator-X's
protocol-2.0 servos opened with the protocol-1.0 backend (a map naming RX-24F). Each
gives one message naming the protocol the servos answer, their IDs and the map's model;
no servo's torque comes on.
"""

from __future__ import annotations

import pytest
from _emulator import emulator

from armlab.control.backend import BackendError
from armlab.hardware.backends.joint_map import default_joint_map
from armlab.hardware.family_parts import open_servo_backend
from armlab.hardware.wire.bus import Bus
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator over a pseudo-terminal

MARGIN = 0.1  # s of reply timeout: generous, the test machine is shared


@pytest.mark.parametrize(("robot", "servo", "emulate", "answers", "named"), [
    ("receptionist_arm", "XM430-W350", (), "protocol 1.0 (IDs 1, 3, 5)", "(protocol 2.0)"),
    ("open_manipulator_x", "RX-24F", ("--robot", "open_manipulator_x"),
     "protocol 2.0 (IDs 11, 12, 13, 14, 15)", "(protocol 1.0)"),
    # a Feetech bus asks protocol 2.0 (1.0's PING is its own bytes: no telling them apart)
    ("so101", "STS3215", ("--robot", "open_manipulator_x"),
     "protocol 2.0 (IDs 11, 12, 13, 14, 15)", "(Feetech STS)"),
])
def test_a_map_naming_the_other_protocol_s_servos_is_named(robot, servo, emulate, answers,
                                                           named):
    model = load_robot(robot)
    jmap = default_joint_map(model, servo=servo)  # the map a technician got wrong
    with emulator(*emulate) as emu:
        with pytest.raises(BackendError) as caught:
            open_servo_backend(model, emu.port, joint_map=jmap, timeout_margin=MARGIN)
        text = str(caught.value)
        assert text == (f"the servos on {emu.port} answer {answers}, but the joint map "
                        f"names {servo} {named}: fix the map's servo model "
                        f"(armlab scan --port {emu.port} shows what answers)")
        assert "\n" not in text
        # the port was let go, and every servo's torque is still off
        theirs = 1 if robot == "receptionist_arm" else 2
        with Bus(emu.port, protocol=theirs, timeout_margin=MARGIN) as bus:
            for i in (11, 12, 13, 14) if theirs == 2 else (1, 3, 5):
                assert bus.read(i, "torque_enable") == 0


def test_nothing_answering_either_protocol_still_says_no_reply():
    model = load_robot("receptionist_arm")
    jmap = default_joint_map(model, servo="RX-24F", ids=(21, 23, 25))  # not on the bus
    with emulator() as emu:
        with pytest.raises(BackendError, match="no reply from servo 21"):
            open_servo_backend(model, emu.port, joint_map=jmap, timeout_margin=MARGIN)
