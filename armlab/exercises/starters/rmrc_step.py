"""armlab exercise rmrc_step: one RMRC step with step halving (thesis 000, eq. 3.20-3.22).

Fill in the function below, then check it:   armlab check rmrc_step.py
"""

import numpy as np

EXERCISE = "rmrc_step"

#: Most halvings of dX before the step is given up.
MAX_HALVINGS = 30


def rmrc_step(q: np.ndarray, J: np.ndarray, J_inv: np.ndarray, dX: np.ndarray, e: float,
              lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """One step of resolved motion rate control (thesis eq. 3.21 and 3.22).

    The lab has found the task error dX = X_target − X (eq. 3.16), the Jacobian J at q
    and an inverse J_inv of it (eq. 3.20, adj(J)/det(J); or the pseudo-inverse of
    eq. 3.19; or, near a singularity, a damped inverse that is not exact). Eq. 3.21
    checks how well the inverse can be trusted for this step: while
    error = |(I − J J_inv) dX| > e, halve dX. Then eq. 3.22: θ = θ + J_inv dX, and the
    new angles are clipped into [lower, upper]. If MAX_HALVINGS halvings are not enough
    (the error is still above e), the step is not taken: return q unchanged.

    Args:
        q: (n,) joint angles, rad.
        J: (m, n) Jacobian of the hand's position, m/rad.
        J_inv: (n, m) its inverse (or pseudo-inverse), rad/m.
        dX: (m,) task step, m.
        e: the error bound of eq. 3.21, m.
        lower, upper: (n,) joint limits, rad.

    Returns:
        (n,) the new joint angles, rad.
    """
    raise NotImplementedError("fill in rmrc_step (thesis eq. 3.21-3.22)")
