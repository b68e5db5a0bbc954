"""armlab exercise jacobian: the receptionist arm's Jacobian (thesis 000, §3.3, eq. 3.17).

Fill in the function below, then check it:   armlab check jacobian.py
"""

import numpy as np

EXERCISE = "jacobian"


def hand_jacobian(q: np.ndarray, L1: float, L2: float) -> np.ndarray:
    """The Jacobian of the hand's position: J[i, j] = ∂p_i / ∂q_j (thesis §3.3).

    p = (x, y, z) is the hand position of eq. 3.13 (exercise thesis_fk); differentiate
    each of x, y, z by each joint angle. The thesis prints the entries J11..J33 with its
    columns in the order (θ1, θ2, θ0): here column j belongs to q[j], q = (θ1, θ0, θ2).

    Args:
        q: (3,) joint angles (θ1, θ0, θ2), rad.
        L1, L2: upper-arm and forearm lengths, m.

    Returns:
        (3, 3) array, m/rad: row i is x, y or z, column j is joint j of q.
    """
    raise NotImplementedError("fill in hand_jacobian (thesis §3.3)")
