"""The control loop on the simulated arm: commands, limits, faults, recorder, real-time thread."""

import threading
import time

import numpy as np
import pytest

from armlab.control.backend import BackendError, JointState
from armlab.control.commands import EStop, Push, Reset, RunTrajectory, SetTarget, Stop
from armlab.control.loop import ControlLoop
from armlab.control.params import DEFAULT, REFUSED_ON_SERVOS, Params, check_gains
from armlab.control.trajectory import minimum_jerk, thesis_line
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics import load_robot

ARM = load_robot("receptionist_arm")
POSE = np.array([0.6, 0.3, 1.2])


class Faulty:
    """The simulated arm behind a cable that can go bad: it records every write and can
    hand back NaN or lose the link after a given number of reads. Not Pushable."""

    def __init__(self, *, nan_after: int | None = None, fail_after: int | None = None):
        self.sim = SimBackend(ARM, q0=POSE)
        self.writes: list[tuple[np.ndarray, np.ndarray]] = []
        self.reads = 0
        self.estops = 0
        self.nan_after, self.fail_after = nan_after, fail_after

    n = property(lambda self: self.sim.n)
    lower = property(lambda self: self.sim.lower)
    upper = property(lambda self: self.sim.upper)

    def sync(self, t: float) -> None:
        self.sim.sync(t)

    def read(self) -> JointState:
        self.reads += 1
        if self.fail_after is not None and self.reads > self.fail_after:
            raise BackendError("no status packet from servo 3; check the cable and power")
        s = self.sim.read()
        if self.nan_after is not None and self.reads > self.nan_after:
            load = s.load.copy()
            load[1] = np.nan
            s = JointState(s.t, s.position, s.velocity, load, s.errors, s.torque_on)
        return s

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        self.writes.append((np.array(position), np.array(speed)))
        self.sim.write(position, speed)

    def set_torque(self, on: bool) -> None:
        self.sim.set_torque(on)

    def estop(self) -> None:
        self.estops += 1
        self.sim.estop()

    def close(self) -> None:
        self.sim.close()

    def torque_enabled(self) -> list[int]:
        return [s.regs.torque_enable for s in self.sim.plant.servos]


def all_finite(writes) -> bool:
    return all(np.all(np.isfinite(p)) and np.all(np.isfinite(s)) for p, s in writes)


def test_nan_from_the_servos_stops_the_loop_torque_off_and_no_nan_written():
    be = Faulty(nan_after=20)
    loop = ControlLoop(ARM, be, realtime=False)
    status = loop.run_for(1.0)
    assert status.fault is not None and "non-finite load" in status.fault
    assert not status.active and not status.torque_on
    assert be.torque_enabled() == [0, 0, 0] and be.estops >= 1
    assert len(be.writes) == 20 and all_finite(be.writes)
    loop.run_for(0.5)  # stays stopped: nothing more is written
    assert len(be.writes) == 20


def test_unstable_gains_are_refused_or_caught_at_run_time():
    be = Faulty()  # not Pushable: servos, to the rule on gains
    loop = ControlLoop(ARM, be, realtime=False)
    with pytest.raises(ValueError, match="unstable"):
        loop.set_params(Params(kp=10.0, kv=50.0, period=0.05))  # diverges on any joint
    # stable on paper, but too fast for the servos' own loop: the arm starts to shake
    warning = loop.set_params(Params(kp=100.0, kv=20.0)).warning
    assert warning is not None and "servos" in warning
    loop.post(RunTrajectory(minimum_jerk(POSE, POSE + [0.3, 0.2, -0.3], 1.0)))
    status = loop.run_for(10.0)
    assert status.fault is not None and "unstable" in status.fault
    assert be.torque_enabled() == [0, 0, 0]
    assert status.t < 9.0 and all_finite(be.writes)


