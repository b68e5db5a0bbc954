"""Gaits of the seed 003 quadruped: the sine pattern (Table 1.1), trot, a crawl, walking.

Foot positions are in each leg's seed frame (x forward, y outward, z up, origin at the
hip; see armlab/kinematics/quadruped.py). A cycle is one turn of the phase ω ∈ [0°, 360°).

Table 1.1 as extracted has two typos (docs/seed003-quadruped.md): it prints the same y for
both phase indices and the same x and y for both direction indices. Here the step's sign
flips with the phase index in x *and* y (so that both phases swing the same way), and
direction index 1 reverses the step (the seed: direction 1 on both right legs turns right).

Heading α: the step runs along (sin α, cos α) in the leg frame, i.e. α is measured from the
outward axis y towards forward x. α = 90° walks straight ahead, the default. Because the
right legs' frame is mirrored, α ≠ 90° makes the two sides step in mirrored directions (as
the seed's single formula does); the stance feet then slip (see :func:`walk`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armlab.kinematics.leg_ik import leg_ik
from armlab.kinematics.quadruped import (
    DEFAULT_GEOMETRY,
    LEGS,
    SIDE,
    QuadrupedGeometry,
    body_to_leg,
    hip_position,
    leg_to_body,
)
from armlab.kinematics.stability import centre_of_mass, stability_margin
from armlab.kinematics.validate import scalar

#: Trot (seed 003 §2.4, §3.3.1): diagonal legs share a phase index.
TROT_PHASE = {"RF": 0, "LH": 0, "LF": 1, "RH": 1}
#: Crawl: one leg at a time, hind leg before the front leg of the same side.
CRAWL_SEQUENCE = ("LH", "LF", "RH", "RF")


@dataclass(frozen=True)
class SineParams:
    """Inputs of the sine pattern (seed 003 §3.3.1), m and degrees.

    Attributes:
        A: step length (the foot moves ±A/2 about its mid-stance point).
        B: outward offset of the foot from the hip (the seed's B).
        C: step height, how far the swinging foot rises.
        D: body height, depth of the stance foot below the hip.
        alpha_deg: heading α, degrees (90 = straight ahead, see the module docstring).
    """

    A: float = 0.04
    B: float = 0.10
    C: float = 0.03
    D: float = 0.09
    alpha_deg: float = 90.0

    def __post_init__(self) -> None:
        for name in ("A", "C"):
            scalar(name, getattr(self, name), nonnegative=True)
        scalar("B", self.B)
        scalar("D (body height)", self.D, positive=True)
        scalar("alpha_deg", self.alpha_deg)

    def named(self) -> dict[str, float]:
        """The inputs under names that carry their units: ``A_m`` … ``D_m``, ``alpha_deg``
        (a run file's parameters, an experiment's table)."""
        return {"A_m": self.A, "B_m": self.B, "C_m": self.C, "D_m": self.D,
                "alpha_deg": self.alpha_deg}


def in_swing(omega_deg: float, phase: int) -> bool:
    """True while a leg of this phase index swings (seed 003 Table 1.1, z column).

    Phase 0 swings for 90° <= ω < 270°, phase 1 for the other half.
    """
    w = omega_deg % 360.0
    mid = 90.0 <= w < 270.0
    return mid if phase == 0 else not mid


def sine_pattern(omega_deg: float, p: SineParams, *, phase: int, direction: int = 0
                 ) -> tuple[float, float, float]:
    """Foot position (x, y, z), m, in the leg frame at phase ω (seed 003 Table 1.1).

    x = ∓½ A cos(90° − α) sin ω, y = ∓½ A sin(90° − α) sin ω + B (upper sign phase 0,
    reversed by direction 1); z = −D in stance, C sin(ω − 90°) − D (phase 0) or
    −C sin(ω − 90°) − D (phase 1) in swing.
    """
    if phase not in (0, 1):
        raise ValueError(f"phase index must be 0 or 1, got {phase}")
    if direction not in (0, 1):
        raise ValueError(f"direction index must be 0 or 1, got {direction}")
    w = math.radians(omega_deg % 360.0)
    a = math.radians(p.alpha_deg)
    sign = -1.0 if phase == 0 else 1.0
    if direction == 1:
        sign = -sign
    x = sign * 0.5 * p.A * math.cos(math.pi / 2 - a) * math.sin(w)
    y = sign * 0.5 * p.A * math.sin(math.pi / 2 - a) * math.sin(w) + p.B
    lift = math.sin(w - math.pi / 2)
    if not in_swing(omega_deg, phase):
        z = -p.D
    elif phase == 0:
        z = p.C * lift - p.D
    else:
        z = -p.C * lift - p.D
    return x, y, z


@dataclass(frozen=True)
class GaitCycle:
    """One sampled cycle of a gait.

    Attributes:
        name: "trot" or "crawl".
        params: the sine-pattern inputs.
        omega_deg: (T,) phase of each sample, degrees, in [0, 360).
        feet: (T, 4, 3) foot positions in each leg's seed frame, legs in :data:`LEGS` order.
        stance: (T, 4) True where the foot bears weight.
    """

    name: str
    params: SineParams
    omega_deg: np.ndarray
    feet: np.ndarray
    stance: np.ndarray


def _phases(samples: int) -> np.ndarray:
    if samples < 4:
        raise ValueError(f"samples must be >= 4, got {samples}")
    return np.arange(samples) * (360.0 / samples)


def trot(p: SineParams = SineParams(), *, samples: int = 72,
         directions: dict[str, int] | None = None) -> GaitCycle:
    """One cycle of the seed's trot: sine pattern on every leg, diagonals in phase.

    Args:
        directions: direction index per leg (default 0; 1 on RF and RH turns right).
    """
    dirs = {leg: 0 for leg in LEGS} | (directions or {})
    omega = _phases(samples)
    feet = np.array([[sine_pattern(w, p, phase=TROT_PHASE[leg], direction=dirs[leg])
                      for leg in LEGS] for w in omega])
    stance = np.array([[not in_swing(w, TROT_PHASE[leg]) for leg in LEGS] for w in omega])
    return GaitCycle("trot", p, omega, feet, stance)


def _lateral_offset(point: np.ndarray, normal: np.ndarray, feet_xy: np.ndarray,
                    target: float, span: float) -> float:
    """Smallest |t| for which point + t·normal has stability margin >= target.

    The margin along a line is concave, so: find its maximum t* by ternary search in
    [−span, span]; if the target cannot be met, return t*; else bisect between 0 and t*.
    """
    def margin(t: float) -> float:
        return stability_margin(point + t * normal, feet_xy)

    if margin(0.0) >= target:
        return 0.0
    lo, hi = -span, span
    for _ in range(80):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        if margin(m1) < margin(m2):
            lo = m1
        else:
            hi = m2
    best = 0.5 * (lo + hi)
    if margin(best) <= target:
        return best
    lo, hi = 0.0, best
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if margin(mid) >= target:
            hi = mid
        else:
            lo = mid
    return hi


def crawl(p: SineParams = SineParams(), geom: QuadrupedGeometry = DEFAULT_GEOMETRY, *,
          samples: int = 72, sequence: tuple[str, ...] = CRAWL_SEQUENCE,
          shift_fraction: float = 0.3, margin: float = 0.02) -> GaitCycle:
    """One cycle of a statically stable crawl: one leg swings at a time.

    The cycle has four slots of 90°, one per leg of ``sequence``. In the first
    ``shift_fraction`` of a slot all four feet stand and the body shifts: A/4 along the
    heading (sin α, cos α) in the body frame and sideways, as little as needed to bring
    its centre ``margin`` metres inside the support triangle of the three feet that will
    stay down (or as deep as that line allows). Then the leg swings with the sine
    pattern's swing profile (x −A/2 → +A/2, z = C sin, Table 1.1 phase 0) while the body
    stands still. Each foot thus moves A per cycle, as does the body.
    """
    if sorted(sequence) != sorted(LEGS):
        raise ValueError(f"sequence must order the four legs {LEGS}, got {sequence}")
    if not 0.0 < shift_fraction < 1.0:
        raise ValueError(f"shift_fraction must be in (0, 1), got {shift_fraction}")
    a = math.radians(p.alpha_deg)
    d = np.array([math.sin(a), math.cos(a)])  # heading in the body frame
    n = np.array([-d[1], d[0]])
    # Footholds on the floor at the start of the cycle (body centre at the origin).
    start = {}
    for k, leg in enumerate(sequence):
        nominal = hip_position(leg, geom)[:2] + np.array([0.0, SIDE[leg] * p.B])
        start[leg] = nominal + (k - 1) * p.A / 4 * d

    def feet_at_slot(k: int) -> dict[str, np.ndarray]:
        return {leg: start[leg] + (p.A * d if sequence.index(leg) < k else 0.0)
                for leg in LEGS}

    # Body targets: progress along the heading, sideways to the support triangle.
    lateral = []
    for k, leg in enumerate(sequence):
        feet = feet_at_slot(k)
        support = np.array([feet[o] for o in LEGS if o != leg])
        base = (k + 1) * p.A / 4 * d
        lateral.append(_lateral_offset(base, n, support, margin, geom.hip_y + p.B))
    targets = [(k + 1) * p.A / 4 * d + lateral[k] * n for k in range(4)]
    before = [lateral[3] * n] + targets[:3]  # body at the start of each slot

    omega = _phases(samples)
    feet_out = np.empty((samples, 4, 3))
    stance = np.ones((samples, 4), dtype=bool)
    for j, w in enumerate(omega):
        k = min(int(w // 90.0), 3)
        u = (w - 90.0 * k) / 90.0
        world = {leg: np.array([*xy, 0.0]) for leg, xy in feet_at_slot(k).items()}
        if u < shift_fraction:
            b = 0.5 * (1.0 - math.cos(math.pi * u / shift_fraction))
            body = before[k] + b * (targets[k] - before[k])
        else:
            body = targets[k]
            tau = (u - shift_fraction) / (1.0 - shift_fraction)
            leg = sequence[k]
            world[leg][:2] += p.A * d * 0.5 * (1.0 - math.cos(math.pi * tau))
            world[leg][2] = p.C * math.sin(math.pi * tau)
            stance[j, LEGS.index(leg)] = False
        for i, leg in enumerate(LEGS):
            in_body = world[leg] - np.array([body[0], body[1], p.D])
            feet_out[j, i] = body_to_leg(in_body, leg, geom)
    return GaitCycle("crawl", p, omega, feet_out, stance)


@dataclass(frozen=True)
class Walk:
    """The robot walking across the floor (world frame: floor z = 0).

    Attributes:
        body: (T, 4) body pose per sample: x, y, z (m), yaw (rad).
        feet_world: (T, 4, 3) feet in the world.
        slip: (T,) largest distance of a stance foot from where it was put down, m.
    """

    body: np.ndarray
    feet_world: np.ndarray
    slip: np.ndarray


def _fit_planar(p: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Yaw and (2,) translation of the rigid motion taking points p (k, 2) onto w (k, 2)."""
    pc, wc = p.mean(axis=0), w.mean(axis=0)
    P, W = p - pc, w - wc
    yaw = math.atan2(float(np.sum(P[:, 0] * W[:, 1] - P[:, 1] * W[:, 0])),
                     float(np.sum(P[:, 0] * W[:, 0] + P[:, 1] * W[:, 1])))
    c, s = math.cos(yaw), math.sin(yaw)
    return yaw, wc - np.array([[c, -s], [s, c]]) @ pc


def walk(cycle: GaitCycle, geom: QuadrupedGeometry = DEFAULT_GEOMETRY, *, cycles: int = 1
         ) -> Walk:
    """Move the body across the floor so that the stance feet stay where they were put.

    Each sample's body pose (x, y, yaw) is the rigid motion that best maps the feet
    still standing since the previous sample (body frame) onto where they were put down
    (world); the body height keeps the stance feet on the floor. A foot that lands is
    pinned where it touched. ``slip`` measures how far the stance feet still had to move
    (0 for a consistent gait).
    """
    T = len(cycle.omega_deg)
    feet_b = np.array([[leg_to_body(cycle.feet[j, i], leg, geom) for i, leg in enumerate(LEGS)]
                       for j in range(T)])
    feet_b = np.tile(feet_b, (cycles, 1, 1))
    stance = np.tile(cycle.stance, (cycles, 1))
    N = len(feet_b)
    body = np.zeros((N, 4))
    world = np.zeros((N, 4, 3))
    slip = np.zeros(N)
    anchors: dict[int, np.ndarray] = {}
    yaw, xy = 0.0, np.zeros(2)
    for j in range(N):
        # Feet put down earlier that still touch the floor (a lifting foot touches at
        # its first swing sample: its height has not changed yet).
        held = [i for i in anchors if abs(feet_b[j, i, 2] - feet_b[j - 1, i, 2]) < 1e-12]
        if len(held) >= 2:
            yaw, xy = _fit_planar(feet_b[j, held, :2], np.array([anchors[i][:2] for i in held]))
        elif len(held) == 1:
            i = held[0]
            c, s = math.cos(yaw), math.sin(yaw)
            xy = anchors[i][:2] - np.array([[c, -s], [s, c]]) @ feet_b[j, i, :2]
        down = [i for i in range(4) if stance[j, i]]
        z = -float(np.mean(feet_b[j, down, 2])) if down else (body[j - 1, 2] if j else 0.0)
        body[j] = (xy[0], xy[1], z, yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        world[j] = feet_b[j] @ R.T + np.array([xy[0], xy[1], z])
        slip[j] = max((float(np.linalg.norm(world[j, i] - anchors[i])) for i in held),
                      default=0.0)
        anchors = {i: anchors.get(i, world[j, i].copy()) for i in down}
    return Walk(body, world, slip)


def cycle_angles(cycle: GaitCycle, geom: QuadrupedGeometry = DEFAULT_GEOMETRY, *,
                 knee: int = 1) -> tuple[np.ndarray, bool]:
    """Joint angles of every sample by the leg IK (seed 003 eq. 3.1-3.9).

    Returns:
        ((T, 4, 3) angles in rad, True if every foot was reachable).
    """
    T = len(cycle.omega_deg)
    out = np.empty((T, 4, 3))
    ok = True
    for j in range(T):
        for i in range(4):
            r = leg_ik(cycle.feet[j, i], geom.leg, knee=knee)
            out[j, i] = r.angles
            ok = ok and r.reachable
    return out, ok


def cycle_margins(cycle: GaitCycle, moved: Walk, angles: np.ndarray,
                  geom: QuadrupedGeometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """(T,) static stability margin of every sample, m (armlab.kinematics.stability)."""
    T = len(cycle.omega_deg)
    out = np.empty(T)
    for j in range(T):
        com_b = centre_of_mass({leg: angles[j, i] for i, leg in enumerate(LEGS)}, geom)
        x, y, z, yaw = moved.body[j]
        c, s = math.cos(yaw), math.sin(yaw)
        com = np.array([c * com_b[0] - s * com_b[1] + x, s * com_b[0] + c * com_b[1] + y])
        out[j] = stability_margin(com, moved.feet_world[j, cycle.stance[j], :2])
    return out
