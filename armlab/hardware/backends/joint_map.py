"""Which servo drives which joint: ID, direction sign, zero offset and limits.

A joint angle q (rad, the robot model's convention) and the servo's horn angle
a (rad from raw 512, counter-clockwise positive, see ``armlab.hardware.servos.servo_spec``)
are related by ``q = offset + sign · a``. The map comes from a small JSON or
TOML file (angles in degrees for people), or by default from the robot model:
the thesis's left arm IDs 1, 3, 5 (thesis §2.3, "Set ID") for the receptionist
arm, 1..12 in leg order RF, LF, RH, LH for the quadruped, 1..n otherwise.

Example ``arm.toml`` (``armlab scan --write-map`` drafts one from the servos
that answer; ``protocol`` and ``baud`` record what they answered with)::

    servo = "RX-24F"
    protocol = 1.0
    baud = 1000000
    [[joints]]
    name = "theta1"
    id = 1
    sign = 1
    offset_deg = 0.0
    lower_deg = -150
    upper_deg = 150

An arm whose gripper has its own servo (the OpenManipulator-X's ID 15, the SO-101's ID
6) names it in a ``[gripper]`` table: its ``id``, the URDF's finger ``joint`` (its limits are the
gripper's range) and the horn angles at the finger's closed and open ends
(``closed_deg``, ``open_deg``; the OpenManipulator-X's are known, see
:mod:`armlab.hardware.backends.gripper`)::

    [gripper]
    id = 15
    joint = "gripper_left_joint"
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from armlab.hardware.backends.gripper import (
    GripperServo,
    is_revolute,
    open_manipulator_gripper,
    so101_gripper,
)
from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import ServoFamily
from armlab.hardware.servos.registry import FAMILIES, family, family_of_model, family_of_spec
from armlab.hardware.servos.registry import servo_table as _family_table
from armlab.hardware.servos.servo_spec import ServoSpec, TurnEncoder
from armlab.kinematics.catalog import ROBOT_FILES
from armlab.kinematics.model import Joint, Quadruped, SerialChain, URDFError
from armlab.kinematics.urdf_read import joint_limits

if TYPE_CHECKING:
    from armlab.hardware.wire.scan import Found


def protocols() -> tuple[float | str, ...]:
    """The protocol tags a joint map file may name, one per family (1.0, 2.0, "sts")."""
    return tuple(float(f.protocol) if isinstance(f.protocol, int) else f.protocol
                 for f in FAMILIES)


THESIS_LEFT_ARM_IDS = (1, 3, 5)
THESIS_RIGHT_ARM_IDS = (2, 4, 6)
#: Robot -> (servo model, IDs in joint order) of the arms that ship with their servos: the
#: thesis arm (RX-24F, IDs 1, 3, 5), ROBOTIS's OpenManipulator-X (XM430-W350, IDs
#: 11..14 from its public specification; its gripper's servo is in :data:`ROBOT_GRIPPERS`)
#: and the SO-101 (STS3215, IDs 1..5 in LeRobot's ``so_follower.py`` order).
ROBOT_SERVOS = {"receptionist_arm": ("RX-24F", THESIS_LEFT_ARM_IDS),
                "open_manipulator_x": ("XM430-W350", (11, 12, 13, 14)),
                # LeRobot's SO-101 follower: shoulder_pan 1 .. wrist_roll 5 (its gripper's
                # servo, ID 6, is in ROBOT_GRIPPERS)
                "so101": ("STS3215", (1, 2, 3, 4, 5))}
#: Robots whose servos' zero is each arm's own (the SO-101's STS3215s are assembled at any
#: horn angle; LeRobot calibrates every arm): the default map of one is not calibrated,
#: nor is that of an arm from a URDF the lab does not ship
OWN_ZERO = frozenset({"so101"})
#: Robot -> the supply its servos run from, V, where it is not their datasheet's: the
#: SO-101's 7.4 V STS3215s on the kit's 5 V supply (TheRobotStudio SO-ARM100 README).
ROBOT_SUPPLY = {"so101": 5.0}
#: Robot -> its gripper's servo (ID, finger joint and horn angles; the range comes from
#: the URDF): the OpenManipulator-X's ID 15, the SO-101's ID 6
#: (:mod:`armlab.hardware.backends.gripper`).
ROBOT_GRIPPERS = {"open_manipulator_x": open_manipulator_gripper, "so101": so101_gripper}


def drives_gripper(spec: object) -> bool:
    """Whether the lab can drive a gripper with a servo of datasheet ``spec``: an X-series
    servo in current-based position control (Goal Current bounds the grip), or a Feetech
    STS held to a Torque Limit (it has no current mode)."""
    try:
        hook = family_of_spec(spec).drives_gripper
    except ValueError:  # no datasheet the lab knows
        return False
    return hook is not None and hook(spec)


def servo_table(model: str | int) -> ControlTable:
    """The control table of any model of any servo family the lab drives (protocol 1.0:
    AX-12A, RX-24F; X-series: XL430-W250, XM430-W350, XL330-M288; Feetech: STS3215);
    ValueError listing every known model otherwise."""
    return _family_table(model)


@dataclass(frozen=True)
class JointServo:
    """One joint's servo.

    Attributes:
        name: joint name in the robot model.
        servo_id: Dynamixel ID 0..253.
        sign: +1 when the joint turns with the horn, −1 when against it.
        offset: rad, joint angle when the horn is at its centre (raw 512).
        lower, upper: rad, joint limits the backend enforces (inside the servo's range).
    """

    name: str
    servo_id: int
    sign: int = 1
    offset: float = 0.0
    lower: float = -math.radians(150.0)
    upper: float = math.radians(150.0)


@dataclass(frozen=True)
class JointMap:
    """The servos of a robot, in the robot model's joint order.

    Attributes:
        servo: model name every servo must be ("RX-24F", "AX-12A", or an X-series model:
            their protocol is :attr:`protocol`).
        joints: one :class:`JointServo` per joint.
        gripper: the gripper's servo, or None (the same model, one that
            :func:`drives_gripper`).
        calibrated: the offsets and signs are known to be the arm's own (a robot whose
            servos' zero is its maker's, a calibration, a map a person wrote); False for a
            drafted map or a robot whose servos sit at any horn angle (the SO-101): its
            angles may not be the model's, so the lab keeps torque off until a person says
            the arm is clear (:attr:`~armlab.control.loop.LoopStatus.held_off`).
    """

    servo: str
    joints: tuple[JointServo, ...]
    gripper: GripperServo | None = None
    calibrated: bool = True

    def __post_init__(self) -> None:
        spec = servo_table(self.servo).spec  # ValueError for an unknown model
        ids = [j.servo_id for j in self.joints]
        if self.gripper is not None:
            ids.append(self.gripper.servo_id)
            if not drives_gripper(spec):
                raise ValueError(
                    f"joint map: the gripper's servo (ID {self.gripper.servo_id}) needs "
                    "current-based position control (X-series) or a torque limit the lab "
                    f"holds it to (Feetech STS), which the {self.servo} lacks")
        if len(set(ids)) != len(ids):
            raise ValueError(f"joint map: duplicate servo IDs in {ids}")
        for j in self.joints:
            if not 0 <= j.servo_id <= 253:
                raise ValueError(f"joint map: {j.name} id {j.servo_id} outside 0..253")
            if j.sign not in (1, -1):
                raise ValueError(f"joint map: {j.name} sign must be 1 or -1, got {j.sign}")
            if not all(math.isfinite(v) for v in (j.offset, j.lower, j.upper)):
                raise ValueError(f"joint map: {j.name} offset and limits must be finite")
            if not j.lower < j.upper:
                raise ValueError(f"joint map: {j.name} lower limit must be below upper")

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(j.servo_id for j in self.joints)

    @property
    def spec(self) -> ServoSpec | TurnEncoder:
        return servo_table(self.servo).spec

    @property
    def family(self) -> ServoFamily:
        """The servo family of :attr:`servo` (:mod:`armlab.hardware.families`)."""
        return family_of_model(self.servo)

    @property
    def protocol(self) -> int | str:
        """The protocol the servos speak (1, 2 or "sts")."""
        return self.family.protocol

    @property
    def signs(self) -> np.ndarray:
        return np.array([j.sign for j in self.joints], dtype=float)

    @property
    def offsets(self) -> np.ndarray:
        return np.array([j.offset for j in self.joints])

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints])

    def to_servo(self, q: np.ndarray) -> np.ndarray:
        """(..., n) joint angles rad -> (..., n) horn angles rad: a = sign · (q − offset)."""
        return self.signs * (np.asarray(q, dtype=float) - self.offsets)

    def to_joint(self, a: np.ndarray) -> np.ndarray:
        """(..., n) horn angles rad -> (..., n) joint angles rad: q = offset + sign · a."""
        return self.offsets + self.signs * np.asarray(a, dtype=float)

    def servo_limits_to_joint(self, a_lo: np.ndarray, a_hi: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray]:
        """Horn-angle interval per servo -> (lower, upper) joint-angle interval."""
        q1, q2 = self.to_joint(a_lo), self.to_joint(a_hi)
        return np.minimum(q1, q2), np.maximum(q1, q2)


def robot_joints(model: SerialChain | Quadruped) -> list[Joint]:
    """The movable joints of a model in order (a quadruped: legs RF, LF, RH, LH)."""
    if isinstance(model, Quadruped):
        return [j for leg in model.legs.values() for j in leg.joints]
    return list(model.joints)


def default_servo(robot_name: str) -> str:
    """The servo model of a robot that ships with its servos (:data:`ROBOT_SERVOS`); the
    quadruped and the others AX-12A."""
    return ROBOT_SERVOS.get(robot_name, ("AX-12A", ()))[0]


def default_joint_map(model: SerialChain | Quadruped, *, servo: str | None = None,
                      ids: tuple[int, ...] | None = None) -> JointMap:
    """The map a robot gets without a config file: sign +1, offset 0, limits = the
    model's joint limits inside the servo's ±150°; the gripper's servo of a robot that
    ships with one (:data:`ROBOT_GRIPPERS`) when ``servo`` can drive it, its ID after
    the highest of ``ids`` when they are given (its own, 15, otherwise)."""
    joints = robot_joints(model)
    servo = servo or default_servo(model.name)
    given = ids is not None
    if ids is None:
        shipped = ROBOT_SERVOS.get(model.name, (None, ()))[1]
        ids = shipped if len(shipped) == len(joints) else tuple(range(1, len(joints) + 1))
    if len(ids) != len(joints):
        raise ValueError(f"ids: {len(ids)} given for the {len(joints)} joints of {model.name}")
    spec = servo_table(servo).spec
    half = spec.position_range / 2
    gripper = None
    if (model.name in ROBOT_GRIPPERS and model.urdf_path is not None
            and drives_gripper(spec)):
        gripper = ROBOT_GRIPPERS[model.name](model.urdf_path)
        if given:
            after = max(ids) + 1
            if after > 252:
                raise ValueError(f"ids: the gripper's servo takes the ID after the highest "
                                 f"({max(ids)}), and {after} is past 252")
            gripper = replace(gripper, servo_id=after)
    calibrated = model.name in ROBOT_FILES and model.name not in OWN_ZERO
    return JointMap(servo, tuple(
        JointServo(j.name, int(i), 1, 0.0, max(j.lower, -half), min(j.upper, half))
        for j, i in zip(joints, ids, strict=True)
    ), gripper, calibrated)


def load_joint_map(path: str | Path, model: SerialChain | Quadruped) -> JointMap:
    """Read a JSON or TOML joint map; ValueError naming the file and the problem.

    Keys: ``servo`` (optional, model name), ``joints``: a list of tables with
    ``name`` (must be a joint of ``model``, every joint listed once, any order),
    ``id``, and optional ``sign``, ``offset_deg``, ``lower_deg``, ``upper_deg``; an
    optional ``gripper`` table (its servo's ``id``, the URDF's finger ``joint``,
    ``closed_deg``/``open_deg``; see the module's docstring).
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ValueError(f"joint map {path}: {exc.strerror}") from None
    try:
        data = tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"joint map {path}: {exc}") from None
    protocol = data.get("protocol", 1.0)
    if protocol not in protocols():
        raise ValueError(f"joint map {path}: protocol {protocol!r} is not one this lab drives; "
                         f"known: {', '.join(map(str, protocols()))}")
    joints = robot_joints(model)
    try:
        base = default_joint_map(model, servo=data.get("servo"))
    except ValueError as exc:
        raise ValueError(f"joint map {path}: {exc}") from None
    if "protocol" in data and family(protocol) is not base.family:
        raise ValueError(f"joint map {path}: protocol {protocol} but the {base.servo} speaks "
                         f"protocol {base.family.label}")
    half = base.spec.position_range / 2
    by_name = {j.name: j for j in base.joints}
    entries = data.get("joints")
    if not isinstance(entries, list):
        raise ValueError(f"joint map {path}: needs a 'joints' list")
    given: dict[str, JointServo] = {}
    for e in entries:
        name = e.get("name")
        if name not in by_name:
            raise ValueError(
                f"joint map {path}: unknown joint {name!r}; joints: {', '.join(by_name)}")
        if "id" not in e:
            raise ValueError(f"joint map {path}: joint {name} needs an 'id'")
        d = by_name[name]
        try:
            given[name] = JointServo(
                name, int(e["id"]), int(e.get("sign", 1)),
                math.radians(float(e.get("offset_deg", 0.0))),
                math.radians(float(e["lower_deg"])) if "lower_deg" in e else d.lower,
                math.radians(float(e["upper_deg"])) if "upper_deg" in e else d.upper,
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"joint map {path}: joint {name}: {exc}") from None
        js = given[name]
        for which, value in (("lower", js.lower), ("upper", js.upper)):
            if abs(value) > half + 1e-9:
                raise ValueError(
                    f"joint map {path}: joint {name!r} (servo ID {js.servo_id}, {base.servo}): "
                    f"{which} limit {math.degrees(value):+.1f} deg is outside the servo's "
                    f"range ±{math.degrees(half):.1f} deg")
    missing = [j.name for j in joints if j.name not in given]
    if missing:
        raise ValueError(f"joint map {path}: no servo for joint(s) {', '.join(missing)}")
    try:
        gripper = _gripper_entry(data.get("gripper"), model, base.gripper)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"joint map {path}: {exc}") from None
    calibrated = data.get("calibrated", True)  # a map a person wrote is theirs
    if not isinstance(calibrated, bool):
        raise ValueError(f"joint map {path}: calibrated must be true or false, "
                         f"got {calibrated!r}")
    try:
        return JointMap(base.servo, tuple(given[j.name] for j in joints), gripper, calibrated)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def _gripper_entry(entry: object, model: SerialChain | Quadruped,
                   shipped: GripperServo | None) -> GripperServo | None:
    """A map file's ``[gripper]`` table as a :class:`GripperServo` (None without one): its
    ``id``, the URDF's finger ``joint`` (whose limits are the range) and the horn angles
    ``closed_deg``/``open_deg`` (defaults: the robot's own gripper's)."""
    if entry is None:
        return None
    if not isinstance(entry, dict) or "id" not in entry:
        raise ValueError("[gripper] needs an 'id' (the gripper servo's ID)")
    joint = entry.get("joint", shipped.joint if shipped else None)
    if joint is None or model.urdf_path is None:
        raise ValueError("[gripper] needs the URDF's finger 'joint' it drives")
    try:
        lower, upper = joint_limits(model.urdf_path, str(joint))
    except URDFError as exc:
        raise ValueError(f"[gripper]: {exc}") from None
    angles = {}
    for key, attr in (("closed_deg", "closed_angle"), ("open_deg", "open_angle")):
        if key in entry:
            angles[attr] = math.radians(float(entry[key]))
        elif shipped is not None:
            angles[attr] = getattr(shipped, attr)
        else:
            raise ValueError(f"[gripper] needs '{key}', the horn angle at the finger's "
                             f"{key.split('_')[0]} end")
    # the robot's own gripper keeps its jaw's lever and load (the SO-101's)
    same = shipped is not None and shipped.joint == joint
    return GripperServo(int(entry["id"]), str(joint), lower, upper, **angles,
                        lever=shipped.lever if same else None,  # type: ignore[union-attr]  # same: shipped is not None
                        inertia=shipped.inertia if same else None,  # type: ignore[union-attr]  # same: shipped is not None
                        revolute=is_revolute(model.urdf_path, str(joint)))


