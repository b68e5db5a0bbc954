"""An arm calibrated with LeRobot: its calibration file turned into the lab's joint map.

LeRobot keeps one JSON file per arm, per motor ``{"id", "drive_mode", "homing_offset",
"range_min", "range_max"}`` (``MotorCalibration`` in LeRobot's
``src/lerobot/motors/motors_bus.py`` at 7427f31). The homing offset lives in the servo's
EEPROM (Feetech: Present Position = actual position − Homing Offset, LeRobot
``feetech.py``), so the lab reads the same present positions LeRobot does, and
``range_min``/``range_max`` are present positions. LeRobot's degrees for a body joint are
``(position − mid) · 360 / 4095`` with ``mid`` the middle of the range, negated when
``drive_mode`` is 1 (``MotorsBus._normalize``, ``MotorNormMode.DEGREES``).

The lab's map says ``q = offset + sign · a`` with ``a`` the horn angle from raw 2048
(:mod:`armlab.hardware.backends.joint_map`), so a joint gets ``sign = −1`` when
``drive_mode`` is 1, ``offset = −sign · a(mid)``, and the range as its limits. The
SO-101's URDF (``so101_new_calib``) is taken as drawn for LeRobot's calibration: its
joint zero is the middle of the calibrated range (*interpretation* of the file's name).
A range reaching past the URDF's limits is refused naming the joint; the lab's unit is
4096 counts a turn (LeRobot's 4095 differs by 0.02 %).

The gripper's motor (LeRobot normalises it 0..100 over its range, not in degrees) becomes
the map's ``[gripper]``: its range laid onto the URDF's jaw joint, ``range_min`` at the
joint's lower limit (closed) and ``range_max`` at its upper (open), the other way round
when ``drive_mode`` is 1 (*interpretation*: LeRobot names no closed end).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

from armlab.hardware.backends.joint_map import (
    ROBOT_GRIPPERS,
    JointMap,
    JointServo,
    gripper_toml,
    robot_joints,
    servo_table,
    toml_protocol,
)
from armlab.kinematics.model import Joint, SerialChain

FIELDS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")
TOLERANCE = math.radians(0.5)  #: how far a range may pass a URDF limit (rounding)


def joint_map_from_lerobot(path: str | Path, model: SerialChain, *,
                           servo: str = "STS3215") -> JointMap:
    """The joint map of ``model`` from LeRobot's calibration file at ``path``.

    Motors named as ``model``'s joints are mapped, every joint needs one; the gripper's
    motor (named as the robot's gripper joint, :data:`~armlab.hardware.backends.joint_map.
    ROBOT_GRIPPERS`) becomes the map's gripper when the file has it; other motors are
    left out.

    Raises:
        ValueError: one line naming the file and the problem (unreadable, a field
            missing, a joint without a motor, a range past the URDF's limits).
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise ValueError(f"calibration {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"calibration {path}: not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"calibration {path}: expected one object per motor, by name")
    spec = servo_table(servo).spec
    joints = []
    for j in robot_joints(model):
        servo_id, drive, lo, hi = _motor(path, data, j.name)
        try:
            joints.append(joint_from_range(j, servo_id, spec, sign=-1 if drive else 1,
                                           middle=(lo + hi) / 2, ends=(lo, hi)))
        except ValueError as exc:
            raise ValueError(f"calibration {path}: {exc}") from None
    gripper = None
    if model.name in ROBOT_GRIPPERS and model.urdf_path is not None:
        shipped = ROBOT_GRIPPERS[model.name](model.urdf_path)
        if shipped.joint in data:
            servo_id, drive, lo, hi = _motor(path, data, shipped.joint)
            closed, opened = (hi, lo) if drive else (lo, hi)
            gripper = replace(shipped, servo_id=servo_id,
                              closed_angle=spec.raw_to_position(closed),
                              open_angle=spec.raw_to_position(opened))
    return JointMap(servo, tuple(joints), gripper)


def joint_from_range(joint: Joint, servo_id: int, spec: object, *, sign: int,
                     middle: float, ends: tuple[float, float]) -> JointServo:
    """A joint's servo from a calibrated range: the servo's raw position at the joint's
    zero (``middle``, the URDF's zero) and at the ends of its range, the servo turning
    with the joint (``sign`` 1) or against it (-1): ``offset = -sign · a(middle)``, the
    range as its limits (never wider than the URDF's).

    Raises:
        ValueError: naming the joint and its servo, when the range reaches past the URDF's
            limits (more than :data:`TOLERANCE`).
    """
    a = spec.raw_to_position  # type: ignore[attr-defined]  # a TurnEncoder spec (the LeRobot arms' servos)
    offset = -sign * a(middle)
    lo, hi = sorted(offset + sign * a(r) for r in ends)
    if lo < joint.lower - TOLERANCE or hi > joint.upper + TOLERANCE:
        raise ValueError(
            f"joint {joint.name!r} (servo ID {servo_id}): its range "
            f"{math.degrees(lo):+.1f}..{math.degrees(hi):+.1f} deg reaches past the URDF's "
            f"limits {math.degrees(joint.lower):+.1f}..{math.degrees(joint.upper):+.1f} deg: "
            "calibrate again, or check the arm's URDF")
    return JointServo(joint.name, servo_id, sign, offset, max(lo, joint.lower),
                      min(hi, joint.upper))


def _motor(path: Path, data: dict, name: str) -> tuple[int, int, int, int]:
    """Motor ``name`` of the file: (ID, drive mode, range_min, range_max); ValueError naming
    the file, the motor and what is missing or wrong."""
    entry = data.get(name)
    if not isinstance(entry, dict):
        raise ValueError(f"calibration {path}: no motor for joint {name!r}; motors: "
                         f"{', '.join(data)}")
    missing = [f for f in FIELDS if f not in entry]
    if missing:
        raise ValueError(f"calibration {path}: motor {name!r} lacks {', '.join(missing)}")
    servo_id, drive = int(entry["id"]), int(entry["drive_mode"])
    lo, hi = int(entry["range_min"]), int(entry["range_max"])
    if drive not in (0, 1) or not lo < hi:
        raise ValueError(f"calibration {path}: motor {name!r} (ID {servo_id}): "
                         f"drive_mode 0 or 1 and range_min < range_max, got {drive}, "
                         f"{lo}..{hi}")
    return servo_id, drive, lo, hi


def joint_map_toml(jmap: JointMap, *, baud: float, source: str = "") -> str:
    """TOML text of ``jmap`` (angles in degrees), as :func:`~armlab.hardware.backends.
    joint_map.load_joint_map` reads it."""
    lines = [f"# Written by armlab from {source}" if source else "# Written by armlab",
             f'servo = "{jmap.servo}"', f"protocol = {toml_protocol(jmap.protocol)}",
             f"baud = {int(baud)}", "calibrated = true", ""]
    for j in jmap.joints:
        lines += ["[[joints]]", f'name = "{j.name}"', f"id = {j.servo_id}",
                  f"sign = {j.sign}", f"offset_deg = {math.degrees(j.offset):.4f}",
                  f"lower_deg = {math.degrees(j.lower):.4f}",
                  f"upper_deg = {math.degrees(j.upper):.4f}", ""]
    if jmap.gripper is not None:
        lines += gripper_toml(jmap.gripper)
    return "\n".join(lines)
