"""Private arms of a class on one SharedClock over one BatchedPlant (issue 16 item 2) equal
ControlLoops each on its own SimBackend: recorders and plant states to 1e-9."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
import pytest

from armlab.app.lessons.compliance_servos import read_health
from armlab.control.backend import Backend, BackendError, Pushable
from armlab.control.commands import EStop, Push, Reset, RunTrajectory, SetTarget, Spring
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.periodic import SharedClock
from armlab.control.trajectory import minimum_jerk, thesis_line
from armlab.hardware.families.dynamixel1.batched_backend import (
    POSITION_WORDS,
    SIGNED_WORDS,
    BatchedArmBackend,
    add_sim_arm,
    decode_words,
    word_tables,
)
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant, ReportWords
from armlab.hardware.families.dynamixel1.firmware import ServoReport
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend, decode_reports
from armlab.hardware.servos.servo_spec import AX12A, RX24F
from armlab.kinematics import load_robot

MODEL = load_robot("receptionist_arm")
DT = 1e-3
LINE = thesis_line(MODEL)
Q0 = [LINE.q[0], np.array([0.2, 0.5, 0.8]), np.array([-0.3, 0.4, 0.6])]
PARAMS = [Params(), Params(kp=15.0, kv=4.0, k_env=30.0, period=0.010),
          Params(d_env=10.0, k_f=2.0, period=0.020)]
Action = Callable[[ControlLoop], object]
#: per arm: loop period index -> actions run just before that period
EVENTS: list[dict[int, list[Action]]] = [
    {3: [lambda lp: lp.post(RunTrajectory(LINE))],
     40: [lambda lp: lp.post(Push(np.array([0.0, 4.0, 0.0]), 2, np.zeros(3), 0.2))],
     80: [lambda lp: lp.set_params(Params(period=0.012))]},
    {10: [lambda lp: lp.post(Spring(np.array([0.15, 0.1, 0.1]), 30.0, 2,
                                    np.array([0.25, 0.0, 0.0])))],
     90: [lambda lp: lp.post(Spring(np.array([0.1, 0.2, 0.0]), 40.0, 1, np.zeros(3)))],
     150: [lambda lp: lp.post(Spring(None, 0.0, 2, np.zeros(3)))]},
    {2: [lambda lp: lp.post(RunTrajectory(minimum_jerk(Q0[2], np.array([0.3, 0.1, 0.9]),
                                                       0.4)))],
     30: [lambda lp: lp.post(EStop())],
     45: [lambda lp: lp.post(Reset())],
     60: [lambda lp: lp.post(SetTarget(np.array([0.05, 0.15, 0.2])))]},
]


def _class(n: int = 3) -> tuple[BatchedPlant, SharedClock, list[ControlLoop]]:
    plant = BatchedPlant(MODEL, RX24F, dt=DT)
    lock = threading.RLock()
    clock = SharedClock(plant.step, dt=DT, realtime=False, lock=lock)
    loops = [_join(plant, clock, i) for i in range(n)]
    return plant, clock, loops


def _join(plant: BatchedPlant, clock: SharedClock, i: int) -> ControlLoop:
    arm = add_sim_arm(plant, q0=Q0[i], lock=clock.lock)
    backend = BatchedArmBackend(plant, arm, lock=clock.lock)
    loop = ControlLoop(MODEL, backend, PARAMS[i], realtime=False, clock=clock)
    loop.start()
    return loop


def _run(clock: SharedClock, loops: dict[int, ControlLoop], seconds: float,
         done: set[tuple[int, int]]) -> None:
    """``seconds`` of class time, one tick at a time, each arm's events before its period."""
    for _ in range(round(seconds / DT)):
        for i, lp in loops.items():
            k = lp.status.steps
            if (i, k) not in done:
                done.add((i, k))
                for act in EVENTS[i].get(k, []):
                    act(lp)
        clock.run_for(DT)


