"""Classroom figures: how many private compliance-lesson arms one core keeps in real time.

Figures:
    sandboxes_realtime_per_core: arms (``receptionist_arm``, three RX-24F each) that one
        core steps at 1 kHz in real time with the batched plant, the class step (read,
        decode, Newton–Euler, compliance law, goal writes) and the controller at the
        lesson's 16 ms period included: N · 1e-3 s / (wall time per simulated ms) for the
        largest N of (50, 100, 200). Every arm has its own gains and command step, and a
        tenth of them are being pushed.
    sandboxes_realtime_per_core_1ms_loop: the same with the controller every 1 ms
        (period 0.001 s, the worst case a student can pick).
    classroom_step_us_n50 / _n100 / _n200: wall µs per simulated ms (plant tick, RK4 and
        the period's controller share) of the whole class of N arms.
    sandboxes_loops_realtime_per_core: the same with what "My arm" runs: every arm its own
        :class:`~control.loop.ControlLoop` (compliance, 16 ms: commands, trajectory,
        recorder, run-time checks) over a :class:`~hardware.batched_backend.BatchedArmBackend`,
        all on one :class:`~control.periodic.SharedClock` over one BatchedPlant at 1 ms
        (headless: ``SharedClock.run_for`` of 2 s of class time, 0.5 s quick): N · 1e-3 s /
        (wall time per simulated ms) for the largest N of (50, 100); a tenth of the arms
        play a step trajectory, a tenth are pushed.
    class_loops_step_us_n50 / _n100: wall µs per simulated ms of that class.

Median of repeats, ``time.perf_counter``, one thread; the machine is shared, so these are
figures, never asserted by a test.
"""

from __future__ import annotations

import statistics
import threading
import time

import numpy as np

from app.classroom_sim import ClassroomSim
from control.commands import Push, RunTrajectory
from control.loop import ControlLoop
from control.params import Params
from control.periodic import SharedClock
from control.trajectory import minimum_jerk
from hardware.batched_backend import BatchedArmBackend, add_sim_arm
from hardware.batched_plant import BatchedPlant
from hardware.servo_spec import RX24F
from kinematics import load_robot

SIZES = (50, 100, 200)
LOOP_SIZES = (50, 100)


def class_of(n_arms: int, *, period: float = 0.016, seed: int = 0) -> ClassroomSim:
    """A class of ``n_arms`` arms, each with its own gains and a step in its command."""
    model = load_robot("receptionist_arm")
    rng = np.random.default_rng(seed)
    sim = ClassroomSim(model, period=period)
    q0 = np.array([0.0, 0.3, 0.3])
    for _ in range(n_arms):
        params = Params(kp=float(rng.uniform(10.0, 40.0)), kv=float(rng.uniform(3.0, 9.0)),
                        k_env=float(rng.uniform(8.0, 30.0)), period=period)
        sim.add_arm(q0=q0 + rng.uniform(-0.2, 0.2, 3), params=params)
    sim.step()  # every arm holds where it is
    for arm in sim.plant.arm_ids:
        sim.set_command(int(arm), q0 + rng.uniform(-0.3, 0.3, 3))
    return sim


def ms_cost(sim: ClassroomSim, *, repeat: int) -> float:
    """Median wall seconds per simulated ms of ``sim`` (one period timed at a time), with a
    tenth of the arms under a push."""
    ids = sim.plant.arm_ids
    samples = []
    for k in range(repeat):
        for arm in ids[k % 10::10]:
            sim.plant.push(int(arm), np.array([0.0, 3.0, 0.0]), link=2,
                           point=np.array([0.1, 0.0, 0.0]), duration=sim.period)
        t0 = time.perf_counter()
        sim.step()
        samples.append(time.perf_counter() - t0)
    ticks = sim.period / sim.plant.dt
    return statistics.median(samples[repeat // 5:]) / ticks


def loops_ms_cost(n_arms: int, *, seconds: float, seed: int = 0) -> float:
    """Wall seconds per simulated ms of ``n_arms`` ControlLoops (compliance, 16 ms, gains
    of their own) on one SharedClock over one BatchedPlant at 1 ms, run headless for
    ``seconds`` of class time after 0.1 s of warm-up."""
    model = load_robot("receptionist_arm")
    rng = np.random.default_rng(seed)
    plant = BatchedPlant(model, RX24F, dt=1e-3)
    lock = threading.RLock()
    clock = SharedClock(plant.step, dt=plant.dt, realtime=False, lock=lock)
    q0 = np.array([0.0, 0.3, 0.3])
    loops = []
    for _ in range(n_arms):
        q = q0 + rng.uniform(-0.2, 0.2, 3)
        backend = BatchedArmBackend(plant, add_sim_arm(plant, q0=q), lock=lock)
        params = Params(kp=float(rng.uniform(10.0, 25.0)), kv=float(rng.uniform(3.0, 7.0)),
                        k_env=float(rng.uniform(8.0, 30.0)), period=0.016)
        loop = ControlLoop(model, backend, params, realtime=False, clock=clock)
        loop.start()
        loops.append((loop, q))
    clock.run_for(0.1)
    for i, (loop, q) in enumerate(loops):
        if i % 10 == 0:
            loop.post(RunTrajectory(minimum_jerk(q, q + 0.3, 0.5)))
        elif i % 10 == 5:
            loop.post(Push(np.array([0.0, 3.0, 0.0]), 2, np.array([0.1, 0.0, 0.0]), 0.3))
    t0 = time.perf_counter()
    clock.run_for(seconds)
    wall = time.perf_counter() - t0
    faults = sum(loop.status.fault is not None for loop, _ in loops)
    if faults:
        raise RuntimeError(f"bench class: {faults} of {n_arms} arms faulted")
    return wall / (seconds / plant.dt)


def run(quick: bool) -> dict[str, float]:
    """The figures above (about 6 s quick, 20 s otherwise)."""
    repeat = 15 if quick else 40
    out: dict[str, float] = {}
    cost = 0.0
    for n in SIZES:
        cost = ms_cost(class_of(n), repeat=repeat)
        out[f"classroom_step_us_n{n}"] = cost * 1e6
    out["sandboxes_realtime_per_core"] = SIZES[-1] * 1e-3 / cost
    fast = ms_cost(class_of(SIZES[-1], period=0.001), repeat=repeat * 8)
    out["sandboxes_realtime_per_core_1ms_loop"] = SIZES[-1] * 1e-3 / fast
    for n in LOOP_SIZES:
        cost = loops_ms_cost(n, seconds=0.5 if quick else 2.0)
        out[f"class_loops_step_us_n{n}"] = cost * 1e6
    out["sandboxes_loops_realtime_per_core"] = LOOP_SIZES[-1] * 1e-3 / cost
    return out
