"""The hand's simulation and grasp controller: what one millisecond of the lesson costs.

Figures (median microseconds per call):
    hand_plant_1ms_us: ``HandSim.step`` over one 1 ms control period (ten 0.1 ms plant
        steps of three motor + tendon + finger units) while holding an object.
    grip_update_us: one ``GripController.update`` (three fingers) while holding.
    hand_grasp_2s_ms: a whole 2 s simulated grasp (``simulate_grasp``), milliseconds;
        under 2000 means the lesson can run in real time.
    hands_period_us_n1 / _n30 / _n100: one 1 ms period of a class of N hands, all holding
        (``BatchedGrip.update`` and ``BatchedHand.step``: what the classroom's private
        hands cost per period, :mod:`armlab.app.workers.class_hands`).
    hands_realtime_per_core: hands one core keeps at 1 kHz that way (N = 100).
    hands_batched_over_single_n30: 30 single hands' periods (plant step and update,
        measured in the same run) over the batch's period for 30.
"""

from __future__ import annotations

import time

import numpy as np

from armlab.app.benches import median_us
from armlab.control.batched_grip import BatchedGrip
from armlab.control.grip import GripController, GripModel, GripParams, simulate_grasp
from armlab.hardware.sim.batched_hand import BatchedHand
from armlab.hardware.sim.hand_plant import GraspObject, make_hand

CLASS_SIZES = (1, 30, 100)


def _holding() -> tuple:
    plant = make_hand(size=0.06, stiffness=1000.0)
    controller = GripController(GripModel.of(plant), GripParams(force_limit=0.8))
    simulate_grasp(plant, controller, duration=1.5)
    return plant, controller


def _class_period_us(n: int, repeat: int) -> float:
    """Median µs of one period of ``n`` batched hands holding an object."""
    plant = BatchedHand()
    grip = BatchedGrip(GripModel.of(make_hand(size=0.06, stiffness=1000.0)))
    for _ in range(n):
        plant.add(GraspObject(size=0.06, stiffness=1000.0))
        grip.add(GripParams(force_limit=0.8))
    for hand in plant.ids:
        grip.close(hand)
    current = plant.step(np.zeros((n, 3)), 1e-3)
    for _ in range(1500):  # 1.5 s: every hand holding
        current = plant.step(grip.update(current), 1e-3)
    state = [current]

    def period() -> None:
        state[0] = plant.step(grip.update(state[0]), 1e-3)

    return median_us(period, repeat=repeat)


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
    out = {"hand_plant_1ms_us": step_us, "grip_update_us": update_us,
           "hand_grasp_2s_ms": float(np.median(runs))}
    for n in CLASS_SIZES:
        out[f"hands_period_us_n{n}"] = _class_period_us(n, repeat // 4)
    out["hands_realtime_per_core"] = CLASS_SIZES[-1] * 1e3 / out[
        f"hands_period_us_n{CLASS_SIZES[-1]}"]
    out["hands_batched_over_single_n30"] = 30 * (step_us + update_us) / out["hands_period_us_n30"]
    return out
