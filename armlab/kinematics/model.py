"""Robot models: what a robot *is*, as a serial chain or a quadruped's four (never mutated;
:mod:`armlab.kinematics.urdf_read` reads them from URDF files, :mod:`armlab.kinematics.catalog`
names the shipped ones).

Following Pinocchio, a model is what the robot *is*: joint origins, axes,
limits, link inertias and gravity. Algorithms (``fk``, ``jacobian``, ``ik``,
``dynamics``) are pure functions of (model, arrays) in their own modules; the
methods on :class:`SerialChain` are thin conveniences over them.

Frames: a chain's *base frame* is the link the first movable joint hangs from.
Fixed joints before it are folded into ``base_pose`` (world <- base); fixed
joints between movable ones are folded into the next joint's origin; fixed
joints after the last one form ``tip`` (last link <- end effector). Masses of
links on fixed joints are lumped into the moving link they ride on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from armlab.kinematics import fk as _fk


class URDFError(ValueError):
    """A URDF file that cannot be turned into a model; the message names file and reason."""


@dataclass(frozen=True)
class Joint:
    """One movable joint. ``origin`` (4, 4): previous link frame <- joint frame at q = 0."""

    name: str
    kind: str  # "revolute" | "continuous" | "prismatic"
    origin: np.ndarray
    axis: np.ndarray  # (3,) unit vector in the joint (= child link) frame
    lower: float
    upper: float
    velocity: float
    effort: float
    #: True when the file gave no limits (a continuous joint): ±CONTINUOUS_LIMIT was used.
    limit_default: bool = False


@dataclass(frozen=True)
class Capsule:
    """One collision shape of a link: the segment ``a``–``b`` (3,) m in the link's frame,
    swept by a ball of ``radius`` m (a sphere where ``a`` is ``b``). A URDF's
    ``<collision>`` sphere is one; its cylinder and box are read as one
    (:mod:`armlab.kinematics.urdf_read`)."""

    a: np.ndarray
    b: np.ndarray
    radius: float


@dataclass(frozen=True)
class Link:
    """Inertia of the body moved by one joint, in that joint's child-link frame, and the
    shapes it touches the world with (``collision``: none when the file gives none)."""

    name: str
    mass: float  # kg
    com: np.ndarray  # (3,) m
    inertia: np.ndarray  # (3, 3) kg m^2 about the centre of mass
    collision: tuple[Capsule, ...] = ()


@dataclass(frozen=True)
class SerialChain:
    """A serial chain of ``n`` movable joints; ``links[i]`` is moved by ``joints[i]``.

    Attributes:
        name: robot name.
        joints: the n movable joints, base to tip.
        links: the n moving bodies (with masses of fixed children lumped in).
        base_pose: (4, 4) world <- base frame.
        tip: (4, 4) last link frame <- end-effector frame.
        gravity: (3,) gravity in the base frame, m/s^2.
        urdf_path: file the model came from (for the 3D viewer).
        link_names: URDF link name of each moving body (the viewer's frames).
        package_paths: extra folders where ``package://NAME/...`` meshes are looked
            for (after the URDF's own folder and its parents).
    """

    name: str
    joints: tuple[Joint, ...]
    links: tuple[Link, ...]
    base_pose: np.ndarray
    tip: np.ndarray
    gravity: np.ndarray
    urdf_path: Path | None = None
    link_names: tuple[str, ...] = field(default=())
    package_paths: tuple[Path, ...] = field(default=())

    @property
    def n(self) -> int:
        """Number of movable joints."""
        return len(self.joints)

    def __getstate__(self) -> dict[str, object]:
        """The fields, without what was memoised from them (``_armlab_*``: the generated
        dynamics, the limits' arrays), which the model makes again where it is unpickled
        (the class's worker process)."""
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_armlab_")}

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def lower(self) -> np.ndarray:
        """(n,) lower joint limits (rad or m); a fresh copy (IK reads it every solve)."""
        return self._limits()[0].copy()

    @property
    def upper(self) -> np.ndarray:
        """(n,) upper joint limits (rad or m); a fresh copy."""
        return self._limits()[1].copy()

    def _limits(self) -> tuple[np.ndarray, np.ndarray]:
        cached = self.__dict__.get("_armlab_limits")  # frozen: memoised like reach_bound
        if cached is None:
            cached = (np.array([j.lower for j in self.joints], dtype=float),
                      np.array([j.upper for j in self.joints], dtype=float))
            self.__dict__["_armlab_limits"] = cached
        return cached

    def neutral(self) -> np.ndarray:
        """(n,) zeros clipped into the limits."""
        return np.clip(np.zeros(self.n), self.lower, self.upper)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """(4, 4) end-effector pose in the base frame at joint vector q (n,)."""
        return _fk.fk(self, q)

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, 4, 4) pose of every moving link frame in the base frame."""
        return _fk.link_poses(self, q)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(6, n) geometric Jacobian of the end effector, linear rows first, base frame."""
        return _fk.jacobian(self, q)


@dataclass(frozen=True)
class Quadruped:
    """A body with four 3-joint legs. Each leg's base frame is its hip mount on the body.

    Attributes:
        name: robot name.
        legs: leg chains keyed "RF", "LF", "RH", "LH" (right/left, front/hind).
        body_mass: kg, of the body alone.
        urdf_path: the URDF file.
        body_link: URDF name of the body link.
    """

    name: str
    legs: dict[str, SerialChain]
    body_mass: float
    urdf_path: Path | None = None
    body_link: str = "body"
