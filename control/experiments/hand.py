"""``armlab experiment hand-grip``: the thesis's hand closes on an object with a force limit.

Thesis §2.4/§3.1.1: three fingers, each pulled by a 6 V DC gearmotor whose
current gives its torque (eq. 2.29). The grasp (:mod:`control.grip`) closes
until each finger holds the object with the force limit F, estimated from the
current alone. The figures show whether it does, for an object of any size
and stiffness: steady grip force (≈ F), peak force (never much above F), time
to grasp, final motor current.

The simulated hand comes from the CLI as the factory ``args.hand_plant``
(``hardware.hand.make_hand``): control/ never imports hardware/.
"""

from __future__ import annotations

import argparse
from typing import Any

from control.experiments import Experiment
from control.grip import GripController, GripModel, GripParams, grasp_figures, simulate_grasp
from kinematics.validate import scalar

CONTROL_PERIOD = 1.0e-3  #: s, the controller's period (the plant steps at 0.1 ms inside)


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", type=float, default=0.8, metavar="F",
                        help="grip force limit per finger, N (default 0.8)")
    parser.add_argument("--stiffness", type=float, default=1000.0, metavar="K",
                        help="object contact stiffness, N/m (default 1000; soft 200, hard 5000)")
    parser.add_argument("--size", type=float, default=6.0, metavar="S",
                        help="object diameter, cm (default 6)")
    parser.add_argument("--damping", type=float, default=1.0, metavar="D",
                        help="object contact damping, N·s/m (default 1)")
    parser.add_argument("--lpf", type=float, default=None, metavar="HZ",
                        help="current sensor low-pass cut-off, Hz (default: none)")
    parser.add_argument("--duration", type=float, default=3.0, metavar="T",
                        help="simulated time from the close command, s (default 3)")


def run_grip(args: argparse.Namespace) -> dict[str, Any]:
    """Close the simulated hand on the object; return the grasp's figures (SI, size in cm)."""
    force = scalar("force", args.force, positive=True)
    size_cm = scalar("size", args.size, positive=True)
    stiffness = scalar("stiffness", args.stiffness, positive=True)
    damping = scalar("damping", args.damping)
    duration = scalar("duration", args.duration, positive=True)
    lpf = None if args.lpf is None else scalar("lpf", args.lpf, positive=True)
    plant = args.hand_plant(
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
        add_arguments=_add_arguments,
        run=run_grip,
        needs=("hand_plant",),
    ),
)
