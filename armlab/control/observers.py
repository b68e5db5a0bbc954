"""Disturbance and reaction-torque observers on a torque-driven joint (thesis §2.1.1).

The RX-24F takes no current command, so this is the simulation lesson of
§2.1.1: a DC-motor joint J θ̈ = K_t I − τ_l (eq. 2.27, 2.29) whose load
τ_l = τ_g + τ_ext + F + D θ̇ (eq. 2.28) is unknown to the controller, which
only knows nominal J_n and K_tn. Everything it does not model is lumped into

    τ_dis = τ_l + (J − J_n) θ̈ − (K_t − K_tn) I_ref      (eq. 2.33)
    J_n θ̈ = K_tn I_ref − τ_dis                            (eq. 2.35)

and estimated without differentiating θ̇ (eq. 2.36 with the LPF of fig. 2.7–2.8),
or, after subtracting the known gravity and friction, the external torque
alone (reaction-torque observer, eq. 2.37).

Defaults are the thesis's gripper gearmotor (§2.4: 6 V, 5:1, 2 oz·in and 1.6 A
at stall, both at the gearbox output -> K_t = 2 oz·in / 1.6 A = 8.83e-3 N·m/A
at the output, :data:`armlab.kinematics.hand_statics.GRIPPER_KT`; the 5:1 ratio is already in
the stall torque and is not applied again); the finger inertia is an
assumption (not in the thesis).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from armlab.control.compliance import lpf
from armlab.kinematics.hand_statics import GRIPPER_KT


@dataclass(frozen=True)
class TorqueJoint:
    """A joint driven by motor current (the true plant).

    Attributes:
        inertia: J, kg·m².
        kt: K_t, N·m/A (at the joint).
        gravity: m g l, N·m; gravity torque is m g l sin θ.
        coulomb: F, N·m (smoothed sign over ``coulomb_speed``).
        viscous: D, N·m·s/rad.
        coulomb_speed: rad/s over which the Coulomb term changes sign.
    """

    inertia: float = 2.0e-5
    kt: float = GRIPPER_KT
    gravity: float = 0.004
    coulomb: float = 0.002
    viscous: float = 1.0e-4
    coulomb_speed: float = 0.05


def gravity_torque(joint: TorqueJoint, q: float) -> float:
    """τ_g = m g l sin θ, N·m."""
    return joint.gravity * math.sin(q)


def friction_torque(joint: TorqueJoint, qd: float) -> float:
    """F + D θ̇ of eq. 2.28 (Coulomb smoothed by tanh), N·m."""
    return joint.coulomb * math.tanh(qd / joint.coulomb_speed) + joint.viscous * qd


def load_torque(joint: TorqueJoint, q: float, qd: float, tau_ext: float) -> float:
    """Thesis eq. 2.28: τ_l = τ_int + τ_ext + (F + D θ̇); here τ_int is gravity (one joint)."""
    return gravity_torque(joint, q) + tau_ext + friction_torque(joint, qd)


def joint_accel(joint: TorqueJoint, current: float, tau_load: float) -> float:
    """Thesis eq. 2.27 with 2.29: θ̈ = (K_t I − τ_l) / J."""
    return (joint.kt * current - tau_load) / joint.inertia


def total_disturbance(tau_load: float, qdd: float, current: float, *, inertia: float,
                      j_n: float, kt: float, kt_n: float) -> float:
    """Thesis eq. 2.33: τ_dis = τ_l + ΔJ θ̈ − ΔK_t I_ref (ΔJ = J − J_n, ΔK_t = K_t − K_tn)."""
    return tau_load + (inertia - j_n) * qdd - (kt - kt_n) * current


def lpf_gain(cutoff: float, dt: float) -> float:
    """Gain a of the sampled first-order LPF g/(s + g): y += a (x − y), a = 1 − e^(−g dt)."""
    return 1.0 - math.exp(-cutoff * dt)


@dataclass
class ObserverState:
    """Filter state of one observer (the LPF output before − g J_n θ̇ is taken off)."""

    z: float = 0.0


def disturbance_observer(state: ObserverState, current: float, qd: float, *, j_n: float,
                         kt_n: float, g_dis: float, dt: float) -> float:
    """Disturbance observer (thesis eq. 2.36 through the LPF of fig. 2.7–2.8), one sample.

    τ̂_dis = g/(s + g) · (K_tn I_ref + g J_n θ̇) − g J_n θ̇, which equals
    g/(s + g) · (K_tn I_ref − J_n θ̈) without differentiating θ̇.

    Args:
        state: the filter state (updated in place).
        current: I_ref, A.  qd: θ̇, rad/s.  g_dis: cut-off, rad/s.  dt: sample time, s.

    Returns:
        τ̂_dis, N·m.
    """
    u = kt_n * current + g_dis * j_n * qd
    state.z = lpf(state.z, u, lpf_gain(g_dis, dt))
    return state.z - g_dis * j_n * qd


def reaction_torque_observer(state: ObserverState, current: float, qd: float,
                             tau_known: float, *, j_n: float, kt_n: float, g_reac: float,
                             dt: float) -> float:
    """Reaction-torque observer (thesis eq. 2.37), one sample.

    τ̂_reac = g/(s + g) · (K_tn I_ref + g J_n θ̇ − τ_int − τ_g − F − D θ̇) − g J_n θ̇.

    Args:
        tau_known: τ_int + τ_g + F + D θ̇ from the identified model, N·m.

    Returns:
        τ̂_reac, the external torque estimate, N·m.
    """
    u = kt_n * current + g_reac * j_n * qd - tau_known
    state.z = lpf(state.z, u, lpf_gain(g_reac, dt))
    return state.z - g_reac * j_n * qd


@dataclass(frozen=True)
class ObserverRun:
    """Time series of :func:`simulate_observers` (all (N,) arrays, SI)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    current: np.ndarray
    tau_dis: np.ndarray
    tau_dis_hat: np.ndarray
    tau_ext: np.ndarray
    tau_ext_hat: np.ndarray


