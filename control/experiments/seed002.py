"""``armlab experiment seed002-circle``: the redundant planar arm tracks the paper's circle.

Seed 002 §5: x_d(t) = (0.25(1 − cos πt), 0.25(2 + sin πt)) m for 2 s, Δt = 4 ms,
K = diag(400, 400), k_a = 200, θ(0) = [π, −π/2, −π/2]. ``--mode`` picks one of the
paper's four simulations (1: J⁺ only; 2: + joint limits by the decomposition method;
3: + manipulability gradient; 4: both) or ``bounded`` (limits guaranteed by bounded
least squares). Prints the tracking error after the first 0.2 s, each joint's worst
excursion beyond its limits, and the mean and minimum manipulability.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.control.experiments import Experiment, option
from armlab.kinematics.model import SerialChain, load_robot
from armlab.kinematics.redundancy import (
    MODES,
    CircleRun,
    CircleTask,
    limit_violation,
    simulate_circle,
)

#: Tracking error is measured after this time, s (the start-up transient is excluded).
SETTLE_S = 0.2


def circle(mode: str, *, gain: float = 400.0, k_a: float = 200.0) -> dict[str, Any]:
    """Run one seed 002 simulation and summarise it (see the module docstring)."""
    model = load_robot("redundant_planar")
    return summarise(model, simulate_circle(model, mode, CircleTask(gain=gain, k_a=k_a)))


def summarise(model: SerialChain, run: CircleRun) -> dict[str, Any]:
    """The figures of one run (what ``circle`` prints; the redundancy lesson shows them)."""
    mode = run.mode
    after = run.t >= SETTLE_S - 1e-9
    qdot = np.diff(run.q, axis=0) / np.diff(run.t)[:, None]
    return {
        "mode": int(mode) if mode.isdigit() else mode,
        "max_error_m": float(run.error()[after].max()),
        "max_violation_rad": limit_violation(run.q, model.lower, model.upper).tolist(),
        "mean_manipulability": float(run.w.mean()),
        "min_manipulability": float(run.w.min()),
        "max_joint_speed_rad_s": float(np.abs(qdot).max()),
        "description": MODES[mode],
    }


@dataclass(frozen=True)
class CircleOptions:
    """Options of ``seed002-circle`` (see :func:`circle`)."""

    mode: str = option("4", "simulation: " + "; ".join(f"{k}: {v}" for k, v in MODES.items()),
                       choices=tuple(MODES))
    gain: float = option(400.0, "task-space gain K of x' = x'_d + K (x_d - x), 1/s (paper: 400)")
    k_a: float = option(200.0, "manipulability gradient gain k_a (paper: 200)")


def _run(options: CircleOptions) -> dict[str, Any]:
    return circle(options.mode, gain=options.gain, k_a=options.k_a)


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    v = result["max_violation_rad"]
    return [{
        "mode": result["mode"],
        "max_error_m": result["max_error_m"],
        "viol_j1_rad": v[0], "viol_j2_rad": v[1], "viol_j3_rad": v[2],
        "mean_w": result["mean_manipulability"],
        "min_w": result["min_manipulability"],
        "max_qdot_rad_s": result["max_joint_speed_rad_s"],
    }]


EXPERIMENTS = (
    Experiment(
        name="seed002-circle",
        help="seed 002: redundant 3R arm on a circle, joint limits and manipulability",
        options=CircleOptions,
        run=_run,
        rows=_rows,
    ),
)
