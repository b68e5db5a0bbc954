"""Kinematics hot paths: FK, Jacobian and one RMRC solve on the receptionist arm.

Figures (median microseconds per call):
    fk_us: end-effector pose, thesis eq. 3.13 (``SerialChain.fk``).
    jacobian_us: geometric Jacobian, thesis eq. 3.17 (``SerialChain.jacobian``).
    fk_and_jacobian_us: both in one pass (``armlab.kinematics.fk.fk_and_jacobian``, what IK uses).
    rmrc_us: one RMRC solve (thesis eq. 3.16-3.22) to 0.1 mm from the neutral pose
        (arm hanging straight down, q = 0) to a reachable target; the calls cycle
        through 16 fixed targets, the FK of poses drawn inside the middle half of the
        joint ranges, so the median is over a spread of distances and directions.
"""

from __future__ import annotations

import itertools

import numpy as np

from armlab.app.benches import median_us
from armlab.kinematics import SerialChain, load_robot
from armlab.kinematics.fk import fk_and_jacobian
from armlab.kinematics.ik import rmrc


def rmrc_targets(model: SerialChain, count: int = 16) -> np.ndarray:
    """(count, 3) reachable targets (m): FK of poses in the middle half of the joint ranges."""
    mid, half = (model.upper + model.lower) / 2, (model.upper - model.lower) / 4
    poses = np.random.default_rng(7).uniform(mid - half, mid + half, (count, model.n))
    return np.array([model.fk(q)[:3, 3] for q in poses])


def run(quick: bool) -> dict[str, float]:
    """Median µs of FK, Jacobian and one RMRC solve on ``receptionist_arm``."""
    arm = load_robot("receptionist_arm")
    repeat = 200 if quick else 2000
    q = np.array([0.3, -0.2, 0.9])
    q0 = arm.neutral()
    targets = itertools.cycle(rmrc_targets(arm))
    return {
        "fk_us": median_us(lambda: arm.fk(q), repeat=repeat),
        "jacobian_us": median_us(lambda: arm.jacobian(q), repeat=repeat),
        "fk_and_jacobian_us": median_us(lambda: fk_and_jacobian(arm, q), repeat=repeat),
        "rmrc_us": median_us(lambda: rmrc(arm, next(targets), q0), repeat=repeat // 4),
    }
