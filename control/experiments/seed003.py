"""``armlab experiment seed003-gait``: one cycle of the quadruped's trot or crawl.

Foot positions from the sine pattern of seed 003 Table 1.1 (trot) or a statically
stable crawl, joint angles from the leg IK (eq. 3.1-3.9), the body walked across the
floor so that the stance feet stay put, and the static stability margin of every sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from control.experiments import Experiment, option
from kinematics.gait import SineParams, crawl, cycle_angles, cycle_margins, trot, walk
from kinematics.quadruped import LEGS, QuadrupedGeometry


def gait_cycle(gait: str = "trot", params: SineParams | None = None, *, samples: int = 36,
               right_direction: int = 0) -> dict[str, Any]:
    """One cycle of ``gait`` ("trot" or "crawl"); lengths in m, angles in degrees.

    ``rows`` holds one entry per sample: phase, body pose, stance flags, feet (leg frames
    and world), joint angles and static stability margin.
    """
    params = params or SineParams()
    geom = QuadrupedGeometry()
    if gait == "trot":
        cycle = trot(params, samples=samples,
                     directions={"RF": right_direction, "RH": right_direction})
    elif gait == "crawl":
        cycle = crawl(params, geom, samples=samples)
    else:
        raise ValueError(f"gait must be trot or crawl, got {gait!r}")
    angles, reachable = cycle_angles(cycle, geom)
    warnings = [] if reachable else [
        f"some feet are out of the leg's reach ({geom.leg.femur + geom.leg.tibia:.3f} m from "
        "the hip): their joint angles are the nearest reachable pose"]
    # Two cycles: the first is the cycle itself, the same phase in the second gives the advance.
    moved = walk(cycle, geom, cycles=2)
    margins = cycle_margins(cycle, moved, angles, geom)
    out = []
    for j, w in enumerate(cycle.omega_deg):
        out.append({
            "omega_deg": float(w),
            "body": moved.body[j].tolist(),
            "stance": {leg: bool(cycle.stance[j, i]) for i, leg in enumerate(LEGS)},
            "feet_m": {leg: cycle.feet[j, i].tolist() for i, leg in enumerate(LEGS)},
            "feet_world_m": {leg: moved.feet_world[j, i].tolist() for i, leg in enumerate(LEGS)},
            "angles_deg": {leg: np.degrees(angles[j, i]).tolist() for i, leg in enumerate(LEGS)},
            "margin_m": float(margins[j]) if math.isfinite(margins[j]) else None,
        })
    n = len(cycle.omega_deg)
    return {
        "gait": gait,
        "params": {"A_m": params.A, "B_m": params.B, "C_m": params.C, "D_m": params.D,
                   "alpha_deg": params.alpha_deg},
        "leg_m": {"femur": geom.leg.femur, "tibia": geom.leg.tibia},
        "reachable": reachable,
        "min_margin_m": float(np.min(margins)),
        "max_slip_m": float(np.max(moved.slip)),
        "advance_per_cycle_m": (moved.body[n, :2] - moved.body[0, :2]).tolist(),
        "yaw_per_cycle_rad": float(moved.body[n, 3] - moved.body[0, 3]),
        "warnings": warnings,
        "rows": out,
    }


_D = SineParams()


@dataclass(frozen=True)
class GaitOptions:
    """Options of ``seed003-gait`` (lengths in cm, as the seed gives them)."""

    gait: Literal["trot", "crawl"] = option("trot", "trot (default) or crawl")
    A: float = option(_D.A * 100, "step length, cm")
    B: float = option(_D.B * 100, "outward offset of the foot from the hip, cm")
    C: float = option(_D.C * 100, "step height, cm")
    D: float = option(_D.D * 100, "body height (hip above the floor), cm")
    alpha: float = option(_D.alpha_deg, "heading alpha, degrees (90 = straight ahead)")
    samples: int = option(36, "samples per cycle")
    right_direction: Literal[0, 1] = option(
        0, "direction index of the right legs (trot; 1 turns right)")


def _run(options: GaitOptions) -> dict[str, Any]:
    o = options
    params = SineParams(A=o.A / 100, B=o.B / 100, C=o.C / 100, D=o.D / 100, alpha_deg=o.alpha)
    return gait_cycle(o.gait, params, samples=o.samples, right_direction=o.right_direction)


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for s in result["rows"]:
        for leg in LEGS:
            x, y, z = s["feet_m"][leg]
            t1, t2, t3 = s["angles_deg"][leg]
            rows.append({"omega_deg": s["omega_deg"], "leg": leg, "stance": s["stance"][leg],
                         "x_m": x, "y_m": y, "z_m": z, "th1_deg": t1, "th2_deg": t2,
                         "th3_deg": t3, "body_x_m": s["body"][0], "margin_m": s["margin_m"]})
    return rows


EXPERIMENTS = (
    Experiment(
        name="seed003-gait",
        help="seed 003: one cycle of the quadruped's trot or crawl (feet, joints, margin)",
        options=GaitOptions,
        run=_run,
        rows=_rows,
    ),
)