def _alone(i: int, periods: int) -> ControlLoop:
    """Arm i on its own SimBackend, ``periods`` periods headless, the same events."""
    loop = ControlLoop(MODEL, SimBackend(MODEL, q0=Q0[i]), PARAMS[i], realtime=False)
    for k in range(periods):
        for act in EVENTS[i].get(k, []):
            act(loop)
        loop.step()
    return loop


def _same_record(a: ControlLoop, b: ControlLoop) -> None:
    ra, rb = a.recorder._ring.rows(), b.recorder._ring.rows()
    assert ra.shape == rb.shape
    np.testing.assert_allclose(ra, rb, rtol=0.0, atol=1e-9, equal_nan=True)


@pytest.mark.slow
def test_class_on_a_shared_clock_equals_loops_on_their_own_sim_backends() -> None:
    plant, clock, loops = _class()
    _run(clock, dict(enumerate(loops)), 2.0, set())
    assert clock.t == pytest.approx(2.0) and clock.errors == 0
    for i, lp in enumerate(loops):
        st = lp.status
        ref = _alone(i, st.steps)
        assert st.steps == ref.status.steps and st.t == ref.status.t
        assert st.fault is None and ref.status.fault is None, (st.fault, ref.status.fault)
        assert st.running is False  # headless: nothing ran in a thread
        _same_record(lp, ref)
        sim = ref.backend
        assert isinstance(sim, SimBackend)
        sim.plant.advance_to(clock.t)
        assert np.max(np.abs(plant.q[i] - sim.plant.q)) <= 1e-9
        assert np.max(np.abs(plant.qd[i] - sim.plant.qd)) <= 1e-9
    assert loops[0].params.period == 0.012  # the period change took effect
    assert loops[1].status.steps == 200 and loops[2].status.steps == 100
    for lp in loops:  # every arm really moved (arm 1 by the spring alone)
        q = lp.recorder.snapshot()["q"]
        assert np.max(np.nanmax(q, axis=0) - np.nanmin(q, axis=0)) > 0.05


@pytest.mark.slow
def test_an_arm_joining_or_leaving_leaves_the_others_unchanged() -> None:
    _, ref_clock, ref = _class(2)
    _run(ref_clock, dict(enumerate(ref)), 1.2, set())
    plant, clock, loops = _class(2)
    done: set[tuple[int, int]] = set()
    _run(clock, dict(enumerate(loops)), 0.4, done)
    third = _join(plant, clock, 2)  # joins at 0.4 s: its loop time starts at 0
    every = {0: loops[0], 1: loops[1], 2: third}
    _run(clock, every, 0.4, done)
    loops[1].shutdown()  # detached at 0.8 s: its arm stays, its loop stops
    stopped_at = loops[1].status.steps
    _run(clock, {0: loops[0], 2: third}, 0.4, done)
    assert loops[1].status.steps == stopped_at and clock.loops == 2
    _same_record(loops[0], ref[0])
    t = third.recorder.snapshot()["t"]
    assert t[0] == 0.0 and third.status.steps == 40  # 0.8 s at 20 ms
    alone = _alone(2, third.status.steps)
    _same_record(third, alone)
    first = ref[1].recorder._ring.rows()[:stopped_at]
    np.testing.assert_allclose(loops[1].recorder._ring.rows(), first, atol=1e-9,
                               equal_nan=True)
    loops[1].start()  # attached again: goes on from its next period at once
    _run(clock, every, 0.05, done)
    assert loops[1].status.steps == stopped_at + 5


