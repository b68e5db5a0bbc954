"""The lab's own calibration, for an arm without a LeRobot file: each joint guided in the
terminal to the middle of its range and to its two ends, read from its servo, and the
joint map written from what was read (``armlab scan --port P --robot so101 --calibrate
--write-map MAP.toml``).

The servos' torque goes off first (broadcast), so a person moves every joint by hand:
for each joint, in the robot's order, the middle of its range (the URDF's zero: the
SO-101's URDF is drawn for the middle of LeRobot's calibrated range, as
:mod:`armlab.hardware.backends.lerobot_calibration` reads it), then one end, then the
other; for the gripper's servo the jaw closed, then open. After each place the person
presses Enter and the servo's Present Position is read (three times, the middle of the
three kept: a joint still swinging is read again by the person's next Enter anyway).

A joint's map entry is :func:`~armlab.hardware.backends.lerobot_calibration.
joint_from_range` of what was read, the servo turning with the joint (LeRobot's
``drive_mode`` 0, which its SO-101 uses on every motor); a range reaching past the
URDF's limits is refused naming the joint and its servo. The gripper's horn angles at
closed and open become the map's ``[gripper]``.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable
from dataclasses import replace

from armlab.hardware.backends.joint_map import JointMap, JointServo, default_joint_map
from armlab.hardware.backends.lerobot_calibration import joint_from_range
from armlab.hardware.wire.bus import Bus
from armlab.kinematics.model import SerialChain

#: What a joint is moved to, in order, and the words that ask for it.
JOINT_PLACES = (("middle", "to the middle of its range"), ("end", "to one end of its range"),
                ("other end", "to the other end of its range"))
GRIPPER_PLACES = (("closed", "closed"), ("open", "fully open"))
READS = 3  #: Present Position reads a place, the middle one kept


def calibrate(bus: Bus, model: SerialChain, *, ask: Callable[[str], None],
              say: Callable[[str], None] = lambda text: None,
              jmap: JointMap | None = None) -> JointMap:
    """Guide a person through every joint of ``model`` (and its gripper's servo) and
    return the joint map of what was read.

    Args:
        bus: the servos' bus (their family's protocol, their baud).
        model: the arm.
        ask: shows one instruction and returns once the person has done it (the terminal:
            print it, wait for Enter).
        say: shows a line of progress (what was read).
        jmap: the servos' IDs (default: the robot's shipped map, with its gripper).

    Raises:
        ValueError: a range past the URDF's limits, naming the joint and its servo.
        armlab.hardware.wire.errors.BusError: a servo that does not answer.
    """
    jmap = jmap or default_joint_map(model)
    spec = jmap.spec
    bus.write_bytes(bus.broadcast_id, *bus.table.encode("torque_enable", 0))
    say("torque off on every servo: move the arm by hand, holding it")
    joints: list[JointServo] = []
    for j, servo in zip(model.joints, jmap.joints, strict=True):
        raw = {}
        for place, words in JOINT_PLACES:
            ask(f"Move {j.name} (servo {servo.servo_id}) {words}, then press Enter")
            raw[place] = _position(bus, servo.servo_id)
            say(f"{j.name}: {place} at {raw[place]}")
        joints.append(joint_from_range(j, servo.servo_id, spec, sign=1, middle=raw["middle"],
                                       ends=(raw["end"], raw["other end"])))
    gripper = jmap.gripper
    if gripper is not None:
        raw = {}
        for place, words in GRIPPER_PLACES:
            ask(f"Put the gripper (servo {gripper.servo_id}) {words}, then press Enter")
            raw[place] = _position(bus, gripper.servo_id)
            say(f"gripper: {place} at {raw[place]}")
        gripper = replace(gripper, closed_angle=spec.raw_to_position(raw["closed"]),
                          open_angle=spec.raw_to_position(raw["open"]))
    return JointMap(jmap.servo, tuple(joints), gripper)


def _position(bus: Bus, servo_id: int) -> int:
    """Present Position of ``servo_id``: the middle of :data:`READS` reads."""
    return int(statistics.median(bus.read(servo_id, "present_position") for _ in range(READS)))
