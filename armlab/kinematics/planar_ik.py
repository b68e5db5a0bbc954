"""Closed-form IK of the seed 004 planar servo arm (three links 6.5 / 10.5 / 6.5 cm).

The paper's geometric method (eq. 1-24): pick the end-effector orientation
θ0 = atan2(Y, X), step back along it by l3 to the wrist point, solve the two-link
arm for θ1, θ2, and close the chain with θ3 = θ0 − θ1 − θ2. Angles are relative
(θ2 of link 2 against link 1, …), counter-clockwise positive, in the arm's plane.

Servos. The arm has three 0..180° hobby servos. The paper does not say how a joint
angle becomes a servo command; this module uses servo = offset − joint angle (degrees)
with offsets (180, 90, 90), i.e. joint 1 ∈ [0°, 180°], joints 2 and 3 ∈ [−90°, 90°].
This reading is the one that reproduces Table 1: the controller *truncates* the servo
command to whole degrees (int()), which is each joint angle rounded *up*, and rows 1-5
and 20-24 then match the printed (X1, Y1) to 0.01 cm (elbow-down branch). Rows 6-19 need
θ2 < −90°, outside the servo range (tests/test_seed004_table.py).

Units: metres and radians inside (pure Python floats, no numpy, for speed); the
table experiment converts to cm and degrees at the edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Whole-degree rounding modes of the servo command (the paper's controller truncates).
ROUNDINGS = ("none", "round", "truncate")
#: Branches of the two-link solution: "down" has θ2 <= 0 (clockwise elbow bend), "up" θ2 >= 0.
ELBOWS = ("down", "up")


@dataclass(frozen=True)
class PlanarArm:
    """Geometry and servo mounting of the seed 004 arm.

    Attributes:
        l1, l2, l3: link lengths, m (6.5, 10.5, 6.5 cm in the paper).
        servo_offset_deg: servo command = offset − joint angle, degrees, per joint.
        servo_min_deg, servo_max_deg: servo travel (0..180° hobby servos).
    """

    l1: float = 0.065
    l2: float = 0.105
    l3: float = 0.065
    servo_offset_deg: tuple[float, float, float] = (180.0, 90.0, 90.0)
    servo_min_deg: float = 0.0
    servo_max_deg: float = 180.0

    @property
    def reach(self) -> float:
        """l1 + l2 + l3, m (23.5 cm)."""
        return self.l1 + self.l2 + self.l3


@dataclass(frozen=True)
class PlanarIKResult:
    """One closed-form solve.

    Attributes:
        angles: exact joint angles (θ1, θ2, θ3), rad.
        commanded: joint angles after whole-degree rounding of the servo command, rad.
        servo_deg: servo commands of ``commanded``, degrees.
        position: (X, Y) reached by ``commanded`` (forward kinematics), m.
        theta0: end-effector orientation used, rad.
        in_servo_range: all three servo commands within the servo travel.
        reachable: the wrist point is within the two-link workspace (else the nearest
            reachable pose for this θ0 is returned and ``message`` says so).
        message: "" or why the target was not met.
    """

    angles: tuple[float, float, float]
    commanded: tuple[float, float, float]
    servo_deg: tuple[float, float, float]
    position: tuple[float, float]
    theta0: float
    in_servo_range: bool
    reachable: bool
    message: str = ""


def orientation(X: float, Y: float) -> float:
    """End-effector orientation θ0 = atan2(Y, X) (seed 004 eq. 1)."""
    return math.atan2(Y, X)


def wrist_point(X: float, Y: float, theta0: float, l3: float) -> tuple[float, float]:
    """Tip of link 2: (X − l3 cos θ0, Y − l3 sin θ0) (seed 004 eq. 2-3, typo fixed).

    The paper prints x = X cos θ0, y = Y sin θ0; the geometry of its Fig. 2 is the wrist
    point one link l3 back from the target along θ0.
    """
    return X - l3 * math.cos(theta0), Y - l3 * math.sin(theta0)


def elbow_cosine(x: float, y: float, l1: float, l2: float) -> float:
    """cos θ2 = (x² + y² − l1² − l2²) / (2 l1 l2) (seed 004 eq. 6-7)."""
    return (x * x + y * y - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)


def elbow_angle(c2: float, elbow: str = "down") -> float:
    """θ2 = atan2(±sqrt(1 − cos²θ2), cos θ2) (seed 004 eq. 8-9); "down" takes the minus root.

    ``c2`` must be in [−1, 1].
    """
    s2 = math.sqrt(max(0.0, 1.0 - c2 * c2))
    return math.atan2(-s2 if elbow == "down" else s2, c2)


def shoulder_angle(x: float, y: float, theta2: float, l1: float, l2: float) -> float:
    """θ1 = atan2(y, x) − atan2(k2, k1), k1 = l1 + l2 cos θ2, k2 = l2 sin θ2 (eq. 10-23)."""
    k1 = l1 + l2 * math.cos(theta2)
    k2 = l2 * math.sin(theta2)
    return math.atan2(y, x) - math.atan2(k2, k1)


def wrist_angle(theta0: float, theta1: float, theta2: float) -> float:
    """θ3 = θ0 − θ1 − θ2 (seed 004 eq. 24), wrapped to (−π, π]."""
    return _wrap(theta0 - theta1 - theta2)


def fk(angles: tuple[float, float, float] | list[float], arm: PlanarArm = PlanarArm()
       ) -> tuple[float, float, float]:
    """Forward kinematics of the planar arm (seed 004 eq. 4-5 extended by link 3).

    Returns:
        (X, Y, φ): end-effector position (m) and orientation φ = θ1 + θ2 + θ3 (rad).
    """
    t1, t2, t3 = angles
    a1 = t1
    a2 = a1 + t2
    a3 = a2 + t3
    X = arm.l1 * math.cos(a1) + arm.l2 * math.cos(a2) + arm.l3 * math.cos(a3)
    Y = arm.l1 * math.sin(a1) + arm.l2 * math.sin(a2) + arm.l3 * math.sin(a3)
    return X, Y, a3


def servo_angles(angles: tuple[float, float, float] | list[float],
                 arm: PlanarArm = PlanarArm()) -> tuple[float, float, float]:
    """Servo commands in degrees: offset − joint angle (see the module docstring)."""
    o = arm.servo_offset_deg
    return (o[0] - math.degrees(angles[0]), o[1] - math.degrees(angles[1]),
            o[2] - math.degrees(angles[2]))


def joint_angles(servo_deg: tuple[float, float, float] | list[float],
                 arm: PlanarArm = PlanarArm()) -> tuple[float, float, float]:
    """Joint angles (rad) of three servo commands (degrees); inverse of :func:`servo_angles`."""
    o = arm.servo_offset_deg
    return (math.radians(o[0] - servo_deg[0]), math.radians(o[1] - servo_deg[1]),
            math.radians(o[2] - servo_deg[2]))


def round_command(servo_deg: float, rounding: str) -> float:
    """Whole-degree servo command: "none" keeps it, "round" to nearest (halves up),
    "truncate" drops the fraction as the paper's software does (int(), toward zero)."""
    if rounding == "truncate":
        return float(math.trunc(servo_deg))
    if rounding == "round":
        return float(math.floor(servo_deg + 0.5))
    if rounding == "none":
        return servo_deg
    raise ValueError(f"rounding must be one of {', '.join(ROUNDINGS)}, got {rounding!r}")


