"""armlab exercise null_space_step: joint rate with a null-space step (seed 002, eq. 4, 6).

Fill in the function below, then check it:   armlab check null_space_step.py
"""

import numpy as np

EXERCISE = "null_space_step"


def joint_rate(J: np.ndarray, xdot: np.ndarray, grad_w: np.ndarray,
               k_a: float) -> np.ndarray:
    """The joint velocity of the gradient projection method (seed 002, eq. 4).

    A redundant arm (more joints n than task rows m) follows the hand velocity ẋ with the
    minimum-norm joint velocity J⁺ẋ (J⁺ the Moore-Penrose pseudo-inverse), and adds a
    self-motion in the null space of J (eq. 6) that climbs the criterion w without moving
    the hand: θ̇ = J⁺ ẋ + (I − J⁺ J) k_a ∇w.

    Args:
        J: (m, n) task Jacobian, m/rad.
        xdot: (m,) hand velocity, m/s.
        grad_w: (n,) gradient of the criterion (the manipulability, eq. 3).
        k_a: the gradient's gain (the paper: 200).

    Returns:
        (n,) joint velocity, rad/s.
    """
    raise NotImplementedError("fill in joint_rate (seed 002, eq. 4)")
