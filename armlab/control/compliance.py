"""The thesis's PD reference loop and compliance controller (thesis 000 §2.1).

One function per equation; each works on floats or on (n,) arrays alike.
:class:`ComplianceController` strings them together once per control period:

    τ_lpf  = LPF(τ_dist)                      (ch. 4 LPF, y += α(x − y))
    τ_ext  = τ_lpf − τ_dyn                    (eq. 2.23, τ_dyn from Newton–Euler)
    θ_env  <- M θ̈ + D θ̇ + K θ = K_f τ_ext     (eq. 2.7, one semi-implicit Euler step)
    θ̈_ref  = law 2.20 / 2.6 / 2.26
    θ̇_ref += T θ̈_ref ; θ_ref += T θ̇_ref       (integrated twice, then sent to the servos)

Sign convention: the servo's load is the torque the motor *applies*, so τ_ext
is the torque the motor spends against the outside world; a hand pushing a
joint forward gives τ_ext < 0, θ_env < 0, and the reference θ_cmd − θ_env moves
forward with the hand (eq. 2.4: x_real = x_virtual − x_env).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np

from armlab.control.backend import JointState
from armlab.control.laws import LAWS, ArrayT, ComplianceLaw, with_student
from armlab.control.params import ParamColumns, Params
from armlab.kinematics.smallarrays import clamp

Mode = Literal["none", "pd", "compliance"]
MODES: tuple[str, ...] = ("none", "pd", "compliance")

Array = np.ndarray | float


def pd_reference_accel(kp: float, kv: float, q_cmd: ArrayT, qd_cmd: ArrayT, q: ArrayT,
                       qd: ArrayT) -> ArrayT:
    """Thesis eq. 2.20: θ̈_ref = Kp (θ_cmd − θ) + Kv (θ̇_cmd − θ̇).

    Args:
        q_cmd, qd_cmd: commanded position (rad) and speed (rad/s), (n,) or scalar.
        q, qd: measured position and speed, same shape.

    Returns:
        θ̈_ref, rad/s², same shape.
    """
    return kp * (q_cmd - q) + kv * (qd_cmd - qd)


def environment_accel(m_env: float, d_env: float, k_env: float, k_f: float, tau_ext: ArrayT,
                      q_env: ArrayT, qd_env: ArrayT) -> ArrayT:
    """Thesis eq. 2.7 as a differential equation: M θ̈_env + D θ̇_env + K θ_env = K_f τ_ext.

    Returns θ̈_env (rad/s²) for the current state and external torque (N·m).
    """
    return (k_f * tau_ext - d_env * qd_env - k_env * q_env) / m_env


def environment_step(m_env: float, d_env: float, k_env: float, k_f: float, tau_ext: ArrayT,
                     q_env: ArrayT, qd_env: ArrayT, dt: float) -> tuple[ArrayT, ArrayT, ArrayT]:
    """One discrete step of the environment impedance (thesis eq. 2.7).

    Semi-implicit Euler: θ̈ from (2.7), then θ̇ += dt θ̈, then θ += dt θ̇.

    Returns:
        (θ_env, θ̇_env, θ̈_env) after the step.
    """
    qdd = environment_accel(m_env, d_env, k_env, k_f, tau_ext, q_env, qd_env)
    qd = qd_env + dt * qdd
    return q_env + dt * qd, qd, qdd


def integrate_reference(q_ref: ArrayT, qd_ref: ArrayT, qdd_ref: ArrayT,
                        dt: float) -> tuple[ArrayT, ArrayT]:
    """θ̈_ref integrated twice over one period (semi-implicit Euler, as the thesis's loop);
    ``dt`` s (a (K, 1) column of periods for K arms' (K, n) rows).

    Returns:
        (θ_ref, θ̇_ref) after the step.
    """
    qd = qd_ref + dt * qdd_ref
    return q_ref + dt * qd, qd


def lpf(y: ArrayT, x: ArrayT, alpha: float) -> ArrayT:
    """The thesis's digital low-pass filter (ch. 4, on eq. 2.21–2.23): y + α (x − y)
    (α a (K, 1) column for K arms' (K, n) rows).

    α = dt / (RC + dt); the thesis uses α = 0.05.
    """
    return y + alpha * (x - y)


def external_torque(tau_dist_filtered: ArrayT, tau_dyn: ArrayT) -> ArrayT:
    """Thesis eq. 2.23: τ_ext = LPF(τ_dist) − τ_dyn (friction neglected, eq. 2.22).

    Args:
        tau_dist_filtered: the servo load after the LPF, N·m.
        tau_dyn: the Newton–Euler torque of the motion (gravity included), N·m.
    """
    return tau_dist_filtered - tau_dyn


@dataclass(frozen=True)
class Laws:
    """The equations :meth:`ComplianceController.step` calls: the lab's own by default.

    Coursework (:mod:`armlab.exercises`) puts a student's function in place of one, to run
    it on the arm; each takes the arguments and returns what the lab's own function does
    (the compliance law: the registry of :mod:`armlab.control.laws` with the student's in
    eq. 2.6's place, :func:`~armlab.control.laws.with_student`).
    """

    # the loop's: (n,) arrays in, (n,) arrays out
    pd: Callable[..., np.ndarray] = pd_reference_accel  #: eq. 2.20
    #: eq. 2.6 / 2.26, by ``Params.law``
    compliance: Mapping[str, ComplianceLaw] = field(default_factory=lambda: LAWS)
    environment: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]] = (
        environment_step)  #: eq. 2.7

    @classmethod
    def with_student(cls, name: str, fn: Callable[..., Any]) -> Laws:
        """The lab's own equations with a student's function for the one ``name``d ("pd",
        "compliance": eq. 2.6's place in the law registry, "environment")."""
        if name == "compliance":
            return cls(compliance=with_student(fn))
        if name == "pd":
            return cls(pd=fn)
        if name == "environment":
            return cls(environment=fn)
        raise ValueError(f"no equation {name!r}: pd, compliance or environment")

    def law(self, params: Params | ParamColumns) -> ComplianceLaw:
        """The compliance law ``params`` picks (its ``law``), as this controller runs it."""
        return self.compliance[params.law]


@dataclass
class ControllerState:
    """What the controller remembers between periods (all (n,) arrays).

    Attributes:
        q_ref, qd_ref, qdd_ref: the integrated reference (rad, rad/s, rad/s²).
        q_env, qd_env, qdd_env: the environment offset of eq. 2.7.
        tau_lpf: the filtered servo load, N·m.
        tau_ext: the last external-torque estimate (eq. 2.23), N·m.
    """

    q_ref: np.ndarray
    qd_ref: np.ndarray
    qdd_ref: np.ndarray
    q_env: np.ndarray
    qd_env: np.ndarray
    qdd_env: np.ndarray
    tau_lpf: np.ndarray
    tau_ext: np.ndarray

    @classmethod
    def at_rest(cls, q: np.ndarray, load: np.ndarray | None = None) -> ControllerState:
        """A state holding position ``q`` (n,), with the LPF primed on ``load`` (n,)."""
        q = np.array(q, dtype=float)
        z = np.zeros_like(q)
        tau = z.copy() if load is None else np.array(load, dtype=float)
        return cls(q.copy(), z.copy(), z.copy(), z.copy(), z.copy(), z.copy(), tau, z.copy())


class ComplianceController:
    """PD reference loop (2.20) or compliance controller (2.6 / 2.26) for n joints.

    Args:
        lower, upper: (n,) joint limits, rad; the integrated reference is kept
            inside them (no wind-up against a limit).
        max_speed: (n,) or scalar, rad/s; |θ̇_ref| is kept below it.
        mode: "none" (send θ_cmd itself), "pd" (eq. 2.20) or "compliance".
        laws: the equations to run (default: the lab's own, :class:`Laws`).

    ``Params.feedforward`` adds θ̈_cmd to θ̈_ref (not in the thesis; off keeps eq. 2.3).
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, max_speed: np.ndarray | float,
                 *, mode: Mode = "compliance", laws: Laws | None = None) -> None:
        if mode not in MODES:
            raise ValueError(f"controller must be one of {', '.join(MODES)}, got {mode!r}")
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.max_speed = np.broadcast_to(np.asarray(max_speed, dtype=float),
                                         self.lower.shape).copy()
        self.mode: Mode = mode
        self.laws = Laws() if laws is None else laws

    def effective_mode(self, params: Params | ParamColumns) -> Mode:
        """The mode actually run: "compliance" with ``params.compliance`` off is "pd"."""
        if self.mode == "compliance" and not params.compliance:
            return "pd"
        return self.mode

    def step(self, params: Params | ParamColumns, state: ControllerState, q_cmd: np.ndarray,
             qd_cmd: np.ndarray, qdd_cmd: np.ndarray, measured: JointState,
             tau_dyn: np.ndarray, tau_world: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """Advance one period of ``params.period`` s; updates ``state`` in place.

        Args:
            q_cmd, qd_cmd, qdd_cmd: (n,) the commanded trajectory (e.g. from RMRC).
            measured: what the servos report (position, velocity, load).
            tau_dyn: (n,) Newton–Euler torque of the measured motion, N·m.
            tau_world: (n,) N·m a rendered wall adds to the external torque the
                environment answers (:mod:`armlab.control.virtual_wall`; None: none).

        Returns:
            (θ_ref, θ̇_ref), each (n,): the goal position and signed speed to send.

        K arms under this controller's limits step as one with ``params`` a
        :class:`~armlab.control.params.ParamColumns`, ``state`` and every array (K, n)
        (:mod:`armlab.control.law_batch`): each row gets the numbers its own step would.
        """
        # ParamColumns' α and T are (K, 1) columns: they broadcast over the (K, n) rows as
        # one arm's floats do over its (n,) arrays (lpf and integrate_reference take either)
        p, T = params, cast(float, params.period)
        state.tau_lpf = lpf(state.tau_lpf, measured.load, cast(float, p.alpha))
        state.tau_ext = external_torque(state.tau_lpf, tau_dyn)
        mode = self.effective_mode(p)
        if mode == "none":
            state.q_ref = np.array(q_cmd, dtype=float)
            state.qd_ref = np.array(qd_cmd, dtype=float)
            state.qdd_ref = np.array(qdd_cmd, dtype=float)
            state.q_env[:] = state.qd_env[:] = state.qdd_env[:] = 0.0
            return state.q_ref.copy(), state.qd_ref.copy()
        q, qd = measured.position, measured.velocity
        if mode == "pd":
            state.q_env[:] = state.qd_env[:] = state.qdd_env[:] = 0.0
            qdd = self.laws.pd(p.kp, p.kv, q_cmd, qd_cmd, q, qd)
        else:
            state.q_env, state.qd_env, state.qdd_env = self.laws.environment(
                p.m_env, p.d_env, p.k_env, p.k_f,
                state.tau_ext if tau_world is None else state.tau_ext + tau_world,
                state.q_env, state.qd_env, T)
            qdd = self.laws.law(p).accel(p, q_cmd, qd_cmd, q, qd, state.q_env, state.qd_env,
                                         state.qdd_env)
        if p.feedforward:
            qdd = qdd + qdd_cmd
        state.qdd_ref = np.asarray(qdd, dtype=float)
        q_ref, qd_ref = integrate_reference(state.q_ref, state.qd_ref, state.qdd_ref, T)
        qd_ref = clamp(qd_ref, -self.max_speed, self.max_speed)
        inside = clamp(q_ref, self.lower, self.upper)
        if any((inside != q_ref).ravel().tolist()):  # at a limit: no speed further out
            low, high = q_ref < self.lower, q_ref > self.upper
            qd_ref = np.where((low & (qd_ref < 0)) | (high & (qd_ref > 0)), 0.0, qd_ref)
        state.q_ref = inside
        state.qd_ref = qd_ref
        return state.q_ref.copy(), state.qd_ref.copy()
