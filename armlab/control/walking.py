"""The seed 003 quadruped walking in time: a gait cycle planned once, played at any phase.

:func:`plan_gait` samples one cycle of the trot (seed 003 Table 1.1, diagonals in
phase) or of the statically stable crawl (``armlab.kinematics.gait.crawl``), with the leg
IK (eq. 3.1-3.9), the body carried across the floor by its stance feet
(``armlab.kinematics.gait.walk``), the centre of mass and the static stability margin of
every sample. :class:`Walker` plays such a plan continuously: the phase advances
by ``cycles/s × dt``, samples are interpolated, and each new cycle starts where the
last one left the body, so the robot walks on for as long as it is told. A new
plan (other sliders, another direction) is taken at the next cycle boundary, so
the body never jumps.

:func:`angle_error_pct` is the paper's eq. 4.1 (commanded vs servo angle).

Frames: world x, y on the floor (z = 0), z up; body pose (x, y, z, yaw); legs in
``armlab.kinematics.quadruped.LEGS`` order (RF, LF, RH, LH), joints per leg (θ1, θ2, θ3).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import cast

import numpy as np

from armlab.kinematics.body_statics import implied_tilts_deg
from armlab.kinematics.gait import (
    CRAWL_SEQUENCE,
    GaitCycle,
    SineParams,
    crawl,
    cycle_angles,
    cycle_margins,
    trot,
    walk,
)
from armlab.kinematics.model import Quadruped
from armlab.kinematics.quadruped import LEGS, QuadrupedGeometry, leg_to_body
from armlab.kinematics.stability import centre_of_mass, stability_margin, support_polygon
from armlab.kinematics.validate import scalar

GAITS = ("trot", "crawl")
#: Crawl walking backwards: the forward sequence (hind leg before the front leg of the
#: same side) with front and hind swapped.
CRAWL_BACK_SEQUENCE = ("LF", "LH", "RF", "RH")
#: Walking commands of the direction buttons.
COMMANDS = ("forward", "back", "left", "right")
#: A foot closer to the floor than this touches it, m.
TOUCH_M = 1e-9
#: The AX-12A's centre (raw 512) as a horn angle from raw 0, degrees: the "set point"
#: added to each IK angle before it is sent (seed 003 §4.1).
SERVO_CENTRE_DEG = 150.0


def trot_directions(command: str) -> dict[str, int]:
    """Direction index per leg for a command (seed 003 §3.3.1).

    The seed: direction 1 on both right legs turns right. Turning left sets it on
    both left legs; walking back sets it on all four (every step reversed).
    """
    if command == "forward":
        ones: tuple[str, ...] = ()
    elif command == "back":
        ones = LEGS
    elif command == "right":
        ones = ("RF", "RH")
    elif command == "left":
        ones = ("LF", "LH")
    else:
        raise ValueError(f"command must be one of {', '.join(COMMANDS)}, got {command!r}")
    return {leg: int(leg in ones) for leg in LEGS}


@dataclass(frozen=True)
class GaitSpec:
    """What to walk.

    Attributes:
        gait: "trot" (seed 003) or "crawl" (one leg at a time, statically stable).
        params: the sine-pattern inputs A, B, C, D (m) and α (degrees).
        command: "forward", "back", "left" or "right".
        samples: samples per cycle.
    """

    gait: str = "trot"
    params: SineParams = SineParams()
    command: str = "forward"
    samples: int = 120

    def __post_init__(self) -> None:
        if self.gait not in GAITS:
            raise ValueError(f"gait must be one of {', '.join(GAITS)}, got {self.gait!r}")
        if self.command not in COMMANDS:
            raise ValueError(f"command must be one of {', '.join(COMMANDS)}, "
                             f"got {self.command!r}")
        if self.gait == "crawl" and self.command in ("left", "right"):
            raise ValueError("turning: the crawl walks straight along its heading α; turn "
                             "with the trot (the seed's direction index) or change α")
        if self.samples < 8 or self.samples % 4:
            raise ValueError(f"samples must be a multiple of 4, at least 8, got {self.samples}")


@dataclass(frozen=True)
class GaitPlan:
    """One sampled cycle, ready to play.

    Attributes:
        spec, geom: what was planned, on which robot.
        cycle: the gait cycle (feet in the leg frames, stance flags).
        angles: (T, 4, 3) joint angles by the leg IK, rad.
        reachable: False if the IK had to clip a foot.
        body: (T + 1, 4) body pose x, y, z (m), yaw (rad) in the plan's frame; row T is
            the start of the next cycle.
        feet_world: (T + 1, 4, 3) feet in the plan's frame (floor z = 0), m.
        feet_body: (T, 4, 3) feet in the body frame, m.
        com_body: (T, 3) centre of mass in the body frame, m.
        margins: (T,) static stability margin, m (negative: outside the support polygon).
        slip: largest distance a stance foot had to slide, m (0 for a consistent gait).
    """

    spec: GaitSpec
    geom: QuadrupedGeometry
    cycle: GaitCycle
    angles: np.ndarray
    reachable: bool
    body: np.ndarray
    feet_world: np.ndarray
    feet_body: np.ndarray
    com_body: np.ndarray
    margins: np.ndarray
    slip: float

    @property
    def samples(self) -> int:
        return len(self.cycle.omega_deg)

    @property
    def touching(self) -> np.ndarray:
        """(T + 1, 4) True where a foot is on the floor (standing, or just lifting)."""
        return self.feet_world[:, :, 2] < TOUCH_M

    @property
    def rest_u(self) -> float:
        """Cycle fraction of the first sample with all four feet on the floor (the trot:
        ω = 90°, where one diagonal lands as the other lifts; the crawl: ω = 0)."""
        rest = np.flatnonzero(self.touching[:-1].all(axis=1))
        return float(rest[0]) / self.samples if len(rest) else 0.0

    @property
    def advance(self) -> np.ndarray:
        """(3,) body motion over one cycle: x, y (m), yaw (rad), in the plan's frame."""
        return np.array([self.body[-1, 0], self.body[-1, 1], self.body[-1, 3]])


