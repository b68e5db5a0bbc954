"""``armlab experiment hand-grip``: the thesis's hand closes on an object with a force limit.

Thesis §2.4/§3.1.1: three fingers, each pulled by a 6 V DC gearmotor whose
current gives its torque (eq. 2.29). The grasp (:mod:`armlab.control.grip`) closes
until each finger holds the object with the force limit F, estimated from the
current alone. The figures show whether it does, for an object of any size
and stiffness: steady grip force (≈ F), peak force (never much above F), time
to grasp, final motor current.

The simulated hand comes from the CLI as the factory ``hand_plant``
(``armlab.hardware.sim.hand_plant.make_hand``): armlab/control/ never imports hardware/.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.control.experiments import Experiment, Keep, option
from armlab.control.grip import (
    N_FINGERS,
    GripController,
    GripModel,
    GripParams,
    grasp_figures,
    simulate_grasp,
)
from armlab.control.grip_loop import COLUMNS
from armlab.control.runs import Run, lab_version, utc_now
from armlab.kinematics.validate import scalar

CONTROL_PERIOD = 1.0e-3  #: s, the controller's period (the plant steps at 0.1 ms inside)


@dataclass(frozen=True)
class GripOptions:
    """Options of ``hand-grip`` (checked by :func:`run_grip`)."""

    force: float = option(0.8, "grip force limit per finger, N (default 0.8)", metavar="F")
    stiffness: float = option(1000.0, "object contact stiffness, N/m (default 1000; soft 200, "
                              "hard 5000)", metavar="K")
    size: float = option(6.0, "object diameter, cm (default 6)", metavar="S")
    damping: float = option(1.0, "object contact damping, N·s/m (default 1)", metavar="D")
    lpf: float | None = option(None, "current sensor low-pass cut-off, Hz (default: none)",
                               metavar="HZ")
    duration: float = option(3.0, "simulated time from the close command, s (default 3)",
                             metavar="T")


def run_grip(options: GripOptions, *, hand_plant: Callable[..., Any],
             keep: Keep | None = None) -> dict[str, Any]:
    """Close the simulated hand (``hand_plant(size=, stiffness=, damping=, current_lpf_hz=)``)
    on the object; return the grasp's figures (SI, size in cm).

    ``keep`` is handed the grasp at every control period: the finger angles as "q"; the
    voltages (V), currents (A), true and estimated fingertip forces (N) of each finger
    as the hand's own signals "voltage", "current", "force", "estimate" (the hand
    lesson's names, :data:`armlab.control.grip_loop.COLUMNS`).

    Raises:
        ValueError: naming the option that is out of range.
    """
    force = scalar("force", options.force, positive=True)
    size_cm = scalar("size", options.size, positive=True)
    stiffness = scalar("stiffness", options.stiffness, positive=True)
    damping = scalar("damping", options.damping)
    duration = scalar("duration", options.duration, positive=True)
    lpf = None if options.lpf is None else scalar("lpf", options.lpf, positive=True)
    plant = hand_plant(
        size=size_cm / 100.0, stiffness=stiffness, damping=damping, current_lpf_hz=lpf
    )
    model = GripModel.of(plant)
    if force > model.max_force():
        raise ValueError(
            f"force must be <= {model.max_force():.2f} N (what the 6 V motors can hold), "
            f"got {force:g}"
        )
    controller = GripController(model, GripParams(force_limit=force), dt=CONTROL_PERIOD)
    trace = simulate_grasp(plant, controller, duration=duration)
    figures = grasp_figures(trace, force)
    if keep is not None:
        keep(Run(robot="hand", joint_names=tuple(f"finger{i + 1}" for i in range(N_FINGERS)),
                 source="experiment:hand-grip", lab_version=lab_version(), created=utc_now(),
                 params={"force_limit_N": force, "stiffness_N_per_m": stiffness,
                         "size_cm": size_cm, "damping_N_s_per_m": damping,
                         "current_lpf_hz": "none" if lpf is None else lpf,
                         "period": CONTROL_PERIOD},
                 commands=({"t": 0.0, "kind": "Close", "force_limit_N": force},),
                 figures={}, t=trace.t,
                 signals={"q": np.asarray(trace.angle), "voltage": trace.voltage,
                          "current": trace.current, "force": trace.force,
                          "estimate": trace.estimate},
                 lesson_signals={k: COLUMNS[k] for k in ("voltage", "current", "force",
                                                         "estimate")}))
    return {
        "force_limit_N": force,
        "stiffness_N_per_m": stiffness,
        "size_cm": size_cm,
        **figures,
        "modes": list(controller.modes),
    }


EXPERIMENTS = (
    Experiment(
        name="hand-grip",
        help="the thesis's 3-finger hand closes on an object with a grip-force limit "
             "(steady and peak force, time to grasp, final current)",
        options=GripOptions,
        run=run_grip,
        needs=("hand_plant",),
    ),
)
