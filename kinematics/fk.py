"""Forward kinematics and the geometric Jacobian of a serial chain (thesis §3.2-3.3).

Product of homogeneous transforms, one per joint: T = Π origin_i · motion_i(q_i) · tip
(thesis eq. 3.8-3.12; for the receptionist arm the product reduces to eq. 3.13).
"""

from __future__ import annotations

import numpy as np

from kinematics.model import SerialChain
from kinematics.transforms import rot_axis
from kinematics.validate import vector


def _motion(joint, qi: float) -> np.ndarray:
    T = np.eye(4)
    if joint.kind == "prismatic":
        T[:3, 3] = joint.axis * qi
    else:
        T[:3, :3] = rot_axis(joint.axis, qi)
    return T


def link_poses(model: SerialChain, q: np.ndarray) -> np.ndarray:
    """Pose of every moving link frame in the base frame.

    Args:
        model: the chain.
        q: (n,) joint positions (rad for revolute, m for prismatic).

    Returns:
        (n, 4, 4) array; entry i is base <- link i (the frame of joint i after its motion).
    """
    q = vector("q", q, model.n)
    out = np.empty((model.n, 4, 4))
    T = np.eye(4)
    for i, joint in enumerate(model.joints):
        T = T @ joint.origin @ _motion(joint, q[i])
        out[i] = T
    return out


def fk(model: SerialChain, q: np.ndarray) -> np.ndarray:
    """(4, 4) end-effector pose in the base frame (thesis eq. 3.12-3.13)."""
    return link_poses(model, q)[-1] @ model.tip


def jacobian(model: SerialChain, q: np.ndarray) -> np.ndarray:
    """Geometric Jacobian of the end effector (thesis eq. 3.14-3.15, generic form).

    Column i is [z_i × (p_e − p_i); z_i] for a revolute joint and [z_i; 0] for a
    prismatic one, with z_i the joint axis and p_i its origin in the base frame.

    Args:
        q: (n,) joint positions.

    Returns:
        (6, n): rows 0-2 linear velocity (m/s per rad/s), rows 3-5 angular velocity.
    """
    poses = link_poses(model, q)
    p_e = (poses[-1] @ model.tip)[:3, 3]
    J = np.zeros((6, model.n))
    for i, joint in enumerate(model.joints):
        z = poses[i][:3, :3] @ joint.axis
        if joint.kind == "prismatic":
            J[:3, i] = z
        else:
            J[:3, i] = np.cross(z, p_e - poses[i][:3, 3])
            J[3:, i] = z
    return J
