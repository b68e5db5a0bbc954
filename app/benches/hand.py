"""The hand's simulation and grasp controller: what one millisecond of the lesson costs.

Figures (median microseconds per call):
    hand_plant_1ms_us: ``HandSim.step`` over one 1 ms control period (ten 0.1 ms plant
        steps of three motor + tendon + finger units) while holding an object.
    grip_update_us: one ``GripController.update`` (three fingers) while holding.
    hand_grasp_2s_ms: a whole 2 s simulated grasp (``simulate_grasp``), milliseconds;
        under 2000 means the lesson can run in real time.
"""

from __future__ import annotations

import time

import numpy as np

from app.benches import median_us
from control.grip import GripController, GripModel, GripParams, simulate_grasp
from hardware.hand import make_hand


def _holding() -> tuple:
    plant = make_hand(size=0.06, stiffness=1000.0)
    controller = GripController(GripModel.of(plant), GripParams(force_limit=0.8))
    simulate_grasp(plant, controller, duration=1.5)
    return plant, controller


def run(quick: bool) -> dict[str, float]:
    repeat = 200 if quick else 2000
    plant, controller = _holding()
    volts = controller.update(plant.measured_current)
    step_us = median_us(lambda: plant.step(volts, 1e-3), repeat=repeat)
    current = plant.measured_current
    update_us = median_us(lambda: controller.update(current), repeat=repeat)
    runs = []
    for _ in range(1 if quick else 3):
        plant = make_hand(size=0.06, stiffness=1000.0)
        controller = GripController(GripModel.of(plant), GripParams(force_limit=0.8))
        t0 = time.perf_counter()
        simulate_grasp(plant, controller, duration=2.0)
        runs.append((time.perf_counter() - t0) * 1000.0)
    return {"hand_plant_1ms_us": step_us, "grip_update_us": update_us,
            "hand_grasp_2s_ms": float(np.median(runs))}