def test_every_way_in_holds_gains_to_the_rule_once_and_none_goes_around_it(monkeypatch):
    """The constructor and set_params apply the lab's one rule on gains exactly once per
    change; the period swap uses that verdict; no argument skips the rule; servos refuse
    unstable gains, a simulated arm takes them (to be seen failing)."""
    import armlab.control.loop as loop_module

    checked: list[tuple[Params, bool]] = []

    def rule(params, *, servos):  # noqa: ANN001, ANN202
        checked.append((params, servos))
        return check_gains(params, servos=servos)

    monkeypatch.setattr(loop_module, "check_gains", rule)
    unstable = Params(kp=10.0, kv=50.0, period=0.05)
    with pytest.raises(ValueError, match=f"^{REFUSED_ON_SERVOS}: the PD loop diverges"):
        ControlLoop(ARM, Faulty(), unstable, realtime=False)
    assert checked == [(unstable, True)]
    loop = ControlLoop(ARM, Faulty(), realtime=False)
    checked.clear()
    with pytest.raises(ValueError, match=f"^{REFUSED_ON_SERVOS}: the PD loop diverges"):
        loop.set_params(unstable)
    with pytest.raises(TypeError):
        loop.set_params(unstable, force=True)  # type: ignore[call-arg]  # no way around
    assert checked == [(unstable, True)] and loop.params == DEFAULT
    slow = Params(period=0.02)
    gains = loop.set_params(slow)
    loop.run_for(0.1)  # swapped in at a period boundary
    assert checked == [(unstable, True), (slow, True)]
    assert loop.gains is gains and loop.params is slow and loop.status.period_ms == 20.0
    sim = ControlLoop(ARM, SimBackend(ARM, q0=POSE), realtime=False)
    taken = sim.set_params(unstable)
    assert checked[-1] == (unstable, False) and taken.unstable and sim.params is unstable


def test_non_finite_or_bad_parameters_never_reach_the_loop():
    loop = ControlLoop(ARM, Faulty(), realtime=False)
    with pytest.raises(ValueError, match="m_env"):
        loop.set_params(Params(m_env=0.0))
    with pytest.raises(ValueError, match="params"):
        loop.set_params({"kp": 1.0})  # type: ignore[arg-type]


def test_backend_error_in_the_thread_gives_one_message_and_no_traceback():
    be = Faulty(fail_after=10)
    hooked: list[object] = []
    old = threading.excepthook
    threading.excepthook = hooked.append
    try:
        loop = ControlLoop(ARM, be, Params(period=0.005), realtime=True)
        loop.start()
        deadline = time.monotonic() + 60.0  # a generous poll: a busy machine
        while loop.status.fault is None and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.05)
        status = loop.status
        loop.shutdown()
    finally:
        threading.excepthook = old
    assert status.fault == "backend error: no status packet from servo 3; check the cable " \
                           "and power"
    assert status.running and not status.active  # the thread lives on, waiting for Reset
    assert hooked == [] and be.reads == 11  # no retries hammering a dead link
    assert be.estops >= 1


def test_estop_then_reset_holds_where_the_arm_is():
    be = Faulty()
    loop = ControlLoop(ARM, be, realtime=False)
    loop.run_for(0.5)
    loop.post(EStop())
    loop.run_for(0.5)
    n = len(be.writes)
    st = loop.status
    assert st.estopped and not st.torque_on and be.torque_enabled() == [0, 0, 0]
    loop.run_for(0.5)
    assert len(be.writes) == n  # nothing written while stopped
    loop.post(Reset())
    loop.run_for(1.0)
    st = loop.status
    assert not st.estopped and st.fault is None and st.active
    assert be.torque_enabled() == [1, 1, 1]
    snap = loop.recorder.snapshot(0.2)
    np.testing.assert_allclose(snap["q_cmd"][-1], snap["q_cmd"][0])  # holding, not moving


