"""armlab exercise environment_impedance: the virtual environment (thesis 000, eq. 2.7).

Fill in the function below, then check it:   armlab check environment_impedance.py
"""

import numpy as np

EXERCISE = "environment_impedance"


def environment_step(m_env: float, d_env: float, k_env: float, k_f: float,
                     tau_ext: np.ndarray, q_env: np.ndarray, qd_env: np.ndarray,
                     dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One sample of the environment impedance (thesis eq. 2.7).

    Eq. 2.7, θ_env = K_f / (M_env s² + D_env s + K_env) · τ_ext, is the differential
    equation M_env θ̈_env + D_env θ̇_env + K_env θ_env = K_f τ_ext: a virtual
    mass-spring-damper that the external torque pushes. Step it by dt with semi-implicit
    Euler: θ̈ from the equation at the current state, then θ̇ += dt θ̈, then θ += dt θ̇
    (with the new θ̇).

    Args:
        m_env, d_env, k_env: the environment's mass, damping and stiffness
            (the thesis's Table 4.1: 1, 5, 12).
        k_f: torque gain K_f (Table 4.1: 0.3).
        tau_ext: external torque, N·m, (n,) array or float.
        q_env, qd_env: the offset θ_env (rad) and its speed (rad/s) now, same shape.
        dt: the sample time, s (the thesis: 0.016).

    Returns:
        (θ_env, θ̇_env, θ̈_env) after the step, each the shape of q_env.
    """
    raise NotImplementedError("fill in environment_step (thesis eq. 2.7)")