def plan_gait(spec: GaitSpec | None = None, geom: QuadrupedGeometry | None = None
              ) -> GaitPlan:
    """Sample one cycle of ``spec`` and walk it (seed 003 Table 1.1, eq. 3.1-3.9).

    The plans of the last :data:`PLANS_KEPT` (spec, geometry) pairs are kept: a class
    pressing Forward together, or a student going back to a gait, plans it once (a plan
    takes tens of ms). A plan is shared, so its arrays are read-only.

    Raises:
        ValueError: for bad parameters, or when a foot of the cycle is out of the leg's
            reach (the message names the parameters to change).
    """
    return _plan(spec or GaitSpec(), geom or QuadrupedGeometry())


#: plans :func:`plan_gait` keeps
PLANS_KEPT = 64


@functools.lru_cache(maxsize=PLANS_KEPT)
def _plan(spec: GaitSpec, geom: QuadrupedGeometry) -> GaitPlan:
    p = spec.params
    if spec.gait == "trot":
        cycle = trot(p, samples=spec.samples, directions=trot_directions(spec.command))
    else:
        sequence = CRAWL_SEQUENCE
        if spec.command == "back":  # heading reversed: the hind legs lead
            p = replace(p, alpha_deg=p.alpha_deg + 180.0)
            sequence = CRAWL_BACK_SEQUENCE
        cycle = crawl(p, geom, samples=spec.samples, sequence=sequence)
    angles, reachable = cycle_angles(cycle, geom)
    if not reachable:
        raise ValueError(
            f"a foot is out of the leg's reach (femur {geom.leg.femur * 100:g} cm + tibia "
            f"{geom.leg.tibia * 100:g} cm): lower A, B, C or D")
    T = len(cycle.omega_deg)
    two = walk(cycle, geom, cycles=2)  # its first cycle is walk(cycle, geom) itself
    feet_body = np.array([[leg_to_body(cycle.feet[j, i], leg, geom)
                           for i, leg in enumerate(LEGS)] for j in range(T)])
    com = np.array([centre_of_mass({leg: angles[j, i] for i, leg in enumerate(LEGS)}, geom)
                    for j in range(T)])
    margins = cycle_margins(cycle, two, angles, geom)
    plan = GaitPlan(spec, geom, cycle, angles, True, two.body[:T + 1].copy(),
                    two.feet_world[:T + 1].copy(), feet_body, com, margins,
                    float(np.max(two.slip)))
    for held in (plan, cycle):
        for value in vars(held).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
    return plan


