"""``armlab experiment contact-sweep``: where contact chatters, wall stiffness against the
control period.

The run of ``armlab experiment contact`` (:func:`~armlab.control.experiments.contact.
run_contact`: the hand along the thesis line into a wall, the command behind it, held
there) is repeated on a grid: every wall stiffness of ``--stiffness`` (N/m) at every
control period of ``--periods-ms``. A stiffer wall turns the same penetration into more
force, and a longer period leaves the law longer on old numbers before it answers, so
past some stiffness-period product the hand no longer comes to rest on the wall: it
keeps losing it and striking it again (it chatters), or presses until the lab's lag
check stops the arm.

Each cell says, of the last second of the hold (:data:`~armlab.control.experiments.
contact.STEADY_S`): whether the hand rested on the wall all through it (``rests``), how
often it lost the wall there (``losses``: the force fell below
:data:`~armlab.control.experiments.contact.TOUCH_N` and rose again), the force's ripple
(its 95th minus 5th percentile, N), and beside them the run's peak and steady force and
bounces. A cell **chatters** when the hand did not rest on the wall through that last
second, or the arm was stopped; for each stiffness the sweep names the longest period
that did not chatter.

What the simulated receptionist arm shows (docs/compliance.md, "Where contact
chatters"): at the thesis's load filter (α 0.05, a 0.3 s lag in the force loop) its hand
chatters at nearly every stiffness and period; with a fast filter (``--alpha 0.6``) it
rests on every wall up to 2·10⁵ N/m at every period from 4 to 50 ms, and chatters on a
10⁶ N/m one at all of them. The boundary is the wall's stiffness against the servos' own
position loop (the firmware's, every millisecond), which holds the contact: the law's
period only sets how soon its admittance answers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from armlab.control.experiments import BackendOptions, Experiment, Keep, option
from armlab.control.experiments.contact import (
    STEADY_S,
    TOUCH_N,
    check_wall_numbers,
    run_contact,
)
from armlab.control.params import DEFAULT, PARAM_SPECS, Params
from armlab.control.runs import Run
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain

#: the sweep's size at most (each cell is a 5 s simulated run)
MAX_CELLS = 48


def numbers(text: str, *, name: str, unit: str) -> tuple[float, ...]:
    """``"2e3,2e4"`` -> (2000.0, 20000.0); ValueError naming ``name`` for anything else
    (empty, not a number, not finite, repeated)."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise ValueError(f"{name}: comma-separated numbers in {unit}, e.g. 2e3,2e4; "
                         f"got {text[:40]!r}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{name}: finite numbers in {unit}, got {text[:40]!r}")
    if len(set(values)) != len(values):
        raise ValueError(f"{name}: each value once, got {text[:40]!r}")
    return values


def chatter_figures(t: np.ndarray, force: np.ndarray) -> dict[str, Any]:
    """The last :data:`STEADY_S` s of a contact run's force ``force`` (N) at loop times
    ``t`` (s): ``rests`` (the hand touched the wall at every period of it), ``losses``
    (times it lost the wall and struck it again) and ``ripple_n`` (95th − 5th percentile
    of the force, N)."""
    force = np.nan_to_num(np.asarray(force, dtype=float))
    last = np.asarray(t, dtype=float) >= float(t[-1]) - STEADY_S
    window = force[last]
    touching = window > TOUCH_N
    losses = int(np.count_nonzero(np.diff(touching.astype(int)) == 1))
    ripple = float(np.percentile(window, 95) - np.percentile(window, 5))
    return {"rests": bool(touching.all()), "losses": losses, "ripple_n": ripple}


