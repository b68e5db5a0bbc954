"""Closed-form IK of one 3-DOF quadruped leg (seed 003 eq. 3.1-3.9, atan2 form).

The leg frame (the seed's x, y, z; origin on the hip-yaw axis at the hip-pitch axis):
x points forward along the body, y outward from the body (the direction the leg
reaches at θ1 = 0), z up. For the right legs this frame is the mirror image of the left
legs' one, as in the seed, which uses one formula for all four legs;
:func:`armlab.kinematics.quadruped.leg_to_body` maps it into the body frame.

Joints: θ1 hip yaw (from the outward axis towards forward), θ2 hip pitch (femur angle
*below* the horizontal), θ3 knee (tibia bend, downward positive). With the seed's
positive root θ3 = atan2(+sqrt(1 − A²), A) the knee is above the line hip→foot: the
usual spider-leg stance of AX-12A quadrupeds. The seed gives no link lengths: the
defaults of :class:`LegGeometry` are plausible ones (femur 7.5 cm, tibia 10 cm).

Pure Python floats, metres and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from armlab.kinematics.validate import scalar


@dataclass(frozen=True)
class LegGeometry:
    """Link lengths of one leg, m: l1 femur (hip pitch → knee), l2 tibia (knee → foot)."""

    femur: float = 0.075
    tibia: float = 0.10

    def __post_init__(self) -> None:
        for name in ("femur", "tibia"):
            scalar(f"{name} length (m)", getattr(self, name), positive=True)


@dataclass(frozen=True)
class LegIKResult:
    """Joint angles (θ1, θ2, θ3) in rad; ``reachable`` False (with a message) when the
    foot was out of reach and the nearest reachable pose was returned instead."""

    angles: tuple[float, float, float]
    reachable: bool
    message: str = ""


def hip_yaw(x: float, y: float) -> float:
    """θ1 = atan2(x, y) (seed 003 eq. 3.4-3.5): yaw from the outward axis y towards x."""
    return math.atan2(x, y)


def knee_cosine(x: float, y: float, z: float, l1: float, l2: float) -> float:
    """A = (x² + y² + z² − l1² − l2²) / (2 l1 l2) = cos θ3 (seed 003 eq. 3.3, 3.8)."""
    return (x * x + y * y + z * z - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)


def knee_angle(A: float, knee: int = 1) -> float:
    """θ3 = atan2(±sqrt(1 − A²), A) (seed 003 eq. 3.9); the seed takes the + root (knee=1).

    ``A`` must be in [−1, 1].
    """
    return math.atan2(knee * math.sqrt(max(0.0, 1.0 - A * A)), A)


def hip_pitch(r: float, h: float, theta3: float, l1: float, l2: float) -> float:
    """θ2 = atan2(C, D) (seed 003 eq. 3.6-3.7), the two-link terms written out.

    With r = sqrt(x² + y²) the horizontal reach, h = −z the depth below the hip,
    k1 = l1 + l2 cos θ3 and k2 = l2 sin θ3: C = h k1 − r k2, D = r k1 + h k2 (eq. 3.2
    as printed is garbled; these are the terms whose ratio it shows).
    """
    k1 = l1 + l2 * math.cos(theta3)
    k2 = l2 * math.sin(theta3)
    return math.atan2(h * k1 - r * k2, r * k1 + h * k2)


def leg_ik(foot: tuple[float, float, float] | list[float], geom: LegGeometry = LegGeometry(),
           *, knee: int = 1) -> LegIKResult:
    """Joint angles that put the foot at ``foot`` = (x, y, z) in the leg frame (eq. 3.1-3.9).

    Args:
        foot: (3,) m, leg frame (x forward, y outward, z up).
        knee: +1 the seed's root (knee above the hip→foot line), −1 the other branch.

    Returns:
        :class:`LegIKResult`; an unreachable foot gives the leg stretched (or folded)
        towards it with ``reachable=False`` and a message, never NaN.
    """
    x, y, z = (float(v) for v in foot)
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise ValueError(f"foot must be finite, got {foot}")
    if knee not in (1, -1):
        raise ValueError(f"knee must be +1 or -1, got {knee}")
    l1, l2 = geom.femur, geom.tibia
    t1 = hip_yaw(x, y)
    A = knee_cosine(x, y, z, l1, l2)
    ok = -1.0 - 1e-12 <= A <= 1.0 + 1e-12  # tolerance for a stretched leg
    msg = ""
    if not ok:
        d = math.sqrt(x * x + y * y + z * z)
        msg = (f"foot ({x:.4f}, {y:.4f}, {z:.4f}) m is {d:.4f} m from the hip; the leg reaches "
               f"{abs(l1 - l2):.4f}..{l1 + l2:.4f} m: returning the nearest pose")
    A = 1.0 if A > 1.0 else (-1.0 if A < -1.0 else A)
    t3 = knee_angle(A, knee)
    t2 = hip_pitch(math.hypot(x, y), -z, t3, l1, l2)
    return LegIKResult((t1, t2, t3), ok, msg)


def leg_fk(angles: tuple[float, float, float] | list[float],
           geom: LegGeometry = LegGeometry()) -> tuple[float, float, float]:
    """Foot position (x, y, z), m, in the leg frame for joint angles (θ1, θ2, θ3), rad.

    The inverse of :func:`leg_ik`: reach ρ = l1 cos θ2 + l2 cos(θ2 + θ3) along the yawed
    outward direction (sin θ1, cos θ1), depth l1 sin θ2 + l2 sin(θ2 + θ3) below the hip.
    """
    t1, t2, t3 = angles
    rho = geom.femur * math.cos(t2) + geom.tibia * math.cos(t2 + t3)
    depth = geom.femur * math.sin(t2) + geom.tibia * math.sin(t2 + t3)
    return rho * math.sin(t1), rho * math.cos(t1), -depth