@pytest.mark.slow
def test_a_failing_period_or_world_step_leaves_the_clock_and_other_arms_running() -> None:
    _, ref_clock, ref = _class(2)
    _run(ref_clock, dict(enumerate(ref)), 0.5, set())
    plant, clock, loops = _class(2)

    def boom() -> None:
        raise RuntimeError("a bad period")

    bad = clock.pacer(boom, period=0.005, name="bad")
    bad.start()
    broken = add_sim_arm(plant, q0=Q0[1])

    class Broken(BatchedArmBackend):
        def read(self):  # noqa: ANN202
            raise KeyError("inside one arm's read")

    lp = ControlLoop(MODEL, Broken(plant, broken, lock=clock.lock), realtime=False,
                     clock=clock)
    lp.start()
    _run(clock, dict(enumerate(loops)), 0.5, set())
    assert bad.errors == 100 and isinstance(bad.last_error, RuntimeError)
    assert lp.status.fault is not None and "KeyError" in lp.status.fault
    for a, b in zip(loops, ref, strict=True):
        _same_record(a, b)
    # a world step that raises is counted; the clock goes on
    calls = []

    def step() -> None:
        calls.append(1)
        if len(calls) == 3:
            raise FloatingPointError("arm 7 diverged")

    seen: list[Exception] = []
    other = SharedClock(step, dt=DT, realtime=False, on_error=seen.append)
    other.run_for(0.01)
    assert len(calls) == 10 and other.errors == 1 and other.steps == 10
    assert isinstance(seen[0], FloatingPointError) and other.last_error is seen[0]


def test_batched_arm_backend_is_a_sim_backend_for_one_arm() -> None:
    plant = BatchedPlant(MODEL, RX24F, dt=DT)
    lock = threading.RLock()
    arm = add_sim_arm(plant, q0=Q0[1])
    be = BatchedArmBackend(plant, arm, lock=lock)
    sim = SimBackend(MODEL, q0=Q0[1])
    assert isinstance(be, Backend) and isinstance(be, Pushable)
    assert np.array_equal(be.lower, sim.lower) and np.array_equal(be.upper, sim.upper)
    assert list(plant.registers(arm)) == [s.regs for s in sim.plant.servos]
    for b in (be, sim):
        b.write(np.array([5.0, 0.2, -9.0]), np.array([1.0, 0.0, 2.0]))  # clamped
    with pytest.raises(ValueError, match="position"):
        be.write(np.array([np.nan, 0.0, 0.0]), np.ones(3))
    for k in range(300):
        if k == 100:
            for b in (be, sim):
                b.push(np.array([0.0, 3.0, 1.0]), link=2, point=np.zeros(3), duration=0.05)
                b.set_spring(np.array([0.1, 0.1, 0.1]), stiffness=40.0, link=1,
                             point=np.zeros(3))
        if k == 200:
            assert be.estop() is True and sim.estop() is True
        plant.step()
        be.sync((k + 1) * DT)
        sim.sync((k + 1) * DT)
        a, b = be.read(), sim.read()
        assert a.t == b.t and a.errors == b.errors and a.torque_on == b.torque_on
        for x, y in ((a.position, b.position), (a.velocity, b.velocity), (a.load, b.load)):
            assert np.array_equal(x, y), k
    be.set_torque(True)
    assert all(r.torque_enable == 1 for r in plant.registers(arm))
    # what the Servos panel reads of a simulated backend's ``plant``
    health, line = read_health(be, MODEL.joint_names)
    assert [h.torque_on for h in health] == [True] * 3 and line.startswith("simulated")
    assert be.plant.reports() == plant.reports(arm) and np.array_equal(be.plant.q, plant.q[0])
    be.close()
    with pytest.raises(BackendError):
        be.write(np.zeros(3), np.ones(3))
    with pytest.raises(BackendError):
        be.read()
    assert be.estop() is True and plant.n_arms == 1  # close removes nothing
    plant.remove_arm(arm)
    assert be.estop() is True  # never raises, even with the arm gone


