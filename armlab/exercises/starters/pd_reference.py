"""armlab exercise pd_reference: the PD reference model (thesis 000, eq. 2.20).

Fill in the function below, then check it:   armlab check pd_reference.py
"""

import numpy as np

EXERCISE = "pd_reference"


def pd_reference_accel(kp: float, kv: float, q_cmd: np.ndarray, qd_cmd: np.ndarray,
                       q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """The reference acceleration of the PD position loop (thesis eq. 2.20).

    The lab integrates this acceleration twice, every control period, into the goal
    position and speed it sends to the servos; the arm then follows the command as the
    reference model x_res = (Kv s + Kp)/(s² + Kv s + Kp) x_cmd (eq. 2.3).

    Args:
        kp: position gain Kp, 1/s² (the thesis: 3.8).
        kv: speed gain Kv, 1/s (the thesis: 0.2).
        q_cmd, qd_cmd: commanded angles (rad) and speeds (rad/s), (n,) arrays or floats.
        q, qd: measured angles and speeds, the same shape.

    Returns:
        θ̈_ref, rad/s², the same shape as q.
    """
    raise NotImplementedError("fill in pd_reference_accel (thesis eq. 2.20)")
