"""The gripper's servo of an arm: on ROBOTIS's OpenManipulator-X one XM430-W350 (ID 15)
opens and closes both fingers.

**Finger and horn.** The URDF draws the gripper as the prismatic ``gripper_left_joint``
(finger travel x, m; the right finger mimics it). The servo turns a horn angle a (rad
from the centre, raw 2048) that the gripper's linkage turns into finger travel; the lab
takes the two linearly related, as ROBOTIS's own ROS 2 driver does
(``open_manipulator_x_system.ros2_control.xacro`` of ROBOTIS-GIT/open_manipulator,
"revolute to prismatic gripper": horn 0.92 rad at x = -0.010 m, closed; -1.52 rad at
x = 0.019 m, open). The gripper's range is the URDF's finger limit (-0.010..0.019 m)
converted to the horn (:meth:`GripperServo.to_servo`): the horn turns through 2.44 rad
(140°) for 29 mm of finger travel, 11.9 mm a radian.

**Grip.** The servo runs in current-based position control (operating mode 5, which
ROBOTIS's e-manual requires for the gripper module, "Basic Operation"), so Goal
Current bounds its torque whatever the position error: squeezing an object, the
fingers press with at most :data:`GRIPPER_CURRENT` × torque constant at the horn, and
never more. ROBOTIS's open_manipulator_libs gives the OpenManipulator-X's gripper Goal
Current 200 (0.54 A) and the tool of its planar manipulator 100; the lab takes the
gentler 100 counts of the XM430 (0.27 A, 0.48 N·m at the horn: by virtual work about
20 N on each finger, :meth:`GripperServo.finger_force`).

**Load** (the emulator's and the simulator's gripper): the horn drives the two fingers'
mass through the linkage, :func:`reflected_inertia` (ROBOTIS's tool mass for the
gripper in open_manipulator_libs, 2 × 32.2 g, taken as the moving fingers), on top of
the servo's own rotor; the fingers stop at the ends of their travel (a finger closing
on nothing reaches its limit). Their weight along the travel is neglected (0.6 N of
fingers, 7 mN·m at the horn, well under the gear friction).

**The SO-101's jaw** (:func:`so101_gripper`): its STS3215 (ID 6) turns the moving jaw
directly, the URDF's revolute ``gripper`` joint (rad, -10°..100°), so the "finger" is that
joint's angle and the horn turns with it (closed at the joint's lower limit, open at its
upper, the horn's centre at the joint's zero). The servo has no current mode: the grip is
bounded by its Torque Limit (:data:`SO101_GRIPPER_TORQUE_LIMIT`, half of the maximum,
LeRobot's ``Max_Torque_Limit`` 500 for the SO-101's gripper, ``so_follower.py``), and the
force is the horn's torque over the jaw's lever (:data:`SO101_JAW_LEVER`, an *estimate*
from the URDF: the jaw's tip some 7 cm from its axis). The jaw's load on the servo is
its inertia about the axis, :data:`SO101_JAW_INERTIA` (an *estimate*: 30 g at 5 cm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from armlab.control.backend import GripperState
from armlab.hardware.servos.registry import FAMILIES, family_of_spec
from armlab.hardware.servos.servo_spec import TurnEncoder
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.model import Joint, Link, SerialChain
from armlab.kinematics.urdf_read import joint_kind, joint_limits

#: The OpenManipulator-X's finger joint in its URDF.
OMX_FINGER_JOINT = "gripper_left_joint"
#: rad, the horn at the finger's closed and open ends (ROBOTIS's ROS 2 driver, above).
OMX_CLOSED_ANGLE, OMX_OPEN_ANGLE = 0.92, -1.52
#: kg, the two fingers the horn moves (ROBOTIS open_manipulator_libs: 2 × 3.2218127e-02).
FINGERS_MASS = 2 * 3.2218127e-02
#: A, the gripper's Goal Current: 100 counts of the XM430-W350's 2.69 mA (see above).
GRIPPER_CURRENT = 100 * 2.69e-3
#: rad/s of the horn between goals: open to closed in about 1 s.
GRIPPER_SPEED = 2.5
#: The SO-101's jaw joint in its URDF (revolute, rad).
SO101_JAW_JOINT = "gripper"
#: m from the jaw's axis to where it presses (estimate, see above).
SO101_JAW_LEVER = 0.07
#: kg·m², the jaw about its axis (estimate: 30 g at 5 cm).
SO101_JAW_INERTIA = 0.030 * 0.05 ** 2
#: fraction of the maximum torque the SO-101's gripper servo may use (LeRobot's 500 of 1000).
SO101_GRIPPER_TORQUE_LIMIT = 0.5


@dataclass(frozen=True)
class GripperServo:
    """The servo that drives an arm's gripper and how its horn moves the finger.

    Attributes:
        servo_id: its Dynamixel ID (15 on the OpenManipulator-X).
        joint: the URDF's finger joint it drives (prismatic, m).
        lower, upper: m, the finger's range (closed, open): the URDF's limits.
        closed_angle, open_angle: rad from the horn's centre at ``lower`` and ``upper``.
        lever: m from a revolute jaw's axis to where it presses (the SO-101's), or None
            for fingers that slide (the OpenManipulator-X's, two of them).
        inertia: kg·m² of the load at the horn (None: :func:`reflected_inertia` of the
            OpenManipulator-X's fingers).
        revolute: whether the URDF's finger joint turns (a jaw: rad, the SO-101's) rather
            than slides (m, the OpenManipulator-X's); ``lower``/``upper`` are in its units.
    """

    servo_id: int
    joint: str
    lower: float
    upper: float
    closed_angle: float
    open_angle: float
    lever: float | None = None
    inertia: float | None = None
    revolute: bool = False

    def __post_init__(self) -> None:
        who = f"gripper servo ID {self.servo_id} ({self.joint})"
        top = max(f.codec.MAX_ID for f in FAMILIES)  # the highest ID any family's servo takes
        if not 0 <= self.servo_id <= top:
            raise ValueError(f"{who}: ID outside 0..{top}")
        values = (self.lower, self.upper, self.closed_angle, self.open_angle)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"{who}: its range and horn angles must be finite")
        if not self.lower < self.upper:
            raise ValueError(f"{who}: closed {self.lower} m must be below open {self.upper} m")
        if abs(self.open_angle - self.closed_angle) < 1e-6:
            raise ValueError(f"{who}: the horn angles closed and open must differ")

    @property
    def ratio(self) -> float:
        """dx/da, m of finger travel per rad of the horn (negative on the OMX)."""
        return (self.upper - self.lower) / (self.open_angle - self.closed_angle)

    def to_servo(self, x: float) -> float:
        """Finger position x (m) -> horn angle a (rad): a = a_closed + (x − lower) / ratio."""
        return self.closed_angle + (float(x) - self.lower) / self.ratio

    def to_finger(self, a: float) -> float:
        """Horn angle a (rad) -> finger position x (m): x = lower + ratio · (a − a_closed)."""
        return self.lower + self.ratio * (float(a) - self.closed_angle)

    def clamp(self, x: float) -> float:
        """A finger goal (m) inside [lower, upper]; ValueError for a non-finite one."""
        x = float(x)
        if not math.isfinite(x):
            raise ValueError(f"gripper goal must be a finite position in m, got {x}")
        return min(max(x, self.lower), self.upper)

    @property
    def angle_range(self) -> tuple[float, float]:
        """(lowest, highest) horn angle of the finger's range, rad."""
        return tuple(sorted((self.closed_angle, self.open_angle)))  # type: ignore[return-value]  # sorted() of two floats: two floats

    def finger_force(self, torque: float) -> float:
        """Horn torque (N·m) -> the force a finger presses with (N): a revolute jaw's
        torque over its lever (the jaw turns with the horn, :attr:`ratio` 1); sliding
        fingers by virtual work, tau · da = 2 F · dx, so F = tau / (2 |dx/da|)."""
        if self.lever is not None:
            return float(torque) / abs(self.ratio) / self.lever
        return float(torque) / (2.0 * abs(self.ratio))


def open_manipulator_gripper(urdf_path: str | Path, *, servo_id: int = 15) -> GripperServo:
    """The OpenManipulator-X's gripper servo, its range read from the URDF's finger joint.

    Raises:
        armlab.kinematics.model.URDFError: the file has no ``gripper_left_joint`` with limits.
    """
    lower, upper = joint_limits(urdf_path, OMX_FINGER_JOINT)
    return GripperServo(servo_id, OMX_FINGER_JOINT, lower, upper, OMX_CLOSED_ANGLE,
                        OMX_OPEN_ANGLE, revolute=is_revolute(urdf_path, OMX_FINGER_JOINT))


def so101_gripper(urdf_path: str | Path, *, servo_id: int = 6) -> GripperServo:
    """The SO-101's jaw servo (ID 6 in LeRobot's order), its range the URDF's ``gripper``
    joint, the horn turning with the jaw (see the module's docstring).

    Raises:
        armlab.kinematics.model.URDFError: the file has no ``gripper`` joint with limits.
    """
    lower, upper = joint_limits(urdf_path, SO101_JAW_JOINT)
    return GripperServo(servo_id, SO101_JAW_JOINT, lower, upper, lower, upper,
                        lever=SO101_JAW_LEVER, inertia=SO101_JAW_INERTIA,
                        revolute=is_revolute(urdf_path, SO101_JAW_JOINT))


def is_revolute(urdf_path: str | Path, joint: str) -> bool:
    """Whether the URDF's finger ``joint`` turns (revolute or continuous, rad) rather than
    slides (prismatic, m)."""
    return joint_kind(urdf_path, joint) != "prismatic"


class GripperHolder:
    """What a backend with an arm's gripper servo (:attr:`gripper`, None without one) says
    of it (``armlab.control.backend.Gripping``), whether the servos are on a bus or
    simulated; the backend holds its servos' datasheet as ``spec``."""

    gripper: GripperServo | None
    spec: Any  # each backend's own datasheet: ServoSpec, XSpec or StsSpec

    @property
    def gripper_range(self) -> tuple[float, float] | None:
        """(closed, open) of the gripper's finger (the URDF joint's units: m, or rad for a
        revolute jaw), or None without a gripper servo."""
        return None if self.gripper is None else (self.gripper.lower, self.gripper.upper)

    @property
    def gripper_revolute(self) -> bool:
        """Whether the gripper's finger joint turns (a jaw, rad) rather than slides (m)."""
        return self.gripper is not None and self.gripper.revolute

    @property
    def gripper_note(self) -> str:
        """How the gripper's servo holds the finger and bounds its grip ("" without one)."""
        if self.gripper is None:
            return ""
        note = family_of_spec(self.spec).grip_note
        return "" if note is None else note(self.spec)

    def _gripper_goal_raw(self, position: float) -> tuple[float, int]:
        """The finger's goal ``position`` clamped into its range (ValueError for a
        non-finite one) and its servo's raw Goal Position for it."""
        assert self.gripper is not None
        x = self.gripper.clamp(position)
        return x, self.spec.position_to_raw(self.gripper.to_servo(x))


def reflected_inertia(gripper: GripperServo, *, mass: float = FINGERS_MASS) -> float:
    """kg·m² the fingers add at the horn: their kinetic energy ½ m ẋ² with ẋ = (dx/da) ȧ
    is that of an inertia m (dx/da)² turning at ȧ; a gripper's own :attr:`~GripperServo.
    inertia` where it states one."""
    if gripper.inertia is not None:
        return gripper.inertia
    return mass * gripper.ratio ** 2


def gripper_chain(gripper: GripperServo) -> SerialChain:
    """The gripper's load as a one-joint chain a :class:`~armlab.hardware.sim.plant.Plant` moves:
    the horn's revolute joint (about the vertical, so gravity does no work) carrying
    :func:`reflected_inertia`, its limits the horn angles at the fingers' ends."""
    lo, hi = gripper.angle_range
    inertia = np.diag([0.0, 0.0, reflected_inertia(gripper)])
    joint = Joint(f"{gripper.joint} (servo horn)", "revolute", np.eye(4),
                  np.array([0.0, 0.0, 1.0]), lo, hi, math.inf, math.inf)
    return SerialChain("gripper", (joint,), (Link("fingers", 0.0, np.zeros(3), inertia),),
                       base_pose=np.eye(4), tip=np.eye(4), gravity=np.array([0.0, 0.0, -9.81]))


def gripper_plant(gripper: GripperServo, spec: TurnEncoder, *, dt: float = 1e-3,
                  registers: Any = None,
                  params: ServoParams | None = None) -> Plant:
    """The gripper's servo firmware (its family's) moving its load (:func:`gripper_chain`),
    horn at its centre, the fingers' ends as the plant's joint stops. ``registers``: the
    servo's, its family's type (default: its power-on values, as an emulated servo
    starts); ``params``: its
    physical constants and supply."""
    return Plant(gripper_chain(gripper), spec, dt=dt, params=params,
                 registers=None if registers is None else [registers])


def gripper_state(gripper: GripperServo, *, angle: float, speed: float, torque: float,
                  torque_on: bool, alarm: str = "") -> GripperState:
    """The horn's angle rad, speed rad/s and torque N·m as the finger's position and speed
    (the URDF joint's units: m on the OpenManipulator-X, rad on the SO-101), the horn's
    torque and the force a finger presses with, N."""
    return GripperState(joint=gripper.joint, position=gripper.to_finger(angle),
                        velocity=gripper.ratio * speed, effort=torque,
                        force=gripper.finger_force(torque), torque_on=torque_on, alarm=alarm)