def test_trajectory_runs_and_goals_stay_in_the_limits():
    be = Faulty()
    loop = ControlLoop(ARM, be, Params(), controller="none", realtime=False)
    lower, upper = be.lower, be.upper
    beyond = POSE.copy()
    beyond[2] = upper[2] + 0.5  # the elbow asked past its limit
    loop.post(RunTrajectory(minimum_jerk(POSE, beyond, 1.0), approach=False))
    loop.run_for(2.0)
    goals = np.array([w[0] for w in be.writes])
    speeds = np.array([w[1] for w in be.writes])
    assert np.all(goals >= lower - 1e-12) and np.all(goals <= upper + 1e-12)
    assert goals[-1, 2] == pytest.approx(upper[2])
    assert np.all(speeds >= 0) and np.all(speeds <= loop.max_speed)


def test_stop_holds_the_command_and_trajectory_progress_is_reported():
    loop = ControlLoop(ARM, SimBackend(ARM, q0=POSE), realtime=False)
    loop.post(RunTrajectory(minimum_jerk(POSE, POSE + [0.4, 0.0, 0.4], 2.0, name="swing")))
    loop.run_for(1.0)
    st = loop.status
    assert st.trajectory == "swing" and 0.4 < st.progress < 0.6
    loop.post(Stop())
    loop.run_for(0.5)
    snap = loop.recorder.snapshot(0.4)
    assert loop.status.trajectory is None
    np.testing.assert_allclose(snap["q_cmd"][-1], snap["q_cmd"][0])
    assert 0.1 < snap["q_cmd"][-1][0] - POSE[0] < 0.3  # stopped half way


def test_set_target_follows_by_rmrc():
    loop = ControlLoop(ARM, SimBackend(ARM, q0=POSE), realtime=False)
    loop.run_for(0.2)
    start = ARM.fk(POSE)[:3, 3]
    target = start + np.array([0.0, 0.05, -0.05])
    loop.post(SetTarget(target))
    loop.run_for(2.0)
    snap = loop.recorder.snapshot(0.1)
    hand_cmd = ARM.fk(snap["q_cmd"][-1])[:3, 3]
    hand = ARM.fk(snap["q"][-1])[:3, 3]
    assert np.linalg.norm(hand_cmd - target) < 1e-3
    assert np.linalg.norm(hand - target) < 0.01  # the arm itself, within servo resolution


def test_push_on_hardware_is_refused_with_a_message():
    loop = ControlLoop(ARM, Faulty(), realtime=False)
    loop.run_for(0.1)
    loop.post(Push([0, 1.0, 0], 2, [0.25, 0, 0], 0.5))
    loop.run_for(0.1)
    assert "push the real arm by hand" in loop.status.message and loop.status.fault is None


def test_params_swap_at_the_next_period_boundary():
    loop = ControlLoop(ARM, SimBackend(ARM, q0=POSE), Params(period=0.016), realtime=False)
    loop.run_for(0.16)
    assert loop.status.steps == 10
    loop.set_params(Params(period=0.005))
    assert loop.status.period_ms == pytest.approx(16.0)  # not yet
    t = loop.status.t
    loop.step()
    assert loop.status.period_ms == pytest.approx(5.0)
    assert loop.status.t == pytest.approx(t + 0.005)


def test_recorder_snapshot_window_and_csv():
    loop = ControlLoop(ARM, SimBackend(ARM, q0=POSE), realtime=False, history_s=2.0)
    loop.run_for(3.0)
    snap = loop.recorder.snapshot()
    assert len(snap["t"]) == loop.recorder.capacity  # the ring kept the last 2 s only
    assert snap["t"][-1] - snap["t"][0] == pytest.approx(2.0, abs=0.02)
    part = loop.recorder.snapshot(0.5)
    assert part["t"][-1] - part["t"][0] == pytest.approx(0.5, abs=0.017)
    assert part["q"].shape == (len(part["t"]), 3)
    thin = loop.recorder.snapshot(max_points=10)
    assert len(thin["t"]) <= 10 and thin["t"][-1] == snap["t"][-1]
    csv = loop.recorder.to_csv(Params(), window_s=0.1)
    lines = csv.splitlines()
    assert "kp=20.0" in lines[1] and "law=2.6" in lines[1]
    assert lines[2].startswith("t_s,wall_time_s,q_cmd_theta1_rad")
    assert len(lines) == 3 + len(loop.recorder.snapshot(0.1)["t"])
    assert lines[3].split(",")[1] == ""  # headless: no wall clock, only loop time