def in_servo_range(angles: tuple[float, float, float] | list[float],
                   arm: PlanarArm = PlanarArm(), *, tol_deg: float = 1e-9) -> bool:
    """True when all three servo commands of the joint angles (rad) are within travel."""
    lo, hi = arm.servo_min_deg - tol_deg, arm.servo_max_deg + tol_deg
    return all(lo <= s <= hi for s in servo_angles(angles, arm))


def solve(X: float, Y: float, *, arm: PlanarArm = PlanarArm(), elbow: str = "down",
          rounding: str = "none", theta0: float | None = None) -> PlanarIKResult:
    """Closed-form IK of the seed 004 arm for target (X, Y), m (eq. 1-24).

    Args:
        X, Y: target, m, in the arm's base frame.
        elbow: "down" (θ2 <= 0; reproduces Table 1) or "up".
        rounding: whole-degree rounding of the servo command (:data:`ROUNDINGS`);
            "truncate" is the paper's controller.
        theta0: end-effector orientation, rad; default atan2(Y, X) (eq. 1).

    Returns:
        A :class:`PlanarIKResult`. An unreachable wrist point gives the stretched or
        folded arm toward it, ``reachable=False`` and a message, never NaN.

    Raises:
        ValueError: non-finite target or unknown elbow/rounding.
    """
    if not (math.isfinite(X) and math.isfinite(Y)):
        raise ValueError(f"target must be finite, got ({X}, {Y})")
    if elbow not in ELBOWS:
        raise ValueError(f"elbow must be one of {', '.join(ELBOWS)}, got {elbow!r}")
    if theta0 is None:
        theta0 = orientation(X, Y)
    elif not math.isfinite(theta0):
        raise ValueError(f"theta0 must be finite, got {theta0}")
    l1, l2 = arm.l1, arm.l2
    x, y = wrist_point(X, Y, theta0, arm.l3)
    c2 = elbow_cosine(x, y, l1, l2)
    reachable = -1.0 - 1e-12 <= c2 <= 1.0 + 1e-12  # tolerance for a stretched arm
    message = ""
    if not reachable:
        d = math.hypot(x, y)
        message = (f"target ({X:.4f}, {Y:.4f}) m unreachable with orientation "
                   f"{math.degrees(theta0):.1f} deg: wrist point at {d:.4f} m, the two-link "
                   f"arm reaches {abs(l1 - l2):.4f}..{l1 + l2:.4f} m; returning the nearest pose")
    t2 = elbow_angle(1.0 if c2 > 1.0 else (-1.0 if c2 < -1.0 else c2), elbow)
    t1 = _wrap(shoulder_angle(x, y, t2, l1, l2))
    angles = (t1, t2, wrist_angle(theta0, t1, t2))
    s1, s2, s3 = servo_angles(angles, arm)
    servo = (round_command(s1, rounding), round_command(s2, rounding),
             round_command(s3, rounding))
    cmd = joint_angles(servo, arm)
    X1, Y1, _ = fk(cmd, arm)
    lo, hi = arm.servo_min_deg - 1e-9, arm.servo_max_deg + 1e-9
    in_range = lo <= servo[0] <= hi and lo <= servo[1] <= hi and lo <= servo[2] <= hi
    return PlanarIKResult(angles, cmd, servo, (X1, Y1), theta0, in_range, reachable, message)