def simulate_observers(joint: TorqueJoint, tau_ext: Callable[[float], float], *,
                       duration: float = 2.0, dt: float = 1e-4, j_n: float | None = None,
                       kt_n: float | None = None, g_dis: float = 200.0,
                       g_reac: float = 200.0, q_cmd: float = 0.5, kp: float = 400.0,
                       kv: float = 40.0, compensate: bool = False,
                       observer: Callable[..., float] | None = None) -> ObserverRun:
    """Run the torque-driven joint under a PD current loop with both observers.

    The controller asks I_ref = (J_n (Kp (θ_cmd − θ) − Kv θ̇) [+ τ̂_dis]) / K_tn; with
    ``compensate`` it feeds the estimated disturbance back (thesis fig. 2.9), which
    makes the joint hold its position against the external torque.

    Args:
        joint: the true plant.
        tau_ext: external load torque (N·m) as a function of time (s).
        j_n, kt_n: the nominal model (default: the true values).
        g_dis, g_reac: observer cut-offs, rad/s.
        observer: the disturbance observer to run (default :func:`disturbance_observer`;
            coursework runs a student's in its place), called as it is.

    Returns:
        the true and estimated disturbance and external torque at every sample.
    """
    j_n = joint.inertia if j_n is None else j_n
    kt_n = joint.kt if kt_n is None else kt_n
    n = int(round(duration / dt)) + 1
    out = {k: np.zeros(n) for k in ("q", "qd", "current", "tau_dis", "tau_dis_hat",
                                    "tau_ext", "tau_ext_hat")}
    dob, rtob = ObserverState(), ObserverState()
    q = qd = 0.0
    dis_hat = 0.0
    dob_step = disturbance_observer if observer is None else observer
    for k in range(n):
        t = k * dt
        acc = j_n * (kp * (q_cmd - q) - kv * qd)
        current = (acc + (dis_hat if compensate else 0.0)) / kt_n
        ext = float(tau_ext(t))
        tl = load_torque(joint, q, qd, ext)
        qdd = joint_accel(joint, current, tl)
        dis_hat = dob_step(dob, current, qd, j_n=j_n, kt_n=kt_n, g_dis=g_dis, dt=dt)
        known = gravity_torque(joint, q) + friction_torque(joint, qd)
        ext_hat = reaction_torque_observer(rtob, current, qd, known, j_n=j_n, kt_n=kt_n,
                                           g_reac=g_reac, dt=dt)
        for key, val in (("q", q), ("qd", qd), ("current", current),
                         ("tau_dis", total_disturbance(tl, qdd, current, inertia=joint.inertia,
                                                       j_n=j_n, kt=joint.kt, kt_n=kt_n)),
                         ("tau_dis_hat", dis_hat), ("tau_ext", ext), ("tau_ext_hat", ext_hat)):
            out[key][k] = val
        qd += dt * qdd
        q += dt * qd
    return ObserverRun(t=np.arange(n) * dt, **out)