@pytest.mark.realtime
def test_real_time_thread_paces_and_a_reader_can_snapshot_meanwhile():
    loop = ControlLoop(ARM, SimBackend(ARM, q0=POSE), realtime=True)
    started = time.monotonic()
    loop.start()
    line = thesis_line(ARM)
    loop.post(RunTrajectory(line))
    shapes = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < 0.8:  # the UI's 30 Hz reader
        snap = loop.recorder.snapshot(5.0)
        shapes.append((len(snap["t"]), snap["q"].shape[0]))
        time.sleep(1 / 30)
    status = loop.status
    elapsed = time.monotonic() - started  # however long a busy machine made it
    loop.shutdown()
    assert not loop.status.running
    assert all(a == b for a, b in shapes) and shapes[-1][0] > shapes[0][0]
    assert status.running and status.fault is None
    # paced, not free-running: at most one period per period of wall time since the start
    assert 1 <= status.steps <= elapsed / loop.params.period + 2
    assert status.jitter_p99_ms is not None and status.period_mean_ms is not None


@pytest.mark.slow
def test_a_servo_stalled_against_a_wall_stops_the_loop_and_reset_recovers():
    q0 = np.array([0.6, 0.0, 1.2])
    d = ARM.jacobian(q0)[:3, 0] / np.linalg.norm(ARM.jacobian(q0)[:3, 0])
    be = SimBackend(ARM, q0=q0)
    be.plant.set_wall(ARM.fk(q0)[:3, 3] + 0.01 * d, -d)  # 1 cm ahead of the hand
    loop = ControlLoop(ARM, be, controller="none", realtime=False)
    loop.post(RunTrajectory(minimum_jerk(q0, q0 + [0.5, 0.0, 0.0], 1.0)))
    status = loop.run_for(6.0)
    assert status.fault is not None and "overload" in status.fault  # the servo's own alarm
    assert [s.regs.torque_enable for s in be.plant.servos] == [0, 0, 0]
    loop.post(Reset())
    status = loop.run_for(1.0)
    assert status.fault is None and status.active
    assert [s.regs.torque_enable for s in be.plant.servos] == [1, 1, 1]


@pytest.mark.slow
def test_a_target_dragged_near_a_joint_limit_moves_the_hand_without_a_fault():
    """The SO-101 folded on its shoulder_lift limit (where a serial arm rests and is
    caught): a target 2 cm aside and 2 cm down asks one RMRC step for some 10 rad/s of
    wrist_flex, which the loop took for unstable gains (torque off). The step is held to
    TARGET_MAX_JOINT_SPEED: no fault, the hand goes towards the target."""
    from armlab.app.arm.backends import loop_over, make_backend
    from armlab.control.loop import TARGET_MAX_JOINT_SPEED

    model = load_robot("so101")
    folded = np.radians([-0.09, 100.0, -24.43, 4.75, 0.0])
    backend = make_backend("sim", model, q0=folded)
    loop = loop_over(backend, model, DEFAULT, realtime=False, history_s=30.0)
    try:
        loop.run_for(1.0)
        start = model.fk(loop.recorder.snapshot(0.1)["q"][-1])[:3, 3]
        goal = start + np.array([0.0, 0.02, -0.02])  # partly beyond the folded arm's reach
        loop.post(SetTarget(goal))
        loop.run_for(5.0)
        assert loop.status.fault is None, loop.status.fault
        snap = loop.recorder.snapshot(6.0)
        steps = np.abs(np.diff(snap["q_cmd"], axis=0)) / DEFAULT.period
        assert np.nanmax(steps) <= TARGET_MAX_JOINT_SPEED + 1e-9
        here = model.fk(snap["q"][-1])[:3, 3]
        assert np.linalg.norm(here - goal) < np.linalg.norm(start - goal) - 0.01
    finally:
        backend.close()


