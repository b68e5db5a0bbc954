"""``armlab experiment observers``: disturbance and reaction-torque observers (thesis §2.1.1).

A torque-driven joint (J θ̈ = K_t I − τ_l, thesis eq. 2.27–2.29) holds a position
under a PD current loop; at ``--at`` s an external torque step ``--step`` N·m hits
it. The disturbance observer (eq. 2.36) and the reaction-torque observer
(eq. 2.37) estimate it from the current and the speed alone. Prints how closely
each follows the truth (the total disturbance τ_dis, which also holds gravity and
friction, for the DOB; τ_ext for the RTOB), how fast the RTOB picks up the step
(its 63 % time should be about 1/g_reac), and, with
the estimate fed back (thesis fig. 2.9), how much less the joint gives way.
RX-24F servos take no current command, so this is a simulation lesson only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from control.experiments import Experiment, option
from control.observers import ObserverRun, TorqueJoint, simulate_observers
from kinematics.validate import scalar

DECIMATE = 20  #: CSV rows: every 20th sample (2 ms at the 0.1 ms step)


def _rise_time(t: np.ndarray, est: np.ndarray, true: np.ndarray, at: float) -> float:
    """Seconds after ``at`` until ``est`` has covered 63 % of the jump ``true`` makes there
    (inf if never)."""
    k = int(np.searchsorted(t, at))
    base, jump = true[k - 1], true[k + 1] - true[k - 1]
    reached = np.nonzero((t >= at) & (np.sign(jump) * (est - base) >= 0.632 * abs(jump)))[0]
    return float(t[reached[0]] - at) if reached.size else float("inf")


def _summary(run: ObserverRun, at: float, settle: float) -> dict[str, float]:
    late = run.t >= at + settle
    return {
        "dob_error_max_nm": float(np.max(np.abs(run.tau_dis_hat - run.tau_dis)[late])),
        "rtob_error_max_nm": float(np.max(np.abs(run.tau_ext_hat - run.tau_ext)[late])),
        "rtob_rise_s": _rise_time(run.t, run.tau_ext_hat, run.tau_ext, at),
        "final_offset_rad": float(abs(run.q[-1] - run.q[np.searchsorted(run.t, at) - 1])),
    }


def observers(*, step: float = 0.004, at: float = 0.5, duration: float = 1.5,
              g_dis: float = 200.0, g_reac: float = 200.0,
              model_error: float = 0.0) -> tuple[dict[str, Any], ObserverRun]:
    """Run the joint without and with disturbance compensation; summarise both.

    Args:
        step: external torque step, N·m.
        at: time of the step, s.
        g_dis, g_reac: observer cut-offs, rad/s.
        model_error: relative error of the nominal inertia J_n (0.2 = 20 % too large).

    Returns:
        (figures, the uncompensated run's time series).
    """
    for name, value in (("g_dis", g_dis), ("g_reac", g_reac), ("duration", duration)):
        scalar(name, value, positive=True)
    scalar("step", step)
    if not 0.0 <= at < duration:
        raise ValueError(f"at must be within [0, duration), got {at}")
    if not -0.9 < scalar("model_error", model_error) < 10.0:
        raise ValueError(f"model_error must be in (-0.9, 10), got {model_error}")
    joint = TorqueJoint()
    j_n = joint.inertia * (1.0 + model_error)

    def tau_ext(t: float) -> float:
        return step if t >= at else 0.0

    settle = 5.0 / min(g_dis, g_reac)
    runs = {
        comp: simulate_observers(joint, tau_ext, duration=duration, j_n=j_n, g_dis=g_dis,
                                 g_reac=g_reac, compensate=comp)
        for comp in (False, True)
    }
    free, held = (_summary(runs[c], at, settle) for c in (False, True))
    figures = {
        "step_nm": step, "g_dis": g_dis, "g_reac": g_reac, "model_error": model_error,
        "expected_rise_s": 1.0 / g_reac,
        **free,
        "offset_compensated_rad": held["final_offset_rad"],
    }
    return figures, runs[False]


@dataclass(frozen=True)
class ObserverOptions:
    """Options of ``observers`` (see :func:`observers`)."""

    step: float = option(0.004, "external torque step, N·m")
    at: float = option(0.5, "time of the step, s")
    g_dis: float = option(200.0, "DOB cut-off, rad/s")
    g_reac: float = option(200.0, "RTOB cut-off, rad/s")
    model_error: float = option(0.0, "relative error of the nominal inertia J_n "
                                "(0.2 = 20 %% too large)")


def _run(options: ObserverOptions) -> dict[str, Any]:
    o = options
    figures, run = observers(step=o.step, at=o.at, g_dis=o.g_dis, g_reac=o.g_reac,
                             model_error=o.model_error)
    sl = slice(None, None, DECIMATE)
    figures["series"] = {k: getattr(run, k)[sl].tolist()
                         for k in ("t", "tau_dis", "tau_dis_hat", "tau_ext", "tau_ext_hat")}
    return figures


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    s = result["series"]
    return [dict(zip(s, vals, strict=True)) for vals in zip(*s.values(), strict=True)]


EXPERIMENTS = (
    Experiment("observers", "disturbance and reaction-torque observers on a torque-driven "
               "joint (thesis eq. 2.36, 2.37)", ObserverOptions, _run, _rows),
)
