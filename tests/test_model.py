"""The receptionist arm model against thesis eq. 3.13 (both link-length presets)."""

import numpy as np
import pytest

from armlab.kinematics import load_robot


def thesis_fk(t1: float, t0: float, t2: float, L1: float, L2: float) -> np.ndarray:
    """Thesis eq. 3.13, transcribed."""
    c0, s0, c1, s1, c2, s2 = np.cos(t0), np.sin(t0), np.cos(t1), np.sin(t1), np.cos(t2), np.sin(t2)
    return np.array([
        L1 * c0 * c1 - L2 * (s1 * s2 - c0 * c1 * c2),
        L2 * (c1 * s2 + c0 * c2 * s1) + L1 * c0 * s1,
        -L1 * s0 - L2 * c2 * s0,
    ])


@pytest.mark.parametrize("preset,lengths", [("18.5/25", (0.185, 0.25)),
                                             ("18.5/18.5", (0.185, 0.185)),
                                             ("17/25", (0.17, 0.25))])
def test_fk_equals_thesis_eq_3_13(preset, lengths):
    model = load_robot("receptionist_arm", preset=preset)
    rng = np.random.default_rng(1)
    for _ in range(50):
        t1, t0, t2 = rng.uniform(-np.pi, np.pi, 3)
        np.testing.assert_allclose(model.fk([t1, t0, t2])[:3, 3], thesis_fk(t1, t0, t2, *lengths),
                                   atol=1e-12)


def test_gravity_along_thesis_plus_x_and_arm_hangs_down():
    model = load_robot("receptionist_arm")
    np.testing.assert_allclose(model.gravity, [9.81, 0, 0], atol=1e-12)
    world_hand = model.base_pose @ model.fk(np.zeros(3))
    shoulder = model.base_pose[:3, 3]
    # At q = 0 the hand is straight below the shoulder in the viewer (z up).
    np.testing.assert_allclose(world_hand[:3, 3] - shoulder, [0, 0, -0.435], atol=1e-12)


def test_unknown_robot_lists_known_ones():
    with pytest.raises(ValueError, match="receptionist_arm"):
        load_robot("no_such_robot")
