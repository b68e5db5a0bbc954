"""armlab exercise hand_stiffness: the hand's stiffness from the joints' (the contact lesson).

Fill in the function below, then check it:   armlab check hand_stiffness.py
"""

import numpy as np

EXERCISE = "hand_stiffness"


def hand_stiffness(J: np.ndarray, K_q: np.ndarray) -> np.ndarray:
    """The hand's stiffness K_x: the force per metre it pushes back with, each way.

    Every joint holds like a spring: a joint torque τ moves it by K_q⁻¹ τ (the compliance
    law at rest, thesis eq. 2.6 with 2.7: K_q = K_env / K_f on every joint). A force f at
    the hand puts τ = Jᵀ f on the joints (the Jacobian's transpose) and the joints' move
    moves the hand by J Δq. Write Δx = C_x f, then K_x = C_x⁻¹.

    Args:
        J: (m, n) the position rows of the Jacobian at the hand, m/rad (m directions of
            the hand, n joints; n may exceed m).
        K_q: (n, n) the joints' stiffness, N·m/rad (symmetric, positive definite).

    Returns:
        (m, m) array, N/m.
    """
    raise NotImplementedError("fill in hand_stiffness (K_x from K_q and J)")
