"""Forward kinematics and the geometric Jacobian of a serial chain (thesis §3.2-3.3).

Product of homogeneous transforms, one per joint: T = Π origin_i · motion_i(q_i) · tip
(thesis eq. 3.8-3.12; for the receptionist arm the product reduces to eq. 3.13).
"""

from __future__ import annotations

import math

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


def _rotate(r: tuple[float, ...], m: tuple[float, ...]) -> tuple[float, ...]:
    """Product of two row-major 3x3 matrices given as 9-tuples of floats."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    return (
        r00 * m00 + r01 * m10 + r02 * m20, r00 * m01 + r01 * m11 + r02 * m21,
        r00 * m02 + r01 * m12 + r02 * m22,
        r10 * m00 + r11 * m10 + r12 * m20, r10 * m01 + r11 * m11 + r12 * m21,
        r10 * m02 + r11 * m12 + r12 * m22,
        r20 * m00 + r21 * m10 + r22 * m20, r20 * m01 + r21 * m11 + r22 * m21,
        r20 * m02 + r21 * m12 + r22 * m22,
    )


def fk_and_jacobian(
    model: SerialChain, q: np.ndarray, *, check: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """End-effector pose and geometric Jacobian in one pass (thesis eq. 3.13 and 3.17).

    The same numbers as :func:`fk` and :func:`jacobian`, computed together on plain
    floats (3x3 rotation blocks, Rodrigues' formula per joint, no 4x4 temporaries):
    for short chains this is several times faster than the array version, which is
    what the IK loops (:mod:`kinematics.ik`) need.

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
    R = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    px = py = pz = 0.0
    axes: list[tuple[float, float, float]] = []
    points: list[tuple[float, float, float]] = []
    for joint, qi in zip(model.joints, q.tolist(), strict=True):
        (o00, o01, o02, ox), (o10, o11, o12, oy), (o20, o21, o22, oz), _ = joint.origin.tolist()
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        px, py, pz = (px + r00 * ox + r01 * oy + r02 * oz,
                      py + r10 * ox + r11 * oy + r12 * oz,
                      pz + r20 * ox + r21 * oy + r22 * oz)
        R = _rotate(R, (o00, o01, o02, o10, o11, o12, o20, o21, o22))
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        ax, ay, az = joint.axis.tolist()
        zx = r00 * ax + r01 * ay + r02 * az
        zy = r10 * ax + r11 * ay + r12 * az
        zz = r20 * ax + r21 * ay + r22 * az
        axes.append((zx, zy, zz))
        if joint.kind == "prismatic":
            px, py, pz = px + zx * qi, py + zy * qi, pz + zz * qi
        else:
            # Rodrigues: R(a, q) = c I + s [a]x + (1 - c) a a^T.
            c, s = math.cos(qi), math.sin(qi)
            v = 1.0 - c
            R = _rotate(R, (c + ax * ax * v, ax * ay * v - az * s, ax * az * v + ay * s,
                            ay * ax * v + az * s, c + ay * ay * v, ay * az * v - ax * s,
                            az * ax * v - ay * s, az * ay * v + ax * s, c + az * az * v))
        points.append((px, py, pz))
    rot = np.array(R).reshape(3, 3)
    T = np.eye(4)
    T[:3, :3] = rot @ model.tip[:3, :3]
    T[:3, 3] = np.array((px, py, pz)) + rot @ model.tip[:3, 3]
    ex, ey, ez = T[:3, 3].tolist()
    cols = []
    for joint, (zx, zy, zz), (ox, oy, oz) in zip(model.joints, axes, points, strict=True):
        if joint.kind == "prismatic":
            cols.append((zx, zy, zz, 0.0, 0.0, 0.0))
        else:
            dx, dy, dz = ex - ox, ey - oy, ez - oz
            cols.append((zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx, zx, zy, zz))
    return T, np.array(cols).T.copy()
