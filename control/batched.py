"""The compliance controller of N arms at once: :class:`ComplianceController`'s law over (N, n).

A classroom runs the same lesson on N private arms, each with its own gains. This
module is the controller half of that batch (the plant half and the glue that reads
and writes the servos live in ``hardware``, as control never touches hardware):
the equations of :mod:`control.compliance`, applied by the very same functions to
arrays of shape (N, n) (arm, joint) with every gain a column (N, 1):

    τ_lpf  = LPF(τ_dist)                          (ch. 4 LPF)
    τ_ext  = τ_lpf − τ_dyn                        (eq. 2.23)
    θ_env  <- M θ̈ + D θ̇ + K θ = K_f τ_ext         (eq. 2.7, semi-implicit Euler)
    θ̈_ref  = law 2.6 / 2.26 (compliance) or 2.20 (PD), per arm
    θ̇_ref += T θ̈_ref ; θ_ref += T θ̇_ref           (then speed and joint limits)

:meth:`BatchedController.step` equals :meth:`ComplianceController.step` of each arm
(tests/test_batched_plant.py checks it to 1e-9; the operations are the same, so the
results are bit for bit equal). Not batched: mode "none" (send θ_cmd itself).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from control.compliance import (
    ControllerState,
    compliance_accel,
    compliance_accel_literal,
    environment_step,
    external_torque,
    integrate_reference,
    lpf,
    pd_reference_accel,
)
from control.params import Params
from kinematics.batched_dynamics import batched_dynamics
from kinematics.model import SerialChain


@dataclass(frozen=True)
class BatchedGains:
    """Every arm's :class:`Params` as columns (N, 1) (floats) or (N, 1) bools.

    Attributes:
        kp, kv, m_env, d_env, k_env, k_f, alpha: the gains (units as in Params).
        compliance: the environment term on (eq. 2.6/2.26) or off (PD, eq. 2.20).
        literal: law "2.26" (thesis-literal) instead of "2.6".
        feedforward: θ̈_cmd added to θ̈_ref.
        period: the control period T, s, one for the whole batch.
    """

    kp: np.ndarray
    kv: np.ndarray
    m_env: np.ndarray
    d_env: np.ndarray
    k_env: np.ndarray
    k_f: np.ndarray
    alpha: np.ndarray
    compliance: np.ndarray
    literal: np.ndarray
    feedforward: np.ndarray
    period: float

    @classmethod
    def of(cls, params: Sequence[Params]) -> BatchedGains:
        """The gains of ``params`` (one :class:`Params` per arm, all with one period).

        Raises:
            ValueError: naming ``params`` when one is not a Params or the periods differ.
        """
        plist = list(params)
        if not all(isinstance(p, Params) for p in plist):
            raise ValueError("params must be control.params.Params, one per arm")
        periods = {p.period for p in plist}
        if len(periods) > 1:
            raise ValueError(f"params must share one period, got {sorted(periods)}")

        def column(name: str, dtype: type = float) -> np.ndarray:
            return np.array([getattr(p, name) for p in plist], dtype=dtype).reshape(-1, 1)

        return cls(
            **{f.name: column(f.name) for f in fields(cls)
               if f.name in ("kp", "kv", "m_env", "d_env", "k_env", "k_f", "alpha")},
            compliance=column("compliance", bool),
            literal=np.array([p.law == "2.26" for p in plist]).reshape(-1, 1),
            feedforward=column("feedforward", bool),
            period=periods.pop() if periods else Params().period,
        )


@dataclass
class BatchedState:
    """:class:`ControllerState` of N arms: every attribute (N, n)."""

    q_ref: np.ndarray
    qd_ref: np.ndarray
    qdd_ref: np.ndarray
    q_env: np.ndarray
    qd_env: np.ndarray
    qdd_env: np.ndarray
    tau_lpf: np.ndarray
    tau_ext: np.ndarray

    @classmethod
    def at_rest(cls, q: np.ndarray, load: np.ndarray | None = None) -> BatchedState:
        """Holding ``q`` (N, n), the LPF primed on ``load`` (N, n) (ControllerState.at_rest)."""
        q = np.array(q, dtype=float)
        z = np.zeros_like(q)
        tau = z.copy() if load is None else np.array(load, dtype=float)
        return cls(q.copy(), z.copy(), z.copy(), z.copy(), z.copy(), z.copy(), tau, z.copy())

    def arm(self, row: int) -> ControllerState:
        """Row ``row`` as a single arm's :class:`ControllerState` (copies)."""
        return ControllerState(**{f.name: getattr(self, f.name)[row].copy()
                                  for f in fields(self)})

    def put(self, rows: np.ndarray, other: BatchedState) -> None:
        """Rows ``rows`` := ``other``'s rows (a Reset of some arms)."""
        for f in fields(self):
            getattr(self, f.name)[rows] = getattr(other, f.name)

    def append(self, other: BatchedState) -> BatchedState:
        """Both batches' arms, ``other``'s after these."""
        return BatchedState(**{f.name: np.concatenate([getattr(self, f.name),
                                                       getattr(other, f.name)])
                               for f in fields(self)})

    def delete(self, row: int) -> BatchedState:
        """Without row ``row``."""
        return BatchedState(**{f.name: np.delete(getattr(self, f.name), row, axis=0)
                               for f in fields(self)})


