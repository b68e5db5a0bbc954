"""Commands a UI thread posts to the control loop; the loop applies them at its next period.

Every command checks its own fields when built, so a bad value from a person
raises ``ValueError`` in the caller's thread (naming the field) and never
reaches the loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armlab.control.backend import WallSetting
from armlab.control.compliance import MODES, Mode
from armlab.control.trajectory import JointTrajectory
from armlab.kinematics.redundancy import AIMS
from armlab.kinematics.validate import scalar, vector

#: 1/s, the largest null-space gain k_a (seed 002 eq. 2) a person may set
MAX_NULL_SPACE_GAIN = 10.0


@dataclass(frozen=True)
class RunTrajectory:
    """Play ``trajectory`` from the next period.

    Attributes:
        trajectory: the joint trajectory (times from 0).
        approach: first move smoothly (minimum jerk) from the current command to
            the trajectory's first point when they differ.
    """

    trajectory: JointTrajectory
    approach: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.trajectory, JointTrajectory):
            raise ValueError(f"trajectory must be a JointTrajectory, got "
                             f"{type(self.trajectory).__name__}")


@dataclass(frozen=True)
class Stop:
    """Stop the trajectory (or target following) and hold the current command."""


@dataclass(frozen=True)
class Push:
    """Push the (simulated) arm: ``force`` (3,) N in the model's base frame (as the
    simulator's ``push`` takes it; ``model.base_pose`` turns it to the viewer's world), at
    ``point`` (3,) m in link ``link``'s frame, for ``duration`` s."""

    force: np.ndarray
    link: int
    point: np.ndarray
    duration: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "force", vector("force", self.force, 3))
        object.__setattr__(self, "point", vector("point", self.point, 3))
        object.__setattr__(self, "duration", scalar("duration", self.duration, positive=True))
        if not isinstance(self.link, int | np.integer) or self.link < 0:
            raise ValueError(f"link must be a link index >= 0, got {self.link!r}")


@dataclass(frozen=True)
class Spring:
    """Pull ``point`` (3,) m on link ``link`` towards ``anchor`` (3,) m, base frame, with
    ``stiffness`` N/m (a hand dragging the arm); ``anchor`` None releases it."""

    anchor: np.ndarray | None
    stiffness: float
    link: int
    point: np.ndarray

    def __post_init__(self) -> None:
        if self.anchor is not None:
            object.__setattr__(self, "anchor", vector("anchor", self.anchor, 3))
        k = scalar("stiffness (N/m)", self.stiffness, nonnegative=True)
        object.__setattr__(self, "stiffness", k)
        object.__setattr__(self, "point", vector("point", self.point, 3))
        if not isinstance(self.link, int | np.integer) or self.link < 0:
            raise ValueError(f"link must be a link index >= 0, got {self.link!r}")


@dataclass(frozen=True)
class EStop:
    """Emergency stop: torque off everywhere now; the loop stops commanding until Reset."""


@dataclass(frozen=True)
class Reset:
    """Clear a fault or e-stop: torque on, hold where the arm is now."""


@dataclass(frozen=True)
class Reconnect:
    """After a lost link: open the backend's link again now (the loop also tries once a
    second) and configure the servos; torque stays off until Reset."""


@dataclass(frozen=True)
class SetTarget:
    """Follow a (draggable) hand target by RMRC: ``xyz`` (3,) m, base frame; None stops."""

    xyz: np.ndarray | None

    def __post_init__(self) -> None:
        if self.xyz is not None:
            object.__setattr__(self, "xyz", vector("xyz", self.xyz, 3))


@dataclass(frozen=True)
class UseSpareJoints:
    """While the hand follows a target (``SetTarget``), move the joints it does not need
    (n > 3) towards ``aim`` (a key of ``armlab.kinematics.redundancy.AIMS``: "off", "limits",
    "manipulability", "both") by seed 002's gradient projection with gain ``gain`` (k_a
    of eq. 2, 1/s). Turned on while the arm holds, the hand's place becomes the target."""

    aim: str
    gain: float = 1.0

    def __post_init__(self) -> None:
        if self.aim not in AIMS:
            raise ValueError(f"aim must be one of {', '.join(AIMS)}, got {self.aim!r}")
        g = scalar("null-space gain k_a (1/s)", self.gain, nonnegative=True)
        if g > MAX_NULL_SPACE_GAIN:
            raise ValueError(f"null-space gain k_a (1/s) must be at most "
                             f"{MAX_NULL_SPACE_GAIN:g}, got {g:g}")
        object.__setattr__(self, "gain", g)


@dataclass(frozen=True)
class SetController:
    """Switch the controller mode ("none", "pd", "compliance") without a bump."""

    mode: Mode

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")


@dataclass(frozen=True)
class SetVirtualWall:
    """Render a wall with the compliance law from the next period on
    (:mod:`armlab.control.virtual_wall`; None: take it away). What real servos touch in
    place of the simulator's wall; a backend whose world holds a wall of its own keeps
    that one."""

    wall: WallSetting | None


@dataclass(frozen=True)
class SetGripper:
    """Move the gripper's finger to ``position`` in the URDF finger joint's units (m for a
    finger that slides, rad for a jaw that turns); the backend clamps it into the
    gripper's range."""

    position: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", scalar("gripper position (m or rad)", self.position))


Command = (RunTrajectory | Stop | Push | Spring | EStop | Reset | Reconnect | SetTarget
           | UseSpareJoints | SetController | SetGripper | SetVirtualWall)
COMMANDS = (RunTrajectory, Stop, Push, Spring, EStop, Reset, Reconnect, SetTarget,
            UseSpareJoints, SetController, SetGripper, SetVirtualWall)