@pytest.mark.slow
def test_an_arm_still_falling_when_its_torque_goes_on_is_caught_then_run_from_rest():
    """A limp SO-101 falling from upright (shoulder_lift at 10°) gets its torque on at
    speed, as a person's Reset may find a serial arm. Started at once, the reference
    (thesis eq. 2.20: driven by the arm's measured error and speed) wound up past the arm
    and drove it the other way until the loop faulted ("more than 29° from its
    reference", torque off: CI saw it on the emulated servos). The loop holds the goal
    where the arm was until the arm is at rest, then runs the controller from there; the
    trajectory asked meanwhile starts where the arm came to rest (no command jump)."""
    from armlab.app.arm.backends import make_backend
    from armlab.control.loop import CATCH_SPEED
    from armlab.control.trajectory import hold

    model = load_robot("so101")
    pose = np.radians([0.0, -30.0, 60.0, 20.0, 0.0])
    backend = make_backend("sim", model, q0=np.radians([0.0, 10.0, 0.0, 0.0, 0.0]))
    backend.set_torque(False)  # limp, as a serial arm's servos start
    loop = ControlLoop(model, backend, DEFAULT, realtime=False, history_s=30.0,
                       hold_off="a person confirms the arm is clear")
    try:
        while loop.status.t < 2.0:  # limp: it falls
            loop.step()
            q = loop.recorder.snapshot(0.1)["q"]
            if len(q) > 1 and np.max(np.abs(q[-1] - q[-2])) / DEFAULT.period > 6.0:
                break
        speed = np.abs(np.diff(loop.recorder.snapshot(0.1)["q"][-2:], axis=0)).max()
        assert speed / DEFAULT.period > 30 * CATCH_SPEED  # falling fast, 6 rad/s
        t_on = loop.status.t
        loop.post(Reset())
        loop.post(RunTrajectory(hold(pose, 0.2), approach=True))
        loop.step()
        assert loop.status.catching and loop.status.trajectory is None  # put off
        while loop.status.catching and loop.status.fault is None:
            loop.step()
        t_rest = loop.status.t - DEFAULT.period  # the first period of the controller
        assert t_rest - t_on < 1.0  # caught well inside CATCH_MAX
        st = loop.status
        assert st.fault is None and st.trajectory == "hold", st
        loop.run_for(8.0)
        assert loop.status.fault is None, loop.status.fault
        snap = loop.recorder.snapshot(30.0)
        t = snap["t"]
        caught = (t >= t_on - 1e-9) & (t < t_rest - 1e-9)
        # the catch holds one goal: where the arm was when its torque went on
        np.testing.assert_allclose(snap["q_ref"][caught], snap["q_ref"][caught][:1]
                                   .repeat(caught.sum(), axis=0))
        after = np.flatnonzero(t >= t_rest - 1e-9)
        rest = snap["q"][after[0]]
        # the approach starts where the arm rested, and the reference never ran away
        assert np.max(np.abs(snap["q_cmd"][after[0]] - rest)) < np.radians(0.5)
        lag = np.max(np.abs(snap["q_ref"][after] - snap["q"][after]))
        assert lag < np.radians(6.0), np.degrees(lag)  # without the catch: 19.6°
        assert np.max(np.abs(snap["q"][-1] - pose)) < np.radians(6.0)  # the push-free pose
    finally:
        backend.close()
