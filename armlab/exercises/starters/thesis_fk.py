"""armlab exercise thesis_fk: forward kinematics of the receptionist arm (thesis 000, eq. 3.13).

Fill in the function below, then check it:   armlab check thesis_fk.py
"""

import numpy as np

EXERCISE = "thesis_fk"


def hand_position(q: np.ndarray, L1: float, L2: float) -> np.ndarray:
    """The hand's position (x, y, z) for the joint angles q (thesis eq. 3.13).

    The arm: the shoulder turns about the world z axis by θ1, then about the new y axis
    by θ0; the upper arm (length L1) runs along x to the elbow, which turns about z by θ2;
    the forearm (length L2) runs along x to the hand. Gravity points along +x, so q = 0
    hangs the arm straight down the x axis. T = Rz(θ1) Ry(θ0) Tx(L1) Rz(θ2) Tx(L2), and
    the thesis writes out its last column (eq. 3.13) with c0 = cos θ0, s1 = sin θ1, ...

    Args:
        q: (3,) joint angles (θ1, θ0, θ2), rad, in this order (the lab's joint order).
        L1: upper-arm length, m (0.185 in the thesis's appendix code).
        L2: forearm length, m (0.25).

    Returns:
        (3,) array: x, y, z of the hand, m, in the shoulder frame.
    """
    raise NotImplementedError("fill in hand_position (thesis eq. 3.13)")
