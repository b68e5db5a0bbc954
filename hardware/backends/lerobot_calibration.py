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
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from armlab.hardware.backends.joint_map import JointMap, JointServo, robot_joints, servo_table
from armlab.kinematics.model import SerialChain

FIELDS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")
TOLERANCE = math.radians(0.5)  #: how far a range may pass a URDF limit (rounding)


def joint_map_from_lerobot(path: str | Path, model: SerialChain, *,
                           servo: str = "STS3215") -> JointMap:
    """The joint map of ``model`` from LeRobot's calibration file at ``path``.

    Motors named as ``model``'s joints are mapped (others, such as the gripper, which the
    lab does not drive as a joint, are left out); every joint needs one.

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
        entry = data.get(j.name)
        if not isinstance(entry, dict):
            raise ValueError(f"calibration {path}: no motor for joint {j.name!r}; motors: "
                             f"{', '.join(data)}")
        missing = [f for f in FIELDS if f not in entry]
        if missing:
            raise ValueError(f"calibration {path}: motor {j.name!r} lacks "
                             f"{', '.join(missing)}")
        servo_id, drive = int(entry["id"]), int(entry["drive_mode"])
        lo, hi = int(entry["range_min"]), int(entry["range_max"])
        if drive not in (0, 1) or not lo < hi:
            raise ValueError(f"calibration {path}: motor {j.name!r} (ID {servo_id}): "
                             f"drive_mode 0 or 1 and range_min < range_max, got {drive}, "
                             f"{lo}..{hi}")
        sign = -1 if drive else 1
        mid = spec.raw_to_position((lo + hi) / 2)
        offset = -sign * mid
        ends = sorted(offset + sign * spec.raw_to_position(r) for r in (lo, hi))
        if ends[0] < j.lower - TOLERANCE or ends[1] > j.upper + TOLERANCE:
            raise ValueError(
                f"calibration {path}: joint {j.name!r} (servo ID {servo_id}): its range "
                f"{math.degrees(ends[0]):+.1f}..{math.degrees(ends[1]):+.1f} deg reaches past "
                f"the URDF's limits {math.degrees(j.lower):+.1f}..{math.degrees(j.upper):+.1f}"
                " deg: calibrate again, or check the arm's URDF")
        joints.append(JointServo(j.name, servo_id, sign, offset,
                                 max(ends[0], j.lower), min(ends[1], j.upper)))
    return JointMap(servo, tuple(joints))


def joint_map_toml(jmap: JointMap, *, baud: float, source: str = "") -> str:
    """TOML text of ``jmap`` (angles in degrees), as :func:`~armlab.hardware.backends.
    joint_map.load_joint_map` reads it."""
    protocol = jmap.protocol
    tag = f"{protocol}.0" if isinstance(protocol, int) else f'"{protocol}"'
    lines = [f"# Written by armlab from {source}" if source else "# Written by armlab",
             f'servo = "{jmap.servo}"', f"protocol = {tag}", f"baud = {int(baud)}", ""]
    for j in jmap.joints:
        lines += ["[[joints]]", f'name = "{j.name}"', f"id = {j.servo_id}",
                  f"sign = {j.sign}", f"offset_deg = {math.degrees(j.offset):.4f}",
                  f"lower_deg = {math.degrees(j.lower):.4f}",
                  f"upper_deg = {math.degrees(j.upper):.4f}", ""]
    return "\n".join(lines)
