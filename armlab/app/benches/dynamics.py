"""Dynamics benches: one RNEA call and plant steps per second (receptionist arm, 3 RX-24F)."""

from __future__ import annotations

import time

import numpy as np

from armlab.app.benches import median_us
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import newton_euler, rnea


def run(quick: bool) -> dict[str, float]:
    """``rnea_us``: median µs of ``rnea(model, q, qd, qdd)`` with numpy arrays in and out;
    ``newton_euler_us`` the same torques by the readable recursion (the teaching text), and
    ``rnea_speedup`` their ratio measured in this run.

    ``plant_steps_per_s``: 1 ms plant steps per second of this thread's CPU time ("on one
    core"), while the three RX-24F track a goal: the median of several batches. CPU time,
    not wall time, because the benchmark machines are shared and a wall clock there counts
    other people's work; a real-time run needs only 1000 steps per wall second.
    """
    model = load_robot("receptionist_arm")
    q, qd, qdd = np.array([0.3, 0.5, 0.8]), np.array([0.4, -0.2, 0.6]), np.array([1.0, 2, 3])
    rnea_us = median_us(lambda: rnea(model, q, qd, qdd), repeat=500 if quick else 5000)
    readable_us = median_us(lambda: newton_euler(model, q, qd, qdd),
                            repeat=200 if quick else 1000)
    backend = SimBackend(model, q0=[0.0, 0.3, 0.3])
    backend.write(np.array([0.5, 0.8, 1.0]), np.full(3, 1.5))
    plant = backend.plant
    steps = 1000 if quick else 5000
    rates = []
    for _ in range(3 if quick else 7):
        t0 = time.thread_time()
        for _ in range(steps):
            plant.step()
        rates.append(steps / (time.thread_time() - t0))
    return {"rnea_us": rnea_us, "newton_euler_us": readable_us,
            "rnea_speedup": readable_us / rnea_us, "plant_steps_per_s": float(np.median(rates))}
