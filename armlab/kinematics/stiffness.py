"""The hand's stiffness from the joints' (joint-space stiffness seen at the hand).

A joint stiffness K_q (n, n) N·m/rad holds a joint torque τ = K_q Δq; at the hand a force
f makes τ = Jᵀ f and moves the hand by Δx = J Δq = J K_q⁻¹ Jᵀ f: the hand's compliance is
C_x = J K_q⁻¹ Jᵀ and its stiffness K_x = C_x⁻¹ (J the position rows of the Jacobian; the
compliance law's static stiffness K_q = (K_env / K_f) I, thesis eq. 2.6 with 2.7).
"""

from __future__ import annotations

import numpy as np


def cartesian_compliance(J: np.ndarray, K_q: np.ndarray) -> np.ndarray:
    """C_x = J K_q⁻¹ Jᵀ (m, m) m/N of the hand, for the position Jacobian ``J`` (m, n) m/rad
    and the joint stiffness ``K_q`` (n, n) N·m/rad (symmetric, positive definite)."""
    J = np.asarray(J, dtype=float)
    return J @ np.linalg.solve(np.asarray(K_q, dtype=float), J.T)


def cartesian_stiffness(J: np.ndarray, K_q: np.ndarray) -> np.ndarray:
    """K_x = (J K_q⁻¹ Jᵀ)⁻¹ (m, m) N/m: the force per metre the hand pushes back with,
    each way, held by joints of stiffness ``K_q`` (n, n) N·m/rad through the position
    Jacobian ``J`` (m, n) m/rad of full row rank (a singular arm has no finite compliance
    along a direction it cannot move: LinAlgError).

    Raises:
        numpy.linalg.LinAlgError: ``J`` loses rank (C_x is singular).
    """
    return np.linalg.inv(cartesian_compliance(J, K_q))
