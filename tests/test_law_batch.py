"""A class's private arms compute the lab's own law of the periods due at one tick as one
(:mod:`armlab.control.law_batch`, issue 54's speed): every arm's record, to the last bit,
is what its loop computing its own law records.

The reference is the same class with a student's law that is the lab's own function
(``armlab serve --exercise``'s path): a student's law never joins the batch, so each of
those loops computes every period's law on its own, through the same equations.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import fields

import numpy as np
import pytest

from armlab.control.backend import JointState
from armlab.control.commands import EStop, Push, Reset, RunTrajectory, SetTarget
from armlab.control.compliance import ComplianceController, ControllerState, Laws
from armlab.control.law_batch import LawAsk, LawBatch, step_many
from armlab.control.laws import compliance_accel
from armlab.control.loop import ControlLoop
from armlab.control.params import GAINS, ParamColumns, Params
from armlab.control.periodic import SharedClock
from armlab.control.trajectory import minimum_jerk, thesis_line
from armlab.hardware.families.dynamixel1.batched_backend import BatchedArmBackend, add_sim_arm
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.families.dynamixel1.batched_walls import BatchedWalls
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics import load_robot

MODEL = load_robot("receptionist_arm")
LINE = thesis_line(MODEL)
Action = Callable[[ControlLoop], object]

#: per arm: its start, its parameters, when it joins (clock tick) and its events (loop
#: period -> actions just before it). Mixed on purpose: both laws, PD, no feedforward,
#: periods that fall on different ticks (of other lengths, or changed), a wall, an e-stop
#: and Reset, gains that fault.
ARMS: list[tuple[np.ndarray, Params, int, dict[int, list[Action]]]] = [
    (LINE.q[0], Params(), 0, {3: [lambda lp: lp.post(RunTrajectory(LINE))]}),
    (np.array([0.2, 0.5, 0.8]), Params(kp=15.0, kv=4.0, k_env=30.0, period=0.010), 0,
     {5: [lambda lp: lp.post(Push(np.array([0.0, 4.0, 0.0]), 2, np.zeros(3), 0.2))]}),
    (np.array([-0.3, 0.4, 0.6]), Params(law="2.26", d_env=10.0, k_f=2.0), 3,
     {2: [lambda lp: lp.post(RunTrajectory(minimum_jerk(np.array([-0.3, 0.4, 0.6]),
                                                        np.array([0.3, 0.1, 0.9]), 0.4)))],
      30: [lambda lp: lp.post(EStop())], 45: [lambda lp: lp.post(Reset())],
      60: [lambda lp: lp.post(SetTarget(np.array([0.05, 0.15, 0.2])))]}),
    (np.array([0.0, 0.3, 0.3]), Params(compliance=False, kp=30.0, kv=6.0), 0,
     {4: [lambda lp: lp.post(RunTrajectory(minimum_jerk(np.array([0.0, 0.3, 0.3]),
                                                        np.array([0.4, 0.6, 0.6]), 0.5)))],
      50: [lambda lp: lp.set_params(Params(kp=12.0, period=0.008))]}),
    (np.array([0.5, 0.2, 0.1]), Params(feedforward=False, m_env=0.5, period=0.001), 7,
     {2: [lambda lp: lp.post(RunTrajectory(minimum_jerk(np.array([0.5, 0.2, 0.1]),
                                                        np.array([0.1, 0.5, 0.4]), 0.6)))]}),
    (np.array([0.1, 0.2, 0.5]), Params(kp=200.0, kv=0.0, k_env=0.1, period=0.05), 0,
     {2: [lambda lp: lp.post(RunTrajectory(minimum_jerk(np.array([0.1, 0.2, 0.5]),
                                                        np.array([1.5, -1.0, 1.5]), 0.3)))]}),
]
WALL_ARM = 1  #: this arm's hand meets a wall of its own (a Touchable backend)


def _student_own_law() -> Laws:
    """The lab's eq. 2.6 handed in as a student's function: never batched."""
    return Laws.with_student("compliance", lambda *a: compliance_accel(*a))


def _class(*, own_laws: bool, dt: float = 1e-3) -> tuple[SharedClock, list[ControlLoop]]:
    """The class of :data:`ARMS`, played for 1.2 s of class time."""
    plant = BatchedPlant(MODEL, RX24F, dt=dt)
    walls = BatchedWalls(plant)
    lock = threading.RLock()
    clock = SharedClock(walls.step, dt=dt, realtime=False, lock=lock)
    LawBatch.of(clock).smallest = 2  # this class's groups are of two and three
    loops: dict[int, ControlLoop] = {}
    done: set[tuple[int, int]] = set()
    for tick in range(round(1.2 / dt)):
        for i, (q0, params, join, _) in enumerate(ARMS):
            if tick == join:
                backend = BatchedArmBackend(plant, add_sim_arm(plant, q0=q0, lock=lock),
                                            lock=lock, walls=walls)
                if i == WALL_ARM:
                    hand = MODEL.fk(q0)[:3, 3]
                    backend.set_wall(hand - np.array([0.0, 0.004, 0.0]),
                                     np.array([0.0, 1.0, 0.0]), stiffness=2e4, damping=50.0)
                loops[i] = ControlLoop(MODEL, backend, params, realtime=False, clock=clock,
                                       laws=None if own_laws else _student_own_law())
                loops[i].start()
        for i, lp in loops.items():
            k = lp.status.steps
            if (i, k) not in done:
                done.add((i, k))
                for act in ARMS[i][3].get(k, []):
                    act(lp)
        clock.run_for(dt)
    return clock, [loops[i] for i in range(len(ARMS))]


@pytest.mark.slow
@pytest.mark.parametrize("dt", [1e-3, 2e-3])
def test_the_batched_law_records_every_arm_as_its_own_loop_does(dt: float) -> None:
    """Every arm's recorded rows (commands, references, measurements, torques, the wall's
    force) and its status equal the reference class's bit for bit, its fault included.
    At a clock (and plant) step of 2 ms the arm of 1 ms has two periods in every tick: the
    first computes its own law before the second starts."""
    clock, batched = _class(own_laws=True, dt=dt)
    other, alone = _class(own_laws=False, dt=dt)
    assert clock.errors == 0
    assert LawBatch.of(clock).batched > 20 and LawBatch.of(other).batched == 0
    for i, (a, b) in enumerate(zip(batched, alone, strict=True)):
        ra, rb = a.recorder._ring.rows(), b.recorder._ring.rows()
        assert ra.shape == rb.shape and len(ra) > 10, i
        assert np.array_equal(ra, rb, equal_nan=True), f"arm {i}"
        sa, sb = a.status, b.status
        assert (sa.fault, sa.steps, sa.active, sa.message) == (
            sb.fault, sb.steps, sb.active, sb.message), i
    assert batched[5].status.fault and "unstable" in batched[5].status.fault  # it faulted
    assert batched[2].status.active and batched[0].status.active
    wall = batched[WALL_ARM].recorder.snapshot()["f_contact"]
    assert np.nanmax(wall) > 0.0  # its hand pressed the wall


def _asks(k: int) -> list[LawAsk]:
    rng = np.random.default_rng(k)
    ctl = ComplianceController(MODEL.lower, MODEL.upper, 3.0)
    asks = []
    for _ in range(k):
        state = ControllerState.at_rest(rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3))
        state.q_env[:] = rng.uniform(-0.1, 0.1, 3)
        meas = JointState(t=0.0, position=rng.uniform(-1, 1, 3),
                          velocity=rng.uniform(-2, 2, 3), load=rng.uniform(-1, 1, 3),
                          errors=(0, 0, 0), torque_on=(True,) * 3)
        asks.append(LawAsk(ctl, Params(kp=float(rng.uniform(5, 50))), state,
                           rng.uniform(-3, 3, 3), rng.uniform(-1, 1, 3),
                           rng.uniform(-1, 1, 3), meas, rng.uniform(-1, 1, 3)))
    return asks


def test_step_many_gives_each_row_its_own_step_and_leaves_the_states_when_it_fails() -> None:
    """:func:`step_many` of 5 asks (some references past a joint limit) equals five steps
    of their own, states and answers; with a bad ask it raises and no state changes."""
    mine, theirs = _asks(5), _asks(5)
    answers = step_many(mine)
    for a, b, (q_ref, qd_ref) in zip(mine, theirs, answers, strict=True):
        q, qd = b.controller.step(b.params, b.state, b.q_cmd, b.qd_cmd, b.qdd_cmd,
                                  b.measured, b.tau_dyn)
        assert np.array_equal(q, q_ref) and np.array_equal(qd, qd_ref)
        for name in ("q_ref", "qd_ref", "qdd_ref", "q_env", "qd_env", "qdd_env", "tau_lpf",
                     "tau_ext"):
            assert np.array_equal(getattr(a.state, name), getattr(b.state, name)), name
    bad = _asks(3)
    before = [a.state.q_ref.copy() for a in bad]
    bad[1] = LawAsk(*(vars(bad[1])[f] for f in ("controller", "params", "state")),
                    np.zeros(2), *(vars(bad[1])[f] for f in ("qd_cmd", "qdd_cmd", "measured",
                                                             "tau_dyn")))
    with pytest.raises(ValueError):
        step_many(bad)
    assert all(np.array_equal(a.state.q_ref, b) for a, b in zip(bad, before, strict=True))


def test_param_columns_are_the_gains_columns_in_their_order() -> None:
    """step_many builds ParamColumns from the gains in :data:`GAINS`' order."""
    assert tuple(f.name for f in fields(ParamColumns))[:len(GAINS)] == GAINS
    assert set(GAINS) < {f.name for f in fields(Params)}


def test_one_batch_per_clock_at_the_end_of_its_ticks() -> None:
    clock = SharedClock(lambda: None, dt=1e-3, realtime=False)
    assert LawBatch.of(clock) is LawBatch.of(clock)
    assert LawBatch.of(SharedClock(lambda: None, dt=1e-3, realtime=False)) is not (
        LawBatch.of(clock))