def _se2(pose: np.ndarray) -> np.ndarray:
    """(x, y, yaw) -> 3x3 homogeneous transform."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([[c, -s, pose[0]], [s, c, pose[1]], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class WalkState:
    """The robot at one instant.

    Attributes:
        phase: cycles played since the start (the fractional part is ω / 360°).
        omega_deg: phase ω within the cycle, degrees.
        angles: (4, 3) joint angles, rad (legs in LEGS order).
        body: (4,) body pose in the world: x, y, z (m), yaw (rad).
        feet: (4, 3) feet in the world, m.
        stance: (4,) True for the feet on the floor (bearing weight).
        com: (3,) centre of mass in the world, m.
        margin: static stability margin, m.
        support: (k, 2) support polygon (hull of the stance feet), world, m.
    """

    phase: float
    omega_deg: float
    angles: np.ndarray
    body: np.ndarray
    feet: np.ndarray
    stance: np.ndarray
    com: np.ndarray
    margin: float
    support: np.ndarray

    @property
    def q(self) -> np.ndarray:
        """(12,) joint angles in the servo order (RF, LF, RH, LH; θ1, θ2, θ3 each), rad."""
        return self.angles.reshape(12).copy()


class Walker:
    """Plays a :class:`GaitPlan` in time, cycle after cycle.

    Args:
        plan: the gait to walk.
        in_place: keep the body at the origin (the feet slide under it, as on a
            treadmill) instead of carrying it across the floor.

    One thread owns a walker (the gait loop); nothing here locks.
    """

    def __init__(self, plan: GaitPlan, *, in_place: bool = False) -> None:
        self.plan = plan
        self.in_place = in_place
        self._pending: GaitPlan | None = None
        self._cycle_start = np.eye(3)  # world <- plan frame of the current cycle
        self._cycles = 0  # whole cycles played
        self._u = plan.rest_u  # phase within the cycle, [0, 1): start standing on 4 feet

    @property
    def phase(self) -> float:
        return self._cycles + self._u

    @property
    def pending(self) -> GaitPlan | None:
        """A plan waiting for the next cycle boundary."""
        return self._pending

    def set_plan(self, plan: GaitPlan, *, now: bool = False) -> None:
        """Walk ``plan`` from the next cycle boundary (``now``: at once, for a standing
        robot: it stands at ``plan``'s rest pose, the body keeping its place and heading)."""
        if not now:
            self._pending = plan
            return
        body = self.state().body
        here = _se2(np.array([body[0], body[1], body[3]]))
        u = plan.rest_u
        j = min(int(round(u * plan.samples)), plan.samples - 1)
        b = plan.body[j]
        if not self.in_place:
            self._cycle_start = here @ np.linalg.inv(_se2(np.array([b[0], b[1], b[3]])))
        self.plan, self._pending, self._u = plan, None, u

    def reset(self) -> None:
        """Back to the origin at phase 0 (a pending plan is taken now)."""
        if self._pending is not None:
            self.plan, self._pending = self._pending, None
        self._cycle_start = np.eye(3)
        self._cycles = 0
        self._u = self.plan.rest_u

    def advance(self, cycles: float) -> None:
        """Move the phase on by ``cycles`` (>= 0), crossing cycle boundaries as needed."""
        u = self._u + scalar("cycles", cycles, nonnegative=True)
        while u >= 1.0:
            u -= 1.0
            self._cycles += 1
            if not self.in_place:
                self._cycle_start = self._cycle_start @ _se2(self.plan.advance)
            if self._pending is not None:
                self.plan, self._pending = self._pending, None
        self._u = u

    def next_rest(self) -> float:
        """Cycles from now to the next sample at which all four feet are on the floor."""
        T = self.plan.samples
        s = self._u * T
        down = cast(np.ndarray, self.plan.touching[:-1].all(axis=1))  # (T,) bools
        for k in range(T + 1):
            j = math.ceil(s - 1e-9) + k
            if down[j % T]:
                return max(0.0, (j - s) / T)
        return 0.0

    def state(self) -> WalkState:
        """The robot at the current phase (samples interpolated linearly)."""
        plan = self.plan
        T = plan.samples
        s = self._u * T
        j = min(int(s), T - 1)
        f = s - j
        j1 = (j + 1) % T
        angles = (1 - f) * plan.angles[j] + f * plan.angles[j1]
        com_b = (1 - f) * plan.com_body[j] + f * plan.com_body[j1]
        if self.in_place:
            feet_b = (1 - f) * plan.feet_body[j] + f * plan.feet_body[j1]
            z = (1 - f) * plan.body[j, 2] + f * plan.body[j + 1, 2]
            body = np.array([0.0, 0.0, z, 0.0])
            feet = feet_b + np.array([0.0, 0.0, z])
        else:
            b = (1 - f) * plan.body[j] + f * plan.body[j + 1]
            # Feet in the plan frame: stance feet are pinned, so interpolating keeps them put.
            feet_p = (1 - f) * plan.feet_world[j] + f * plan.feet_world[j + 1]
            W = self._cycle_start
            yaw0 = math.atan2(W[1, 0], W[0, 0])
            xy = W[:2, :2] @ b[:2] + W[:2, 2]
            body = np.array([xy[0], xy[1], b[2], b[3] + yaw0])
            feet = np.column_stack([feet_p[:, :2] @ W[:2, :2].T + W[:2, 2], feet_p[:, 2]])
        stance = feet[:, 2] < TOUCH_M
        c, s_ = math.cos(body[3]), math.sin(body[3])
        R = np.array([[c, -s_], [s_, c]])
        com = np.array([*(R @ com_b[:2] + body[:2]), com_b[2] + body[2]])
        support = support_polygon(feet[stance, :2])
        margin = stability_margin(com[:2], feet[stance, :2], hull=support)
        return WalkState(self.phase, 360.0 * self._u, angles, body, feet, stance, com,
                         margin, support)


# ---------------------------------------------------------------------------
# Seed 003 §4.1: commanded vs servo angle


def servo_angle_deg(horn_rad: np.ndarray) -> np.ndarray:
    """Horn angle from the servo's raw 0, degrees: the IK angle plus the set point.

    Seed 003 §4.1 compares "the final angle of the IK calculation with the set point of
    each servo added" with the servo's feedback. For an AX-12A the set point is its
    centre, 150° (raw 512); ``horn_rad`` is the angle from that centre, rad.
    """
    return SERVO_CENTRE_DEG + np.degrees(np.asarray(horn_rad, dtype=float))


def angle_error_pct(commanded_deg: np.ndarray, actual_deg: np.ndarray) -> np.ndarray:
    """%Error = (servo angle − computed angle) / computed angle × 100 (seed 003 eq. 4.1).

    Args:
        commanded_deg: angles computed by the program (IK + set point), degrees, any shape.
        actual_deg: the angles the servos report for them, degrees, same shape.

    Returns:
        The signed percentage per element (the paper averages it: 1.201 %).
    """
    c = np.asarray(commanded_deg, dtype=float)
    a = np.asarray(actual_deg, dtype=float)
    if c.shape != a.shape:
        raise ValueError(f"commanded_deg and actual_deg differ in shape: {c.shape}, {a.shape}")
    if np.any(c == 0.0):
        raise ValueError("commanded_deg: eq. 4.1 divides by the computed angle; 0 is not "
                         "allowed (measure angles from the servo's raw 0, not its centre)")
    return (a - c) / c * 100.0


def mean_angle_error_pct(commanded_deg: np.ndarray, actual_deg: np.ndarray) -> float:
    """Mean of |eq. 4.1| over every servo and sample, % (what the paper reports as 1.201 %).

    The magnitude is averaged so that errors of opposite sign do not cancel.
    """
    e = angle_error_pct(commanded_deg, actual_deg)
    return float(np.mean(np.abs(e))) if e.size else math.nan


def walking_tilts_deg(model: Quadruped, snap: dict[str, np.ndarray]) -> np.ndarray:
    """(M,) body tilt (degrees) the reported angles imply, over a gait-loop snapshot's walking
    samples with finite readings (:func:`armlab.kinematics.body_statics.implied_tilts_deg`)."""
    ok = (snap["walking"] > 0.5) & np.all(np.isfinite(snap["q"]), axis=1)
    return implied_tilts_deg(model, snap["q"][ok])
