"""Rigid-body dynamics of a serial chain: recursive Newton–Euler (thesis §2.2, eq. 2.41–2.50).

Conventions: joint space in the model's joint order (rad, rad/s, N·m; m and N for
prismatic joints); vectors "in the base frame" are in the chain's base frame (for
``receptionist_arm`` the thesis frame, gravity +x), not the viewer's world.

Equation of motion::

    tau = M(q) qdd + C(q, qd) qd + g(q) - J(q)^T f_ext          (rnea computes the right side)

Two implementations of one recursion:

- :func:`newton_euler` is the text to read beside the thesis: one commented step per
  equation, plain numpy over the chain. It is the test oracle.
- :func:`rnea` and the functions after it run the same recursion as straight-line code
  generated once per chain (``armlab.kinematics._rnea_codegen``), fast enough for the plant's
  1 kHz RK4; tests/test_dynamics.py checks it equals :func:`newton_euler` to 1e-12 on
  every shipped robot.

Points on links (their Jacobians, forces there) are in :mod:`armlab.kinematics.points`; the
thesis's simplified closed forms of §3.4 in :mod:`armlab.kinematics.thesis_dynamics`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from armlab.kinematics._rnea_codegen import DynamicsModel, dynamics_model
from armlab.kinematics.model import SerialChain
from armlab.kinematics.points import link_frames, point_jacobian6
from armlab.kinematics.transforms import rot_axis
from armlab.kinematics.validate import floats, matrix, vector

__all__ = ["DynamicsModel", "dynamics_model", "newton_euler", "rnea", "gravity_torques",
           "bias_torques", "mass_matrix", "forward_dynamics", "kinetic_energy",
           "potential_energy"]


# ---------------------------------------------------------------------------
# The recursion as the thesis writes it (the teaching text and the test oracle)


def newton_euler(model: SerialChain, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *,
                 gravity: np.ndarray | None = None) -> np.ndarray:
    """Inverse dynamics by the recursive Newton–Euler equations, written out as the thesis
    gives them (eq. 2.41–2.50) and read joint by joint.

    Frame i is link i's frame (the child of joint i); ``R`` = parent <- child rotation and
    ``p`` = the child origin in the parent frame, both from the joint's origin and its
    motion. Every vector of link i is expressed in frame i. Gravity enters as an upward
    acceleration of the base (the usual trick): the base "accelerates" at -g, so every
    link's inertial force carries its weight.

    Args:
        model: the chain (n joints, revolute or prismatic).
        q, qd, qdd: (n,) joint positions, velocities, accelerations.
        gravity: (3,) m/s², base frame; default ``model.gravity``.

    Returns:
        (n,) joint torques tau = M qdd + C qd + g(q) (N·m, or N for prismatic).

    Slow (numpy on 3-vectors, a few hundred µs); :func:`rnea` is the same sum, fast.
    """
    n = model.n
    q, qd, qdd = (vector(name, v, n) for name, v in (("q", q), ("qd", qd), ("qdd", qdd)))
    g = model.gravity if gravity is None else vector("gravity", gravity, 3)
    R: list[np.ndarray] = []  # parent <- link i
    p: list[np.ndarray] = []  # link i's origin in the parent frame
    for joint, qi in zip(model.joints, q, strict=True):
        R0, p0 = joint.origin[:3, :3], joint.origin[:3, 3]  # the joint's frame at q = 0
        if joint.kind == "prismatic":  # a slide along the axis
            R.append(R0)
            p.append(p0 + R0 @ (qi * joint.axis))
        else:  # a turn about the axis
            R.append(R0 @ rot_axis(joint.axis, qi))
            p.append(p0)

    # Outward pass: velocities and accelerations from the base to the tip.
    w = np.zeros(3)       # ω of the parent, in the parent frame (the base does not turn)
    dw = np.zeros(3)      # ω̇ of the parent
    dv = -np.asarray(g)   # v̇ of the parent's origin: the base "accelerates" against gravity
    F: list[np.ndarray] = []  # inertial force of each link at its centre of mass (frame i)
    N: list[np.ndarray] = []  # inertial moment of each link about its centre of mass
    for i, (joint, link) in enumerate(zip(model.joints, model.links, strict=True)):
        Rt = R[i].T  # link i <- parent
        z = joint.axis  # ẑ_i: the joint axis, in frame i
        # eq. 2.46: the acceleration of link i's origin, carried out from the parent's
        # origin along p (the thesis prints "- ω × ω × p"; the centripetal term is +)
        dv = Rt @ (dv + np.cross(dw, p[i]) + np.cross(w, np.cross(w, p[i])))
        if joint.kind == "prismatic":
            w_new = Rt @ w  # eq. 2.42: a slide does not turn the link
            dw_new = Rt @ dw  # eq. 2.44
            # eq. 2.47: the slide's own acceleration and its Coriolis term
            dv = dv + qdd[i] * z + 2.0 * np.cross(w_new, qd[i] * z)
        else:
            w_new = Rt @ w + qd[i] * z  # eq. 2.41
            # eq. 2.43: the parent's ω̇, the turning of the joint axis, the joint's own θ̈
            dw_new = Rt @ dw + np.cross(Rt @ w, qd[i] * z) + qdd[i] * z
        w, dw = w_new, dw_new
        c = link.com  # p_cm: the centre of mass in frame i
        dv_cm = np.cross(dw, c) + np.cross(w, np.cross(w, c)) + dv  # eq. 2.48
        F.append(link.mass * dv_cm)  # eq. 2.49: Newton
        N.append(link.inertia @ dw + np.cross(w, link.inertia @ w))  # eq. 2.50: Euler

    # Inward pass: the force f and moment m that each link's parent exerts on it, from
    # the tip to the base (Craig eq. 6.51–6.53, which §3.4 applies by hand), and the
    # joint torque as the moment's (or force's) component along the joint axis.
    tau = np.zeros(n)
    f = np.zeros(3)  # f_{i+1}: what link i exerts on link i+1 (frame i+1)
    m = np.zeros(3)
    for i in range(n - 1, -1, -1):
        if i + 1 < n:
            f_child = R[i + 1] @ f  # link i+1's load, into frame i
            m_child = R[i + 1] @ m + np.cross(p[i + 1], f_child)
        else:
            f_child = m_child = np.zeros(3)
        f = F[i] + f_child
        m = N[i] + m_child + np.cross(model.links[i].com, F[i])
        z = model.joints[i].axis
        tau[i] = f @ z if model.joints[i].kind == "prismatic" else m @ z
    return tau


# ---------------------------------------------------------------------------
# Public functions (validated numpy in, numpy out)


def _gravity(model: SerialChain, gravity: object) -> list[float]:
    if gravity is None:
        return np.asarray(model.gravity, dtype=float).tolist()
    return floats("gravity", gravity, 3)


def _external_torques(model: SerialChain, q: list[float], f_ext: object) -> np.ndarray:
    """J^T f_ext: joint torques (n,) of wrenches (n, 6) [force N, moment N·m about the link
    origin], base frame, one row per link, acting on the robot."""
    W = matrix("f_ext", f_ext, (model.n, 6))
    frames = link_frames(model, q)
    out = np.zeros(model.n)
    for i, (_, o_i) in enumerate(frames):
        if np.any(W[i]):
            out += point_jacobian6(model, frames, i, o_i).T @ W[i]
    return out


def rnea(model: SerialChain, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *,
         gravity: np.ndarray | None = None, f_ext: np.ndarray | None = None) -> np.ndarray:
    """Inverse dynamics by recursive Newton–Euler (thesis eq. 2.41–2.50).

    Args:
        model: the chain.
        q, qd, qdd: (n,) joint positions, velocities, accelerations.
        gravity: (3,) m/s², base frame; default ``model.gravity``.
        f_ext: optional (n, 6) external wrenches acting on the links, base frame:
            row i = [force (3,) N, moment (3,) N·m about link i's frame origin].

    Returns:
        (n,) joint torques tau = M qdd + C qd + g(q) - J^T f_ext (N·m, or N for prismatic).

    Example: a 1-link rod of mass m and length L hanging along gravity needs
    tau = m g (L/2) sin(q) to hold it at angle q.
    """
    n = model.n
    dyn = dynamics_model(model)
    qv = floats("q", q, n)
    tau = dyn.rnea(qv, floats("qd", qd, n), floats("qdd", qdd, n), _gravity(model, gravity))
    out = np.array(tau)
    if f_ext is not None:
        out -= _external_torques(model, qv, f_ext)
    return out


def gravity_torques(model: SerialChain, q: np.ndarray, *,
                    gravity: np.ndarray | None = None) -> np.ndarray:
    """(n,) g(q): the joint torques that hold the chain still at q (RNEA with qd = qdd = 0)."""
    n = model.n
    return np.array(dynamics_model(model).bias(floats("q", q, n), [0.0] * n,
                                               _gravity(model, gravity)))


def bias_torques(model: SerialChain, q: np.ndarray, qd: np.ndarray, *,
                 gravity: np.ndarray | None = None) -> np.ndarray:
    """(n,) C(q, qd) qd + g(q): Coriolis, centrifugal and gravity torques (RNEA, qdd = 0)."""
    n = model.n
    return np.array(dynamics_model(model).bias(floats("q", q, n), floats("qd", qd, n),
                                               _gravity(model, gravity)))


def mass_matrix(model: SerialChain, q: np.ndarray | Sequence[float]) -> np.ndarray:
    """(n, n) joint-space inertia M(q), symmetric positive definite; column k = RNEA with
    qdd = e_k, qd = 0, no gravity."""
    n = model.n
    return np.array(dynamics_model(model).mass(floats("q", q, n))).reshape(n, n)


def forward_dynamics(model: SerialChain, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, *,
                     f_ext: np.ndarray | None = None, gravity: np.ndarray | None = None,
                     armature: np.ndarray | None = None) -> np.ndarray:
    """Joint accelerations qdd = (M + diag(armature))^-1 (tau + J^T f_ext - C qd - g).

    Args:
        q, qd, tau: (n,) joint positions, velocities, applied joint torques.
        f_ext: optional (n, 6) external wrenches as in :func:`rnea`.
        gravity: (3,) base frame; default ``model.gravity``.
        armature: optional (n,) extra inertia on each joint's own axis (e.g. a motor
            rotor seen through its gear: J_rotor · ratio²), kg m².

    Returns:
        (n,) qdd.
    """
    n = model.n
    qv = floats("q", q, n)
    tv = floats("tau", tau, n)
    if f_ext is not None:
        tv = (np.array(tv) + _external_torques(model, qv, f_ext)).tolist()
    arm = [0.0] * n if armature is None else floats("armature", armature, n)
    if any(a < 0 for a in arm):
        raise ValueError(f"armature must be >= 0, got {arm}")
    try:
        qdd = dynamics_model(model).fd(qv, floats("qd", qd, n), tv, _gravity(model, gravity),
                                       arm)
    except ZeroDivisionError:
        raise ValueError("mass matrix is singular at this q (a joint moves no inertia); "
                         "give an armature") from None
    return np.array(qdd)


def kinetic_energy(model: SerialChain, q: np.ndarray | Sequence[float],
                   qd: np.ndarray | Sequence[float], *,
                   armature: np.ndarray | Sequence[float] | None = None) -> float:
    """½ qdᵀ (M(q) + diag(armature)) qd, J."""
    qdv = vector("qd", qd, model.n)
    M = mass_matrix(model, q)
    if armature is not None:
        M = M + np.diag(vector("armature", armature, model.n))
    return float(0.5 * qdv @ M @ qdv)


def potential_energy(model: SerialChain, q: np.ndarray | Sequence[float], *,
                     gravity: np.ndarray | None = None) -> float:
    """-Σ m_i g·c_i: gravitational potential energy relative to the base origin, J."""
    g = np.array(_gravity(model, gravity))
    qv = floats("q", q, model.n)
    V = 0.0
    for link, (R, p) in zip(model.links, link_frames(model, qv), strict=True):
        if link.mass:
            V -= link.mass * float(g @ (R @ link.com + p))
    return V