def test_a_batched_arm_decodes_every_raw_word_as_a_sim_backend_does() -> None:
    """BatchedArmBackend.read looks words up in tables (word_tables): for every Present
    Position, Speed and Load word and error byte, of each servo model and direction, it
    gives decode_reports' floats bit for bit (signed zeros included) and its names."""
    specs, dirs = (RX24F, AX12A, RX24F), (1.0, -1.0, -1.0)
    tables = [word_tables(s, d) for s, d in zip(specs, dirs, strict=True)]
    for w in range(SIGNED_WORDS):
        pos = [w % POSITION_WORDS, (w * 7) % POSITION_WORDS, POSITION_WORDS - 1 - w // 2]
        words = ReportWords(position=pos, speed=[w, w ^ 0x400, w], load=[w ^ 0x400, w, w],
                            error=[w & 0x7F, 0, (w >> 4) & 0x7F], torque_enable=[1, 0, w & 1])
        reports = [ServoReport(position=p, speed=v, load=ld, voltage=120, temperature=30,
                               moving=0, error=e, torque_enable=te, torque_limit=1023)
                   for p, v, ld, e, te in zip(*words, strict=True)]
        a, b = decode_words(words, tables, 0.25), decode_reports(reports, specs, dirs, 0.25)
        for x, y in ((a.position, b.position), (a.velocity, b.velocity), (a.load, b.load)):
            assert x.tobytes() == y.tobytes(), w
        assert (a.t, a.errors, a.torque_on, a.alarms) == (b.t, b.errors, b.torque_on, b.alarms)


def test_the_clock_thread_runs_attached_loops_and_stops() -> None:
    plant, clock, loops = _class(2)
    clock.start()
    try:
        assert clock.alive and loops[0].status.running
        with pytest.raises(RuntimeError):
            loops[0].step()
        with pytest.raises(RuntimeError):
            clock.run_for(0.1)
        deadline = time.monotonic() + 10.0
        while loops[1].status.steps < 20 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert loops[1].status.steps >= 20
    finally:
        clock.stop()
    assert not clock.alive and not loops[0].status.running
    assert plant.steps == clock.steps


def test_periods_are_due_where_advance_to_would_put_their_own_plant() -> None:
    """Any period (not a multiple of dt), a period change from inside a period, a pacer
    started later (its time starts at 0, at the next whole number of its periods of class
    time), pacers of one tick in the order started."""
    clock = SharedClock(lambda: None, dt=DT, realtime=False)
    fired: list[tuple[str, int, float]] = []

    def make(name: str, period: float, change_at: int | None = None):  # noqa: ANN202
        local = {"t": 0.0, "k": 0}

        def step() -> None:
            fired.append((name, clock.steps, local["t"]))
            local["k"] += 1
            if local["k"] == change_at:
                pacer.period = 0.0037
            local["t"] += pacer.period

        pacer = clock.pacer(step, period=period, name=name)
        return pacer

    a = make("a", 0.0025, change_at=10)
    b = make("b", 0.016)
    a.start()
    b.start()
    clock.run_for(0.05)
    c = make("c", 0.007)
    c.start()  # at 50 ms: its first period waits for 56 ms, 8 periods of 7 ms
    start_c = 56
    clock.run_for(0.1)
    for name, offset in (("a", 0), ("b", 0), ("c", start_c)):
        k = 0
        for _, step, t in (f for f in fired if f[0] == name):
            while (k + 0.5) * DT <= t:  # Plant.advance_to(t) of a plant of its own
                k += 1
            assert step - offset == k, (name, t)
    first = [f[0] for f in fired if f[1] == 0]
    assert first == ["a", "b"] and sum(f[0] == "a" for f in fired) > 40
    assert fired[-1][1] < clock.steps
    b.stop(timeout=1.0)
    n_b = sum(f[0] == "b" for f in fired)
    clock.run_for(0.05)
    assert sum(f[0] == "b" for f in fired) == n_b and clock.loops == 2
    c.period = 0.0  # a period that would never end a tick: that pacer is detached
    clock.run_for(0.02)
    assert clock.loops == 1 and not c.running and isinstance(c.last_error, ValueError)
    with pytest.raises(ValueError, match="period"):
        clock.pacer(lambda: None, period=0.0, name="zero")


def test_pacers_of_one_period_started_at_different_moments_share_their_ticks() -> None:
    """Students join a class at moments of their own: each loop's first period waits for
    the next whole number of its periods of class time (at most one period), so loops of
    one period run at the same ticks, wherever they started (their law then computed as
    one), and a restarted one keeps to them."""
    clock = SharedClock(lambda: None, dt=DT, realtime=False)
    ticks: dict[str, list[int]] = {}

    def make(name: str, period: float):  # noqa: ANN202
        ticks[name] = []
        return clock.pacer(lambda: ticks[name].append(clock.steps), period=period, name=name)

    pacers = {}
    for name, period in (("a", 0.016), ("b", 0.016), ("c", 0.016), ("d", 0.008),
                         ("e", 0.0025)):
        pacers[name] = make(name, period)
        pacers[name].start()
        clock.run_for(5 * DT)  # the next joins 5 ms later
    clock.run_for(0.2)
    assert ticks["a"][0] == 0 and ticks["b"][0] == 16 and ticks["c"][0] == 16
    assert ticks["d"][0] == 16 and ticks["e"][0] == 20  # (2.5 ms: every 2 steps)
    every = [set(t) for t in (ticks["a"], ticks["b"], ticks["c"])]
    assert every[1] <= every[0] and every[2] == every[1] and len(every[2]) > 10
    assert set(ticks["a"][1:]) <= set(ticks["d"])  # 16 ms ticks are 8 ms ticks too
    assert all(k % 16 == 0 for k in ticks["a"] + ticks["b"] + ticks["c"])
    pacers["b"].stop(timeout=1.0)
    clock.run_for(3 * DT)
    pacers["b"].start()  # again, between two of its ticks: it waits for the next
    before = len(ticks["b"])
    clock.run_for(0.05)
    assert all(k % 16 == 0 for k in ticks["b"][before:]) and len(ticks["b"]) > before


@pytest.mark.slow
def test_a_diverged_arm_is_put_back_by_on_error_and_the_others_go_on() -> None:
    _, ref_clock, ref = _class(2)
    _run(ref_clock, dict(enumerate(ref)), 0.3, set())
    plant = BatchedPlant(MODEL, RX24F, dt=DT)
    put_back: list[int] = []

    def on_error(exc: Exception) -> None:
        assert isinstance(exc, FloatingPointError)
        for arm in plant.diverged():
            plant.set_state(int(arm), MODEL.neutral())
            put_back.append(int(arm))

    clock = SharedClock(plant.step, dt=DT, realtime=False, on_error=on_error)
    loops = [_join(plant, clock, i) for i in range(2)]
    with np.errstate(all="ignore"):
        wild = plant.add_arm(qd0=np.array([1e308, 0.0, 0.0]))
        _run(clock, dict(enumerate(loops)), 0.3, set())
    assert put_back == [wild] and clock.errors == 1 and plant.diverged().size == 0
    for a, b in zip(loops, ref, strict=True):
        _same_record(a, b)


@pytest.mark.slow
def test_a_thread_waiting_for_the_class_lock_gets_it_between_two_ticks() -> None:
    """A page reading its arm (the Servos panel, the overview) takes the class lock. A
    clock that is behind (here always: each tick takes longer than its ``dt``) runs its
    ticks back to back and would take the lock back at once for the next; it lets the
    waiter in first (a HandOverLock), so a reader waits about one tick, not a catch-up of
    many."""
    def slow_step() -> None:
        sum(range(5000))

    clock = SharedClock(slow_step, dt=1e-5, realtime=True, max_catch_up=0.05,
                        hand_over_s=60.0)  # unbounded here: the order, not the time
    clock.start()
    try:
        deadline = time.monotonic() + 30.0
        while clock.steps < 100 and time.monotonic() < deadline:
            time.sleep(0.01)
        waited = []
        for _ in range(40):
            k0 = clock.steps
            with clock.lock:
                waited.append(clock.steps - k0)
            time.sleep(0.002)  # the clock ticks on between two reads
    finally:
        clock.stop()
    # the tick running when the reader asked, and at most one begun before it counted
    # itself a waiter
    assert max(waited) <= 2, waited