class BatchedController:
    """The compliance/PD controller of N arms of one model (ComplianceController over rows).

    Args:
        lower, upper: (n,) joint limits, rad (the reference is kept inside them).
        max_speed: (n,) or scalar, rad/s; |θ̇_ref| is kept below it.
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray,
                 max_speed: np.ndarray | float) -> None:
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.max_speed = np.broadcast_to(np.asarray(max_speed, dtype=float),
                                         self.lower.shape).copy()

    def step(self, gains: BatchedGains, state: BatchedState, q_cmd: np.ndarray,
             qd_cmd: np.ndarray, qdd_cmd: np.ndarray, position: np.ndarray,
             velocity: np.ndarray, load: np.ndarray,
             tau_dyn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One period T of every arm; updates ``state`` in place.

        Args:
            q_cmd, qd_cmd, qdd_cmd: (N, n) commanded trajectory.
            position, velocity, load: (N, n) what the servos report (rad, rad/s, N·m).
            tau_dyn: (N, n) Newton–Euler torque of the measured motion, N·m.

        Returns:
            (θ_ref, θ̇_ref), each (N, n).
        """
        g, T = gains, gains.period
        state.tau_lpf = lpf(state.tau_lpf, load, g.alpha)
        state.tau_ext = external_torque(state.tau_lpf, tau_dyn)
        q, qd = position, velocity
        q_env, qd_env, qdd_env = environment_step(g.m_env, g.d_env, g.k_env, g.k_f,
                                                  state.tau_ext, state.q_env, state.qd_env, T)
        on = g.compliance
        state.q_env = np.where(on, q_env, 0.0)
        state.qd_env = np.where(on, qd_env, 0.0)
        state.qdd_env = np.where(on, qdd_env, 0.0)
        consistent = compliance_accel(g.kp, g.kv, q_cmd, qd_cmd, q, qd, state.q_env,
                                      state.qd_env, state.qdd_env)
        qdd = np.where(on, consistent, pd_reference_accel(g.kp, g.kv, q_cmd, qd_cmd, q, qd))
        if g.literal.any():
            literal = compliance_accel_literal(g.kp, g.kv, g.m_env, g.d_env, g.k_env, q_cmd,
                                               qd_cmd, q, qd, state.q_env, state.qd_env,
                                               state.qdd_env)
            qdd = np.where(on & g.literal, literal, qdd)
        qdd = np.where(g.feedforward, qdd + qdd_cmd, qdd)
        state.qdd_ref = np.asarray(qdd, dtype=float)
        q_ref, qd_ref = integrate_reference(state.q_ref, state.qd_ref, state.qdd_ref, T)
        qd_ref = np.clip(qd_ref, -self.max_speed, self.max_speed)
        low, high = q_ref < self.lower, q_ref > self.upper
        qd_ref = np.where((low & (qd_ref < 0)) | (high & (qd_ref > 0)), 0.0, qd_ref)
        state.q_ref = np.clip(q_ref, self.lower, self.upper)
        state.qd_ref = qd_ref
        return state.q_ref.copy(), state.qd_ref.copy()


def newton_euler_torques(model: SerialChain, q: np.ndarray, qd: np.ndarray,
                         qdd: np.ndarray) -> np.ndarray:
    """τ_dyn (N, n) = RNEA (thesis eq. 2.41–2.50) of every arm's (N, n) q, qd, qdd, the
    model's gravity: :func:`kinematics.dynamics.rnea` per row, in one pass."""
    g = [float(x) for x in model.gravity]

    def rows(x: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(np.asarray(x, dtype=float).T)

    return batched_dynamics(model).rnea(rows(q), rows(qd), rows(qdd), g).T
