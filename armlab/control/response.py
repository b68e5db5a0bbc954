"""Step and push responses: what the student ran, measured, and the ideal joint's (eq. 2.11–2.19).

Pure functions, most over a recorder snapshot
(:meth:`armlab.control.recorder.Recorder.snapshot`: ``"t"`` (N,) and (N, n) signals ``"q"``,
``"q_cmd"``, ``"q_env"``, ``"tau_ext"``, ``"error"``), so they run in a test or a script
without a server:

- :func:`plan_step`: the step of one joint's command a PD-loop test posts, and how long
  to wait before measuring it;
- :func:`measure_step`: the PD loop's response to that step (θ against θ_cmd);
- :func:`measure_push`: the environment's response to a push (θ_env against τ_ext);
- :func:`hand_excursion`: how far a push moved the hand, and how near it came back;
- :func:`line_errors`: the largest |θ_cmd − θ| of a run;
- :func:`simulate_ideal_joint_step`: the sampled PD loop's step on an ideal joint, and
  :func:`step_report`: formulas 2.11–2.19 against it (no recording needed).

The figures are :func:`armlab.control.metrics.measure_step`'s, with ωn and ζ read back from
the measured overshoot and peak time (the inverses of eq. 2.16–2.17).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from armlab.control import metrics
from armlab.control.compliance import integrate_reference, pd_reference_accel
from armlab.control.params import Params
from armlab.control.trajectory import JointTrajectory
from armlab.kinematics.model import SerialChain

MIN_STEP = math.radians(0.5)  #: rad; a smaller step is refused (the slider moves by 1°)


@dataclass(frozen=True)
class Measured:
    """Second-order figures measured on a recorded response (None where undefined).

    Attributes:
        what: what was measured ("step of θ2 by +10°", "push on θ0").
        omega_n: rad/s, from Tp and %OS (underdamped responses only).
        zeta: from %OS (underdamped only).
        overshoot_pct, peak_time_s, rise_time_s, settling_time_s: as in
            :class:`armlab.control.metrics.StepMetrics`.
        static_gain: final / input (C_f for a push: rad per N·m), or None.
        params: the gains it was measured with (None: not said); a figure measured with
            other gains than those in use is stale beside their design figures.
        band: the settling band's half-width, in the response's unit (2 % of the step:
            rad for a joint's step), or None.
    """

    what: str
    omega_n: float | None
    zeta: float | None
    overshoot_pct: float | None
    peak_time_s: float | None
    rise_time_s: float | None
    settling_time_s: float | None
    static_gain: float | None = None
    params: Params | None = None
    band: float | None = None


def measure_response(t: np.ndarray, y: np.ndarray, *, initial: float, final: float,
                     what: str, static_gain: float | None = None,
                     params: Params | None = None) -> Measured:
    """Figures of a recorded step response ``y`` (N,) at times ``t`` (N,) from the step.

    Raises:
        ValueError: when the step is too small to measure (|final − initial| ~ 0).
    """
    if not abs(final - initial) > 1e-9:
        raise ValueError(f"{what}: the response did not move (final = initial = {final:g})")
    m = metrics.measure_step(np.asarray(t) - t[0], y, final=final, initial=initial)
    z = metrics.zeta_from_overshoot(m.overshoot_pct)
    return Measured(what, metrics.omega_from_peak(m.peak_time_s, z), z, m.overshoot_pct,
                    m.peak_time_s, m.rise_time_s, m.settling_time_s, static_gain,
                    params=params, band=0.02 * abs(final - initial))


@dataclass(frozen=True)
class StepPlan:
    """A step of one joint's command (post ``RunTrajectory(trajectory, approach=False)``).

    Attributes:
        trajectory: hold the present command for one period, then the stepped one.
        joint: the stepped joint's index.
        q0, q1: its command before and after, rad.
        wait_s: measure this long after posting (covers the settling time).
    """

    trajectory: JointTrajectory
    joint: int
    q0: float
    q1: float
    wait_s: float


def last_finite(a: np.ndarray) -> np.ndarray | None:
    """The newest row of ``a`` (m, n) with no NaN, or None."""
    for k in range(len(a) - 1, -1, -1):
        if np.all(np.isfinite(a[k])):
            return a[k].copy()
    return None


def plan_step(snap: dict[str, np.ndarray], *, joint: int, step: float, lower: np.ndarray,
              upper: np.ndarray, params: Params, label: str) -> StepPlan:
    """Step joint ``joint``'s present command (the newest in ``snap``) by ``step`` rad.

    The step goes the other way when the joint limit [lower, upper] (rad) is too near.
    The wait is 1.5 × Ts of the PD loop, Ts = 4/(ζp ωp) = 8/Kv (eq. 2.18 with 2.11–2.12),
    kept within 3..12 s.

    Raises:
        ValueError: the loop records no command (not running), the step is under 0.5°,
            or there is no room for it between the limits (``label`` names the joint).
    """
    q_cmd = last_finite(snap["q_cmd"])
    if q_cmd is None:
        raise ValueError("the controller is not running: press Reset first")
    if abs(step) < MIN_STEP:
        raise ValueError("step: choose a step of at least 1°")
    j = joint
    q1 = q_cmd.copy()
    if not lower[j] <= q_cmd[j] + step <= upper[j]:
        step = -step  # too near a limit: the other way
    q1[j] = float(np.clip(q_cmd[j] + step, lower[j], upper[j]))
    if abs(q1[j] - q_cmd[j]) < 0.5 * abs(step):
        raise ValueError(f"{label}: no room for a {abs(math.degrees(step)):g}° step between "
                         "its limits")
    T = params.period
    z = np.zeros((2, len(q1)))
    traj = JointTrajectory(np.array([0.0, T]), np.vstack([q_cmd, q1]), z, z.copy(),
                           name=f"step {label}")
    settle = 4.0 / max(1e-3, params.kv / 2.0) if params.kv > 0 else 10.0
    wait = float(np.clip(1.5 * settle, 3.0, 12.0))
    return StepPlan(traj, j, float(q_cmd[j]), float(q1[j]), wait)


def measure_step(snap: dict[str, np.ndarray], *, t0: float, joint: int, q0: float, q1: float,
                 what: str, params: Params | None = None) -> Measured:
    """The PD loop's response to a step of joint ``joint``'s command from ``q0`` to ``q1``
    (rad) posted at loop time ``t0``: θ from the first period the command has stepped;
    measured with ``params`` (kept in the result).

    Raises:
        ValueError: the command never stepped in ``snap`` (e-stopped, faulted).
    """
    j = joint
    half = 0.5 * abs(q1 - q0)
    stepped = np.abs(snap["q_cmd"][:, j] - q0) > half
    moved = np.flatnonzero((snap["t"] >= t0) & stepped)
    if len(moved) == 0:
        raise ValueError("the command never stepped (was the arm e-stopped?)")
    k = moved[0]
    return measure_response(snap["t"][k:], snap["q"][k:, j], initial=q0, final=q1, what=what,
                            params=params)


def measure_push(snap: dict[str, np.ndarray], *, t0: float, t1: float, what: str,
                 joint_labels: Sequence[str], params: Params | None = None) -> Measured:
    """The environment filter's response (θ_env, eq. 2.7) to a push from ``t0`` to ``t1``
    (loop time, s), on the joint that felt the most torque at its end; measured with
    ``params`` (kept in the result).

    The final values are the medians of the push's last 15 %; the static gain is
    Δθ_env / Δτ_ext (C_f = K_f / K_env for law 2.6, eq. 2.15). ``what`` is followed by
    ``", joint "`` and that joint's entry of ``joint_labels``.

    Raises:
        ValueError: too few finite samples (compliance off), or no torque change.
    """
    keep = (snap["t"] >= t0) & (snap["t"] <= t1)
    t, env, tau = snap["t"][keep], snap["q_env"][keep], snap["tau_ext"][keep]
    if len(t) < 10 or not np.any(np.isfinite(env)):
        raise ValueError("too few samples during the push (compliance off?)")
    tail = slice(int(0.85 * len(t)), None)
    j = int(np.nanargmax(np.abs(np.nanmean(tau[tail], axis=0))))
    e0, tau0 = float(env[0, j]), float(tau[0, j])
    e1, tau1 = float(np.nanmedian(env[tail, j])), float(np.nanmedian(tau[tail, j]))
    if abs(tau1 - tau0) < 1e-4:
        raise ValueError("the push did not reach the estimated torque")
    return measure_response(t, env[:, j], initial=e0, final=e1,
                            what=f"{what}, joint {joint_labels[j]}",
                            static_gain=(e1 - e0) / (tau1 - tau0), params=params)


def hand_excursion(model: SerialChain, snap: dict[str, np.ndarray], *, t0: float
                   ) -> tuple[float, float]:
    """How far the hand of ``model`` went from where it was at loop time ``t0`` (a push's
    start): (the largest distance since then, the distance in the newest sample), m.

    Raises:
        ValueError: no finite sample at or after ``t0``.
    """
    keep = (snap["t"] >= t0) & np.all(np.isfinite(snap["q"]), axis=1)
    q = snap["q"][keep]
    if len(q) == 0:
        raise ValueError("no samples since the push began (the loop stopped?)")
    x = np.array([model.fk(qi)[:3, 3] for qi in q])
    d = np.linalg.norm(x - x[0], axis=1)
    return float(d.max()), float(d[-1])


def line_errors(snap: dict[str, np.ndarray], *, t0: float) -> np.ndarray:
    """(n,) largest |θ_cmd − θ| per joint since loop time ``t0``, rad (NaN rows skipped)."""
    keep = snap["t"] >= t0
    return np.nanmax(np.abs(snap["error"][keep]), axis=0)


def line_part(q_cmd: np.ndarray, start: np.ndarray, *, tol: float = 1e-6) -> int:
    """The index of the first row of ``q_cmd`` (N, n) rad at the line's first point
    ``start`` (n,) rad: where the line itself begins, after any approach to it (a line run
    again from its end pose first travels back). 0 when no row reaches it (nothing to
    cut). Two runs of one line, each from this index, are sample for sample the same
    command, so their θ can be compared (chapter 4's yield)."""
    at = np.flatnonzero(np.all(np.abs(q_cmd - start) <= tol, axis=1))
    return int(at[0]) if at.size else 0


def line_yield(q_pushed: np.ndarray, q_free: np.ndarray) -> np.ndarray:
    """(n,) chapter 4's yield under a push, rad: the largest |θ_pushed − θ_free| per joint
    over the samples both runs have, each (N, n) rad from its line's start
    (:func:`line_part`), so over the same push as the pushed run's error."""
    m = min(len(q_pushed), len(q_free))
    return np.nanmax(np.abs(q_pushed[:m] - q_free[:m]), axis=0)


def simulate_ideal_joint_step(kp: float, kv: float, *, period: float = 1e-3,
                              duration: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Step response of the sampled PD loop (eq. 2.20 integrated twice) on an ideal joint.

    The ideal acceleration-controlled joint follows its reference exactly, so the
    measured position is θ_ref itself. θ_cmd steps 0 -> 1 at t = 0 with θ̇_cmd = 0:
    the result is the pure second-order part Kp/(s² + Kv s + Kp), sampled.

    Returns:
        (t, θ) arrays of the same length, t from 0.
    """
    if duration is None:
        duration = metrics.step_duration(kp, kv)
    n = int(round(duration / period)) + 1
    y = np.empty(n)
    q = qd = 0.0
    for k in range(n):
        y[k] = q
        qdd = pd_reference_accel(kp, kv, 1.0, 0.0, q, qd)
        q, qd = integrate_reference(q, qd, qdd, period)
    return np.arange(n) * period, y


def step_report(kp: float, kv: float, *, period: float = 1e-3) -> dict[str, object]:
    """Formula (2.11–2.19) vs measured metrics of the ideal joint and of eq. 2.3.

    Returns:
        {"kp", "kv", "omega_n", "zeta", "formula", "measured", "measured_eq_2_3"}, the
        last three each {overshoot_pct, peak_time_s, rise_time_s, settling_time_s}.
    """
    if not (math.isfinite(kp) and kp > 0):
        raise ValueError(f"kp must be > 0, got {kp}")
    if not (math.isfinite(kv) and kv > 0):
        raise ValueError(f"kv must be > 0 (Kv = 0 never settles), got {kv}")
    wn, z = metrics.pd_natural_frequency(kp), metrics.pd_damping(kp, kv)
    duration = metrics.step_duration(kp, kv)
    t, y = simulate_ideal_joint_step(kp, kv, period=period, duration=duration)
    from scipy import signal

    t2, y2 = signal.step(metrics.pd_reference_model(kp, kv),
                         T=np.arange(0.0, duration, period / 2))
    return {
        "kp": kp, "kv": kv, "omega_n": wn, "zeta": z,
        "formula": metrics.formula_metrics(wn, z).as_dict(),
        "measured": metrics.measure_step(t, y).as_dict(),
        "measured_eq_2_3": metrics.measure_step(t2, y2).as_dict(),
    }
