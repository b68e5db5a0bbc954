"""Seed-robot hot paths: the closed-form IK of the seed 004 planar servo arm.

Figures (median microseconds per call):
    planar_ik_us: one closed-form solve (seed 004 eq. 1-24) with the paper's truncated
        whole-degree servo command and its forward kinematics; the call cycles through
        the 24 targets of Table 1 (target <= 20 us).
"""

from __future__ import annotations

import itertools

from armlab.app.benches import median_us
from armlab.control.experiments.seed004_data import TABLE1
from armlab.kinematics.planar_ik import solve


def run(quick: bool) -> dict[str, float]:
    """Median µs of one seed 004 closed-form solve."""
    targets = itertools.cycle([(r[1] / 100.0, r[2] / 100.0) for r in TABLE1])

    def one() -> object:
        X, Y = next(targets)
        return solve(X, Y, rounding="truncate")

    return {"planar_ik_us": median_us(one, repeat=500 if quick else 5000)}
