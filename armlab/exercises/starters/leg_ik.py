"""armlab exercise leg_ik: IK of one quadruped leg in atan2 form (seed 003, eq. 3.1-3.9).

Fill in the function below, then check it:   armlab check leg_ik.py
"""

import math

EXERCISE = "leg_ik"


def leg_ik(x: float, y: float, z: float, l1: float, l2: float) -> tuple[float, float, float]:
    """Joint angles that put the foot of one leg at (x, y, z) (seed 003, eq. 3.1-3.9).

    The leg frame: x forward, y outward from the body, z up, origin at the hip. Joints:
    θ1 hip yaw, from the outward axis y towards x: θ1 = atan2(x, y); θ3 the knee from
    A = (x² + y² + z² − l1² − l2²)/(2 l1 l2): θ3 = atan2(+√(1 − A²), A) (the seed's
    root; clamp A into [−1, 1] for a foot out of reach); θ2 the hip pitch, the femur's
    angle below the horizontal: with r = √(x² + y²), h = −z, k1 = l1 + l2 cos θ3 and
    k2 = l2 sin θ3: θ2 = atan2(h k1 − r k2, r k1 + h k2).

    Args:
        x, y, z: the foot, m, in the leg frame.
        l1: femur length (hip pitch to knee), m (the lab: 0.075).
        l2: tibia length (knee to foot), m (the lab: 0.10).

    Returns:
        (θ1, θ2, θ3), rad.
    """
    raise NotImplementedError("fill in leg_ik (seed 003)")