def sweep_cell(model: SerialChain, backend_factory: Any, params: Params, *, controller: str,
               wall: float, depth: float, stiffness: float, damping: float,
               keep: Keep | None = None) -> dict[str, Any]:
    """One cell: the contact run at ``params.period`` against a wall of ``stiffness``
    (its run handed to ``keep`` too)."""
    kept: list[Run] = []
    figures = run_contact(model, backend_factory, params, controller=controller, wall=wall,
                          depth=depth, stiffness=stiffness, damping=damping,
                          keep=kept.append)
    run = kept[-1]
    if keep is not None:
        keep(run)
    chatter = chatter_figures(np.asarray(run.t), run.signals["f_contact"][:, 0])
    stopped = figures.get("fault") is not None
    return {"stiffness_n_per_m": stiffness, "period_ms": params.period * 1e3,
            "peak_force_n": figures["peak_force_n"],
            "steady_force_n": figures["steady_force_n"],
            "bounces": figures["bounces"], **chatter, "stopped": stopped,
            "chatters": stopped or not chatter["rests"]}


@dataclass(frozen=True)
class SweepOptions(BackendOptions):
    """Options of ``contact-sweep``."""

    controller: Literal["pd", "compliance"] = option(
        "compliance", "the law that drives the hand into the wall")
    stiffness: str = option("2e3,2e4,2e5", "wall stiffnesses to try, N/m, comma-separated",
                            metavar="N_PER_M,...")
    periods_ms: str = option("4,16,32", "control periods to try, ms, comma-separated "
                             "(the thesis's: 16)", metavar="MS,...")
    damping: float = option(50.0, "N·s/m of the wall's damping while in contact")
    wall_cm: float = option(4.0, "cm from the hand to the wall along the thesis line")
    depth_cm: float = option(2.0, "cm behind the wall's surface the command ends")
    k_env: float | None = option(None, "K_env, N·m/rad (default: the lab's)")
    alpha: float | None = option(None, "α of the LPF on the servo load (default: the "
                                 "thesis's 0.05, whose lag makes the hand limit-cycle)")


def run_sweep(options: SweepOptions, *, backend_factory: Any,
              keep: Keep | None = None) -> dict[str, Any]:
    """The grid (see the module's docstring): its cells (``rows``), stiffness by stiffness
    and period by period, and per stiffness ``[N/m, the longest period that did not
    chatter, ms]`` (None: every period did). Each cell's run goes to ``keep``
    (``--save-run`` saves the last)."""
    o = options
    stiffnesses = numbers(o.stiffness, name="--stiffness", unit="N/m")
    periods = numbers(o.periods_ms, name="--periods-ms", unit="ms")
    if len(stiffnesses) * len(periods) > MAX_CELLS:
        raise ValueError(f"--stiffness × --periods-ms: at most {MAX_CELLS} runs, got "
                         f"{len(stiffnesses)} × {len(periods)}")
    for k in stiffnesses:
        check_wall_numbers(stiffness=k, damping=o.damping,
                           names=("--stiffness", "--damping"))
    spec = PARAM_SPECS["period"]
    for ms in periods:
        if not spec.min <= ms / 1e3 <= spec.max:
            raise ValueError(f"--periods-ms must be in {spec.min * 1e3:g}..{spec.max * 1e3:g}, "
                             f"got {ms:g}")
    model = load_robot("receptionist_arm")
    base = DEFAULT
    if o.k_env is not None:
        base = replace(base, k_env=o.k_env)
    if o.alpha is not None:
        base = replace(base, alpha=o.alpha)
    cells = [sweep_cell(model, backend_factory, replace(base, period=ms / 1e3),
                        controller=o.controller, wall=o.wall_cm / 100.0,
                        depth=o.depth_cm / 100.0, stiffness=k, damping=o.damping, keep=keep)
             for k in stiffnesses for ms in sorted(periods)]
    calm = []
    for k in stiffnesses:
        fine = [c["period_ms"] for c in cells if c["stiffness_n_per_m"] == k
                and not c["chatters"]]
        calm.append([k, max(fine) if fine else None])
    return {"controller": o.controller, "rows": cells,
            "longest_calm_period_ms": calm}


def _sweep_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    return list(result["rows"])


EXPERIMENTS = (
    Experiment("contact-sweep", "where contact chatters: the run into a wall at each "
               "wall stiffness and control period, and the longest calm period of each",
               SweepOptions, run_sweep, _sweep_rows, needs=("backend_factory",)),
)
