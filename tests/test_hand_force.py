"""The force drawn at the hand (thesis eq. 2.23, F = (J_vᵀ)⁺ (−τ_ext)): the normal
equations' 3×3 solve every frame takes is the pseudo-inverse's answer, and a pose near a
singularity is left to the SVD."""

from __future__ import annotations

import numpy as np
import pytest

from armlab.app.lessons.compliance_scene import _solve3, estimated_hand_force
from armlab.kinematics import load_robot
from armlab.kinematics.fk import fk_and_jacobian


def _pinv_force(J: np.ndarray, tau: np.ndarray) -> np.ndarray:
    return np.linalg.pinv(J[:3].T) @ (-tau)


@pytest.mark.parametrize("n", [3, 4, 5, 7])
def test_random_jacobians_give_the_pseudo_inverses_force(n):
    rng = np.random.default_rng(n)
    for _ in range(200):
        J = rng.normal(size=(6, n))
        tau = rng.normal(size=n)
        F = estimated_hand_force(J, tau)
        ref = _pinv_force(J, tau)
        # the normal equations lose digits as the square of J_v's condition number
        bound = 1e-14 * np.linalg.cond(J[:3]) ** 2 + 1e-12
        assert np.linalg.norm(F - ref) <= bound * np.linalg.norm(ref)


def test_the_thesis_arm_gives_the_pseudo_inverses_force_bent_and_stretched():
    model = load_robot("receptionist_arm")
    tau = np.array([0.05, -0.3, 0.12])
    for q in ([0.0, 0.3, 0.3], [0.4, -0.6, 1.1], [0.0, 0.0, 0.0], [0.2, 0.5, 1e-7]):
        _, J = fk_and_jacobian(model, np.array(q))
        F = estimated_hand_force(J, tau)
        assert np.allclose(F, _pinv_force(J, tau), rtol=1e-7, atol=1e-9), q


def test_a_rank_deficient_jacobian_is_left_to_the_svd():
    J = np.zeros((6, 3))
    J[0] = [1.0, 1.0, 1.0]  # the hand moves along x only: rank 1
    tau = np.array([0.3, 0.3, 0.3])
    A = J[:3] @ J[:3].T
    assert _solve3(*A.tolist(), (J[:3] @ -tau).tolist()) is None
    np.testing.assert_array_equal(estimated_hand_force(J, tau), _pinv_force(J, tau))


def test_a_two_joint_arm_and_a_non_finite_torque():
    rng = np.random.default_rng(2)
    J, tau = rng.normal(size=(6, 2)), rng.normal(size=2)
    np.testing.assert_array_equal(estimated_hand_force(J, tau), _pinv_force(J, tau))
    assert estimated_hand_force(J, np.array([np.nan, 0.0])) is None
