"""armlab exercise compliance_law: the compliance controller (thesis 000, eq. 2.6).

Fill in the function below, then check it:   armlab check compliance_law.py
"""

import numpy as np

EXERCISE = "compliance_law"


def compliance_accel(kp: float, kv: float, q_cmd: np.ndarray, qd_cmd: np.ndarray,
                     q: np.ndarray, qd: np.ndarray, q_env: np.ndarray, qd_env: np.ndarray,
                     qdd_env: np.ndarray) -> np.ndarray:
    """The compliance controller's reference acceleration (thesis eq. 2.6, joint space).

    The PD loop of eq. 2.20 is made to follow the command moved by the environment's
    offset θ_env (eq. 2.7, exercise environment_impedance), so the arm gives way to a
    push: θ̈_ref = Kp (θ_cmd − θ − θ_env) + Kv (θ̇_cmd − θ̇ − θ̇_env) − θ̈_env.

    Args:
        kp, kv: the PD gains, 1/s² and 1/s.
        q_cmd, qd_cmd: commanded angles (rad) and speeds (rad/s), (n,) arrays or floats.
        q, qd: measured angles and speeds, same shape.
        q_env, qd_env, qdd_env: the environment offset, its speed and acceleration.

    Returns:
        θ̈_ref, rad/s², the same shape as q.
    """
    raise NotImplementedError("fill in compliance_accel (thesis eq. 2.6)")
