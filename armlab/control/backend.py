"""The one interface the controller sees of the servos: the ``Backend`` protocol.

It is met in two ways. Simulated: ``armlab.hardware.families.dynamixel1.sim_backend.SimBackend`` (an
arm and
its servos; ``XSimBackend``, ``StsSimBackend`` for the X-series and Feetech models, with a
gripper), ``BatchedArmBackend`` (one arm of a class's batched plant),
``QuadrupedSimBackend`` and ``BatchedQuadrupedBackend``. On a serial port (real or
emulated servos), one per servo family over ``ServoBusBackend``:
``armlab.hardware.families.dynamixel1.backend.DynamixelBackend`` (protocol 1.0), ``XSeriesBackend``
(protocol 2.0) and ``StsBackend`` (Feetech). The server holds a class worker's arms
through ``RemoteBackend``. The control loop works on any of them and never imports viser
or pyserial.

Joint space throughout: positions in rad, speeds in rad/s, torques in N·m, in
the robot model's joint order and sign convention. Each backend maps joints
to servos (ID, direction, zero offset) itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from armlab.kinematics.smallarrays import all_finite, clamp


@dataclass(frozen=True)
class GripperState:
    """What a gripper's servo reports, in the URDF's finger joint (never ground truth).

    Attributes:
        joint: the URDF's finger joint (the other finger mimics it).
        position: m, the finger joint's position.
        velocity: m/s of the finger.
        effort: N·m at the servo's horn (its current × torque constant).
        force: N each finger presses with (the horn's torque through the linkage).
        torque_on: whether the gripper's servo holds torque.
        alarm: its hardware error ("" = healthy).
    """

    joint: str
    position: float
    velocity: float
    effort: float
    force: float
    torque_on: bool
    alarm: str = ""


@dataclass(frozen=True)
class JointState:
    """What the servos report at one instant (never ground truth).

    Attributes:
        t: backend time, s (simulation time for SimBackend, monotonic for hardware).
        position: (n,) rad, as the servo reports it (10-bit quantised).
        velocity: (n,) rad/s, from Present Speed (signed).
        load: (n,) N·m, from Present Load (signed, estimated by the servo).
        errors: (n,) servo error bytes (protocol 1.0 bits; 0 = healthy).
        torque_on: (n,) whether each servo's torque is enabled.
        alarms: (n,) the backend's names for each servo's set error bits
            ("overheating, overload"; "ok" = healthy), or () when it names none.
        gripper: what the gripper's servo reports, on an arm with one (:class:`Gripping`).
    """

    t: float
    position: np.ndarray
    velocity: np.ndarray
    load: np.ndarray
    errors: tuple[int, ...]
    torque_on: tuple[bool, ...]
    alarms: tuple[str, ...] = ()
    gripper: GripperState | None = None


class BackendError(RuntimeError):
    """A backend cannot go on (link lost, servo fault). The message says what to do."""


@runtime_checkable
class Backend(Protocol):
    """Servos seen from the controller.

    ``lower``/``upper`` are the joint limits the backend will enforce: a goal
    outside them is clamped before anything moves or leaves the process.
    """

    @property
    def n(self) -> int:
        """Number of joints."""
        ...

    @property
    def lower(self) -> np.ndarray:
        """(n,) rad."""
        ...

    @property
    def upper(self) -> np.ndarray:
        """(n,) rad."""
        ...

    def sync(self, t: float) -> None:
        """Bring the backend's world to time ``t`` s since it was opened.

        A simulator integrates its plant up to ``t``; hardware lives in real
        time and does nothing. The loop calls this once per period, before ``read``.
        """
        ...

    def read(self) -> JointState:
        """Read every joint as the servos report it. Raises BackendError when the link fails."""
        ...

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Send goal positions (n,) rad and moving speeds (n,) rad/s (magnitudes, >= 0).

        Goals are clamped into [lower, upper]; speeds into the servo's range,
        with a tiny speed sent as the smallest non-zero unit (Dynamixel 0 means
        "no speed limit", never what a tiny speed means). Non-finite values
        raise ValueError and nothing is sent.
        """
        ...

    def set_torque(self, on: bool) -> None:
        """Switch every servo's torque on or off."""
        ...

    def estop(self) -> bool:
        """Torque off everywhere now (broadcast on a bus); must not raise.

        Returns:
            True when the torque-off went out (on a bus: written to the wire), False when
            it could not be sent (the link is gone: the servos may still hold torque).
        """
        ...

    def close(self) -> None:
        """Release the backend (torque state is left as it is)."""
        ...


@runtime_checkable
class Reconnectable(Protocol):
    """A backend on a link that can be lost and found again (servos on a serial port)."""

    def reconnect(self) -> list[str]:
        """Open the same device path again, find and configure the servos, torque off.

        Returns:
            The configuration lines (as the first opening logged them).

        Raises:
            BackendError: the device or a servo is still missing (nothing changed).
        """
        ...


@runtime_checkable
class Pushable(Protocol):
    """A backend whose world can be pushed (the simulator). Hardware is pushed by a hand."""

    def push(
        self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float
    ) -> None:
        """Apply ``force`` (3,) N, in the robot's base frame (not the viewer's world), at
        ``point`` (3,) m in link ``link``'s frame for ``duration`` s from now."""
        ...

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """Pull ``point`` on ``link`` towards ``anchor`` (3,) m, base frame, with a
        spring of ``stiffness`` N/m (a hand dragging the arm); None releases it."""
        ...


#: μ a wall's Coulomb friction may be: none to rubber on rubber (the plants' and the
#: options' one range)
FRICTION_RANGE = (0.0, 2.0)


@dataclass(frozen=True)
class WallSetting:
    """A wall as :meth:`Touchable.set_wall` placed it: ``origin`` (3,) m and unit ``normal``
    (3,) towards the free side, base frame; ``stiffness`` N/m, ``damping`` N·s/m;
    ``friction`` μ, its Coulomb friction coefficient (0: a frictionless wall); ``size``
    None (a plane) or a box's (width, height, thickness) m, its face on that plane (a
    table top, a block)."""

    origin: np.ndarray
    normal: np.ndarray
    stiffness: float
    damping: float
    friction: float = 0.0
    size: tuple[float, float, float] | None = None


@runtime_checkable
class Touchable(Protocol):
    """A backend whose world holds a wall the hand can touch (the simulator), and which
    knows the force of that contact (its ground truth: the controller only ever sees the
    servos' loads)."""

    def set_wall(self, origin: np.ndarray | None, normal: np.ndarray | None = None, *,
                 stiffness: float, damping: float, friction: float = 0.0,
                 size: tuple[float, float, float] | None = None) -> None:
        """A plane through ``origin`` (3,) m with unit ``normal`` (3,) towards the free
        side, base frame, pushing back ``stiffness`` N/m of penetration and ``damping``
        N·s/m, with Coulomb ``friction`` μ along it (``size``: a box of (width, height,
        thickness) m with its face there instead); None removes it."""
        ...

    def wall_force(self) -> float:
        """N, the wall's normal force on the hand now."""
        ...

    def wall_setting(self) -> WallSetting | None:
        """The wall in the world now (as :meth:`set_wall` placed it), or None: what the
        control loop records a contact force for (armlab.control.recorder's
        ``f_contact``), and what an arm started again keeps (armlab.control.restart)."""
        ...

    def wall_peak(self) -> float:
        """N, the largest wall force since the last call (an impact between two periods)."""
        ...


@runtime_checkable
class Gripping(Protocol):
    """A backend that drives a gripper's servo beside the arm's joints (read and written in
    the same bus transactions as the joints; its torque off with theirs)."""

    @property
    def gripper_range(self) -> tuple[float, float] | None:
        """(closed, open) of the finger joint in its URDF units (m for a finger that
        slides, rad for a jaw that turns), or None when the arm has no gripper."""
        ...

    @property
    def gripper_revolute(self) -> bool:
        """Whether the finger joint turns (a jaw, rad) rather than slides (m)."""
        ...

    @property
    def gripper_note(self) -> str:
        """How the gripper's servo holds the finger and bounds its grip, in a person's
        words ("" without a gripper)."""
        ...

    def set_gripper(self, position: float) -> float:
        """Hold the finger at ``position`` (m or rad), clamped into :attr:`gripper_range`, from the
        next ``write`` on; returns the clamped goal.

        Raises:
            ValueError: a non-finite position, or an arm without a gripper (nothing sent).
        """
        ...


@runtime_checkable
class CurrentSensing(Protocol):
    """A backend that can say whether its servos measure their motor current (the
    disturbance observer, thesis eq. 2.36, needs K_t I, not a load estimate)."""

    @property
    def senses_current(self) -> bool:
        """True when every servo measures its motor current, so ``JointState.load`` is
        current × torque constant (XM430, XL330); False for a load estimate (RX-24F,
        AX-12A Present Load; XL430)."""
        ...


class GoalLimits:
    """The joint limits a backend enforces and the goal check every ``Backend.write`` runs.

    A backend subclasses it and sets ``_lower``, ``_upper`` ((n,) rad) when it opens;
    it gets the ``lower``/``upper`` properties of :class:`Backend` and :meth:`checked_goal`.
    """

    _lower: np.ndarray
    _upper: np.ndarray

    @property
    def lower(self) -> np.ndarray:
        """(n,) rad."""
        return self._lower.copy()

    @property
    def upper(self) -> np.ndarray:
        """(n,) rad."""
        return self._upper.copy()

    def checked_goal(self, position: object, speed: object) -> tuple[np.ndarray, np.ndarray]:
        """``write``'s arguments as (n,) goal positions clamped into [lower, upper], rad,
        and (n,) speeds, rad/s.

        Raises:
            ValueError: naming ``position`` or ``speed``, for a wrong shape or a NaN/inf
                (the caller then sends nothing).
        """
        n = len(self._lower)
        q = _goal_vector("position", position, n)
        v = _goal_vector("speed", speed, n)
        return clamp(q, self._lower, self._upper), v


def _goal_vector(name: str, value: object, n: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {n} numbers, got {value!r}; nothing was sent") from None
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}; nothing was sent")
    if not all_finite(arr):
        raise ValueError(f"{name}: non-finite values {arr.tolist()}; nothing was sent")
    return arr
