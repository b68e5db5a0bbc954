"""SimBackend: the Backend protocol over the simulated arm, as a controller sees it."""

import numpy as np
import pytest

from armlab.app.arm.backends import make_backend
from armlab.control.backend import Backend, BackendError, Pushable
from armlab.hardware.families.dynamixel1.firmware import ERROR_OVERLOAD
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.servos.servo_spec import AX12A, RX24F
from armlab.kinematics import load_robot


@pytest.fixture(scope="module")
def arm():
    return load_robot("receptionist_arm")


def test_implements_backend_and_pushable(arm):
    b = SimBackend(arm)
    assert isinstance(b, Backend) and isinstance(b, Pushable)
    assert b.n == 3
    # Model limits within the servos' 300° range: theta0 keeps its ±90°, the others are
    # cut to the RX-24F's [-150.15°, +149.85°] (raw 0..1023 around 512).
    np.testing.assert_allclose(np.degrees(b.lower), [-150, -90, -150], atol=0.01)
    np.testing.assert_allclose(np.degrees(b.upper), [149.85, 90, 149.85], atol=0.01)


def test_configured_as_the_thesis_does(arm):
    b = SimBackend(arm)
    for servo in b.plant.servos:
        r = servo.regs
        assert (r.cw_compliance_margin, r.ccw_compliance_margin) == (0, 0)
        assert (r.cw_compliance_slope, r.ccw_compliance_slope) == (64, 64)
        assert r.torque_limit == 1023 and r.torque_enable == 1


def test_write_read_round_trip(arm):
    b = SimBackend(arm, q0=[0.0, 0.3, 0.3])
    goal = np.array([0.3, 0.5, 0.8])
    b.write(goal, np.full(3, 1.0))
    assert [s.regs.goal_position for s in b.plant.servos] == [
        RX24F.position_to_raw(x) for x in goal]
    assert [s.regs.moving_speed for s in b.plant.servos] == [RX24F.speed_to_raw(1.0)] * 3
    b.sync(2.0)
    state = b.read()
    assert state.t == pytest.approx(2.0)
    truth = b.plant.truth()
    # What is read is the truth quantised to 10 bits (0.29°), sampled at the servos'
    # last firmware tick (1 ms before) ...
    np.testing.assert_allclose(state.position, truth.q, atol=RX24F.position_unit)
    assert np.all(np.abs(state.position / RX24F.position_unit
                         - np.round(state.position / RX24F.position_unit)) < 1e-9)
    # ... and near the goal up to the servos' compliance droop under gravity (< 3°).
    assert np.abs(state.position - goal).max() < np.radians(3)
    # The load reads the torque holding the arm (estimated from the duty).
    assert np.abs(state.load - truth.motor_torque).max() < 2.6 / 1023 * 1.5 + 0.01
    assert state.errors == (0, 0, 0) and state.torque_on == (True, True, True)


def test_goals_are_clamped_into_the_limits(arm):
    b = SimBackend(arm)
    b.write(np.array([10.0, -10.0, 0.0]), np.array([1e9, 0.0, 1e-6]))
    regs = [s.regs for s in b.plant.servos]
    assert regs[0].goal_position == RX24F.position_to_raw(b.upper[0])
    assert regs[1].goal_position == RX24F.position_to_raw(-np.pi / 2)
    # Speeds: the maximum 1023; a zero or tiny speed is the slowest unit, never 0 (= no limit).
    assert [r.moving_speed for r in regs] == [1023, 1, 1]
    assert all(s.error() == 0 for s in b.plant.servos)


@pytest.mark.parametrize("position,speed,match", [
    ([np.nan, 0, 0], [1, 1, 1], "position"),
    ([0, 0, 0], [1, np.inf, 1], "speed"),
    ([0, 0], [1, 1, 1], "position"),
])
def test_non_finite_or_misshaped_goals_are_refused_and_nothing_written(arm, position, speed,
                                                                       match):
    b = SimBackend(arm, q0=[0.1, 0.2, 0.3])
    before = [(s.regs.goal_position, s.regs.moving_speed) for s in b.plant.servos]
    with pytest.raises(ValueError, match=match):
        b.write(np.array(position, dtype=float), np.array(speed, dtype=float))
    assert [(s.regs.goal_position, s.regs.moving_speed) for s in b.plant.servos] == before


def test_push_displaces_the_arm_and_release_returns_it(arm):
    b = SimBackend(arm, q0=[0.0, 0.6, 0.6])
    b.sync(0.5)
    rest, rest_load = b.read().position, b.read().load
    b.push(np.array([0.0, -4.0, 0.0]), link=2, point=arm.tip[:3, 3], duration=0.6)
    b.sync(1.0)
    pushed = b.read()
    assert np.abs(pushed.position - rest).max() > np.radians(3)
    # The servos feel it: the load readings move away from holding the arm alone.
    assert np.abs(pushed.load - rest_load).max() > 0.3
    b.sync(2.5)
    assert np.abs(b.read().position - rest).max() <= np.radians(1)


def test_estop_and_torque_on_again(arm):
    b = SimBackend(arm, q0=[0.0, 1.0, 0.0])
    b.sync(0.2)
    b.estop()
    b.sync(0.4)
    state = b.read()
    assert state.torque_on == (False, False, False)
    assert np.all(state.load == 0)
    b.set_torque(True)
    b.sync(0.5)
    assert b.read().torque_on == (True, True, True)


def test_set_torque_recovers_an_overload_shutdown(arm):
    b = SimBackend(arm, q0=[0.0, 0.0, 0.0])
    b.plant.set_wall([0.0, 0.05, 0.0], [0.0, -1.0, 0.0], stiffness=2e4, damping=50)
    b.write(np.array([0.0, 0.0, 1.0]), np.full(3, 20.0))
    b.sync(2.6)
    state = b.read()
    # The hand presses on the wall: the servo stalled at full torque for 2 s shuts down.
    tripped = [i for i in range(3) if state.errors[i] & ERROR_OVERLOAD]
    assert tripped and not any(state.torque_on[i] for i in tripped)
    b.plant.set_wall(None)
    b.set_torque(True)
    b.sync(2.8)
    state = b.read()
    assert state.errors == (0, 0, 0) and all(state.torque_on)


def test_closed_backend_raises_backend_error(arm):
    b = SimBackend(arm)
    b.close()
    with pytest.raises(BackendError, match="closed"):
        b.read()
    b.estop()  # must not raise


def test_ax12a_and_mirrored_servos(arm):
    b = SimBackend(arm, specs=AX12A, q0=[0.2, 0.3, 0.4], directions=[1, -1, 1])
    b.sync(0.3)
    np.testing.assert_allclose(b.read().position, b.plant.q, atol=AX12A.position_unit)
    np.testing.assert_allclose(b.read().position, [0.2, 0.3, 0.4], atol=np.radians(4))
    assert b.plant.servos[1].regs.goal_position == AX12A.position_to_raw(-0.3)
    assert b.plant.servos[1].present_position() == AX12A.position_to_raw(-b.read().position[1])


def test_make_backend(arm):
    assert isinstance(make_backend("sim", arm, q0=[0, 0.1, 0]), SimBackend)
    with pytest.raises(ValueError, match="unknown backend"):
        make_backend("usb", arm)
    with pytest.raises(ValueError, match="port"):
        make_backend("sim", arm, port="/dev/ttyUSB0")
    with pytest.raises(ValueError, match="port"):
        make_backend("serial", arm)
