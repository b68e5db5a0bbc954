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

from armlab.control.experiments import Experiment, Keep, option
from armlab.control.runs import Run, lab_version, utc_now
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.redundancy import (
    MODES,
    CircleRun,
    CircleTask,
    limit_violation,
    simulate_circle,
)

#: Tracking error is measured after this time, s (the start-up transient is excluded).
SETTLE_S = 0.2


def circle(mode: str, *, gain: float = 400.0, k_a: float = 200.0,
           keep: Keep | None = None) -> dict[str, Any]:
    """Run one seed 002 simulation and summarise it (see the module docstring); ``keep`` is
    handed the run (:func:`circle_record`)."""
    model = load_robot("redundant_planar")
    task = CircleTask(gain=gain, k_a=k_a)
    run = simulate_circle(model, mode, task)
    if keep is not None:
        keep(circle_record(model, run, task))
    return summarise(model, run)


def circle_record(model: SerialChain, run: CircleRun, task: CircleTask) -> Run:
    """The simulation as a run file's :class:`Run`: θ at every Δt as "q"; the hand's
    position x, the circle x_d (m) and the manipulability w in ``extra["series"]``."""
    return Run(robot=model.name, joint_names=model.joint_names, source="experiment:seed002",
               lab_version=lab_version(), created=utc_now(),
               params={"mode": run.mode, "gain": task.gain, "k_a": task.k_a, "dt": task.dt},
               commands=({"t": float(run.t[0]), "kind": "Circle", "mode": run.mode,
                          "duration_s": task.duration},),
               figures={}, t=run.t, signals={"q": run.q},
               extra={"series": {"x_m": run.x.tolist(), "x_d_m": run.x_d.tolist(),
                                 "w": run.w.tolist()}})


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


def _run(options: CircleOptions, *, keep: Keep | None = None) -> dict[str, Any]:
    return circle(options.mode, gain=options.gain, k_a=options.k_a, keep=keep)


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