@dataclass(frozen=True)
class Alternative:
    """An in-servo-range solution for a target whose default solution is out of range.

    Attributes:
        result: the solve with the chosen orientation.
        theta0_shift: chosen θ0 minus the default atan2(Y, X), rad.
        error: distance from the commanded pose's end effector to the target, m.
    """

    result: PlanarIKResult
    theta0_shift: float
    error: float


def in_range_alternative(X: float, Y: float, *, arm: PlanarArm = PlanarArm(),
                         elbow: str = "down", rounding: str = "truncate",
                         step_deg: float = 0.1, window_deg: float = 5.0) -> Alternative | None:
    """An end-effector orientation whose solution keeps all servos in 0..180°.

    The paper only says such targets were "recalculated" (seed 004 §III). The arm is
    redundant for a position target (3 joints, 2 coordinates), so the orientation θ0 is
    free. This searches θ0 outward from atan2(Y, X) in steps of ``step_deg`` (both signs,
    both elbow branches) for reachable solutions whose *commanded* (rounded) servo angles
    are all in range; from the first such |shift| it looks ``window_deg`` further and
    returns the one whose commanded pose lands nearest the target, with that error.
    None if no orientation works.
    """
    base = math.atan2(Y, X)
    steps = int(round(180.0 / step_deg))
    extra = int(round(window_deg / step_deg))
    best: Alternative | None = None
    last = steps
    k = 0
    while k <= min(steps, last):
        for sign in ((1,) if k == 0 else (-1, 1)):
            shift = math.radians(sign * k * step_deg)
            for e in ELBOWS:
                r = solve(X, Y, arm=arm, elbow=e, rounding=rounding, theta0=base + shift)
                if not (r.reachable and r.in_servo_range):
                    continue
                err = math.hypot(r.position[0] - X, r.position[1] - Y)
                if best is None:
                    last = k + extra
                if best is None or err < best.error - 1e-12 or (
                        abs(err - best.error) <= 1e-12 and e == elbow):
                    best = Alternative(r, shift, err)
        k += 1
    return best


def _wrap(a: float) -> float:
    """Angle wrapped to (−π, π]."""
    a = math.fmod(a + math.pi, 2.0 * math.pi)
    if a <= 0.0:
        a += 2.0 * math.pi
    return a - math.pi