def draft_joint_map(found: Sequence[Found], model: SerialChain | None = None) -> str:
    """TOML text of a joint map for the servos that answered a scan.

    Servos go to joints in ascending ID order (chain order, base first); limits are
    the servos' own CW/CCW angle limits (sign +1, offset 0), narrowed to the
    model's joint limits when ``model`` is given. With ``model`` (the
    robot's URDF) joints take its names, and a servo count that differs from its
    joint count is refused naming the joint without a servo or the servo without a joint;
    on a robot whose gripper has its own servo (:data:`ROBOT_GRIPPERS`) one servo more
    than joints is that gripper's (the highest ID) and gets a ``[gripper]`` table.

    Raises:
        ValueError: nothing answered, a model the lab does not know (the message lists
            the known ones), servos of mixed models, or the count mismatch above.
    """
    servos = sorted(found, key=lambda f: f.servo_id)
    if not servos:
        raise ValueError("no servo answered: nothing to write a map from")
    for f in servos:
        if f.model == "unknown":
            try:
                servo_table(f.model_number)
            except ValueError as exc:  # the message lists the known models
                raise ValueError(f"servo ID {f.servo_id}: {exc}") from None
    models = {f.model for f in servos}
    if len(models) > 1:
        raise ValueError("servos of several models answered ("
                         + ", ".join(f"ID {f.servo_id}: {f.model}" for f in servos)
                         + "); a map drives one model: scan the arm's servos only (--ids)")
    names = [f"joint{i + 1}" for i in range(len(servos))]
    gripper = None
    if model is not None:
        names = list(model.joint_names)
        if (len(servos) == len(names) + 1 and model.name in ROBOT_GRIPPERS
                and model.urdf_path is not None):
            gripper = replace(ROBOT_GRIPPERS[model.name](model.urdf_path),
                              servo_id=servos[-1].servo_id)
            servos = servos[:-1]
        if len(servos) < len(names):
            raise ValueError(
                f"joint {names[len(servos)]!r} of {model.name} has no servo: "
                f"{len(names)} joints, but only servo ID(s) "
                f"{', '.join(str(f.servo_id) for f in servos)} answered")
        if len(servos) > len(names):
            raise ValueError(
                f"servo ID {servos[len(names)].servo_id} has no joint: {model.name} has "
                f"{len(names)} joints ({', '.join(names)}) but {len(servos)} servos answered")
    bauds = {f.baud for f in servos}
    lines = ["# Drafted by armlab scan: check every sign and offset with the arm held safe,",
             "# then set calibrated = true (until then the lab starts with torque off)",
             f'servo = "{servos[0].model}"', f"protocol = {toml_protocol(servos[0].protocol)}",
             f"baud = {int(min(bauds))}", "calibrated = false", ""]
    for i, (name, f) in enumerate(zip(names, servos, strict=True)):
        wheel = f.cw_limit == f.ccw_limit == 0
        lo, hi = f.cw_limit_deg, f.ccw_limit_deg
        if model is not None and not wheel:  # never wider than the URDF allows
            lo = max(lo, math.degrees(model.joints[i].lower))
            hi = min(hi, math.degrees(model.joints[i].upper))
            if lo >= hi:
                raise ValueError(
                    f"joint {name!r} (servo ID {f.servo_id}): the URDF's limits and the "
                    f"servo's angle limits {f.cw_limit_deg:+.1f}..{f.ccw_limit_deg:+.1f} deg "
                    "do not overlap")
        lines += ["[[joints]]", f'name = "{name}"', f"id = {f.servo_id}", "sign = 1",
                  "offset_deg = 0.0"]
        if wheel:
            lines.append("# this servo is in wheel mode (angle limits 0): set its limits first")
        else:
            lines += [f"lower_deg = {lo:.3f}", f"upper_deg = {hi:.3f}"]
        lines.append("")
    if gripper is not None:
        lines += gripper_toml(gripper)
    return "\n".join(lines)


def gripper_toml(gripper: GripperServo) -> list[str]:
    """The lines of a map's ``[gripper]`` table for ``gripper`` (angles in degrees)."""
    return [f"# the gripper's servo: its range is the URDF's {gripper.joint} limits",
            "[gripper]", f"id = {gripper.servo_id}", f'joint = "{gripper.joint}"',
            f"closed_deg = {math.degrees(gripper.closed_angle):.4f}",
            f"open_deg = {math.degrees(gripper.open_angle):.4f}", ""]


def toml_protocol(protocol: int | str) -> str:
    """A family's protocol tag as a joint map writes it: 1.0, 2.0 or "sts"."""
    return f"{protocol}.0" if isinstance(protocol, int) else f'"{protocol}"'
