"""Forward kinematics and the geometric Jacobian of a serial chain (thesis §3.2-3.3).

Product of homogeneous transforms, one per joint: T = Π origin_i · motion_i(q_i) · tip
(thesis eq. 3.8-3.12; for the receptionist arm the product reduces to eq. 3.13).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from armlab.kinematics._rnea_codegen import dynamics_model
from armlab.kinematics.transforms import rot_axis
from armlab.kinematics.validate import vector

if TYPE_CHECKING:  # annotations only: the model's fk(), jacobian() are these functions
    from armlab.kinematics.model import SerialChain


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
    return fk_and_jacobian(model, q)[0]


def jacobian(model: SerialChain, q: np.ndarray) -> np.ndarray:
    """Geometric Jacobian of the end effector (thesis eq. 3.14-3.15, generic form).

    Column i is [z_i × (p_e − p_i); z_i] for a revolute joint and [z_i; 0] for a
    prismatic one, with z_i the joint axis and p_i its origin in the base frame.

    Args:
        q: (n,) joint positions.

    Returns:
        (6, n): rows 0-2 linear velocity (m/s per rad/s), rows 3-5 angular velocity.
    """
    return fk_and_jacobian(model, q)[1]


def fk_and_jacobian(
    model: SerialChain, q: np.ndarray, *, check: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """End-effector pose and geometric Jacobian in one pass (thesis eq. 3.13 and 3.17).

    Computed together as straight-line float code generated once per chain (the
    product of eq. 3.8–3.12 unrolled, structural zeros and ones folded away; see
    ``armlab.kinematics._rnea_codegen``): a few microseconds for a short chain, which is what
    the IK loops (:mod:`armlab.kinematics.ik`) need. :func:`link_poses` is the same product
    written as 4x4 matrices, to read.

    Args:
        model: the chain.
        q: (n,) joint positions (rad for revolute, m for prismatic).
        check: validate ``q`` (False only in a hot loop whose q is already checked).

    Returns:
        ``(T, J)``: T (4, 4) base <- end effector; J (6, n), rows 0-2 linear velocity,
        rows 3-5 angular velocity, column i for joint i.
    """
    if check:
        q = vector("q", q, model.n)
    out = np.array(dynamics_model(model).tip(q.tolist()))
    return out[:16].reshape(4, 4), out[16:].reshape(6, model.n)
