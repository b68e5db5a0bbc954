"""armlab exercise disturbance_observer: the disturbance observer (thesis 000, eq. 2.36).

Fill in the function below, then check it:   armlab check disturbance_observer.py
"""

import math

EXERCISE = "disturbance_observer"


def observer_step(z: float, current: float, qd: float, j_n: float, kt_n: float,
                  g_dis: float, dt: float) -> tuple[float, float]:
    """One sample of the disturbance observer (thesis eq. 2.36 with fig. 2.7-2.8).

    A motor-driven joint obeys J_n θ̈ = K_tn I − τ_dis (eq. 2.35); τ_dis lumps every
    torque the nominal model leaves out. Eq. 2.36, τ_dis = K_tn I − J_n θ̈, needs θ̈;
    the observer instead low-pass filters u = K_tn I + g J_n θ̇ through g/(s + g) and
    subtracts g J_n θ̇: τ̂_dis = g/(s + g) · u − g J_n θ̇ (fig. 2.8). Sampled, the filter
    is z = z + a (u − z) with a = 1 − exp(−g dt).

    Args:
        z: the filter's state (its last output), N·m.
        current: the motor current I_ref, A.
        qd: the joint speed θ̇, rad/s.
        j_n: nominal inertia J_n, kg·m².
        kt_n: nominal torque constant K_tn, N·m/A.
        g_dis: the filter's cut-off g, rad/s.
        dt: the sample time, s.

    Returns:
        (z, tau_dis_hat): the filter's new state and the estimated disturbance, N·m.
    """
    raise NotImplementedError("fill in observer_step (thesis eq. 2.36)")
