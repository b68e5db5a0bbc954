"""armlab exercise planar_ik: geometric IK of the planar 3-link arm (seed 004, eq. 1-24).

Fill in the function below, then check it:   armlab check planar_ik.py
"""

import math

EXERCISE = "planar_ik"


def planar_ik(X: float, Y: float, l1: float, l2: float,
              l3: float) -> tuple[float, float, float]:
    """Joint angles that put the hand of the planar 3-link arm at (X, Y) (seed 004).

    The paper's geometric method: choose the hand's orientation θ0 = atan2(Y, X) (eq. 1);
    step back from the target along it by l3 to the wrist point (x, y) (eq. 2-3); solve
    the two-link arm l1, l2 for the wrist point: cos θ2 = (x² + y² − l1² − l2²)/(2 l1 l2),
    θ2 = atan2(−√(1 − cos²θ2), cos θ2) (elbow down, as the paper's Table 1),
    θ1 = atan2(y, x) − atan2(k2, k1) with k1 = l1 + l2 cos θ2, k2 = l2 sin θ2; and close
    the chain: θ3 = θ0 − θ1 − θ2. Angles are relative (θ2 of link 2 against link 1, ...),
    counter-clockwise positive. If the wrist point is out of the two links' reach, clamp
    cos θ2 into [−1, 1] (the arm stretched or folded towards it).

    Args:
        X, Y: the target, m, in the arm's base frame.
        l1, l2, l3: link lengths, m (the paper: 0.065, 0.105, 0.065).

    Returns:
        (θ1, θ2, θ3), rad.
    """
    raise NotImplementedError("fill in planar_ik (seed 004)")
