"""The simulated Dynamixel firmware and motor (docs/servo-model.md), driven by raw registers."""

from pathlib import Path

import numpy as np
import pytest

from armlab.hardware.families.dynamixel1.firmware import (
    ERROR_ANGLE_LIMIT,
    ERROR_OVERLOAD,
    ServoModel,
    ServoRegisters,
    compliance_duty,
    effective_slope,
)
from armlab.hardware.servos.servo_spec import AX12A, DIRECTION_BIT, RX24F
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.urdf_read import chain_from_urdf

NO_FRICTION = ServoParams(coulomb_friction=0.0, viscous_friction=0.0)


@pytest.fixture(scope="module")
def turntable(tmp_path_factory):
    """One servo turning a 10 cm, 100 g rod about the vertical axis: no gravity load."""
    path = Path(tmp_path_factory.mktemp("urdf")) / "turntable.urdf"
    path.write_text("""<?xml version="1.0"?>
<robot name="turntable"><link name="base"/>
  <link name="rod"><inertial><origin xyz="0.05 0 0"/><mass value="0.1"/>
    <inertia ixx="1e-7" iyy="8.33e-5" izz="8.33e-5" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="turn" type="revolute"><parent link="base"/><child link="rod"/><axis xyz="0 0 1"/>
    <limit lower="-2.7" upper="2.7" effort="2.6" velocity="13"/></joint>
  <link name="tip"/><joint name="end" type="fixed"><parent link="rod"/><child link="tip"/>
    <origin xyz="0.1 0 0"/></joint></robot>""")
    return chain_from_urdf(path)


def regs(**kw) -> ServoRegisters:
    base = dict(torque_enable=1, goal_position=512, cw_compliance_margin=0,
                ccw_compliance_margin=0, cw_compliance_slope=64, ccw_compliance_slope=64)
    base.update(kw)
    return ServoRegisters(**base)


def test_effective_slope_has_the_seven_steps_of_table_2_4():
    table = {0: 2, 2: 2, 3: 2, 4: 4, 7: 4, 8: 8, 15: 8, 16: 16, 31: 16, 32: 32, 63: 32,
             64: 64, 127: 64, 128: 128, 254: 128, 255: 128}
    assert {raw: effective_slope(raw) for raw in table} == table


def test_compliance_curve_margin_punch_slope_limit():
    kw = dict(margin=3, slope=32, punch=32, torque_limit=1023)
    assert compliance_duty(3, **kw) == 0.0  # inside the margin: no torque
    assert compliance_duty(-2, **kw) == 0.0
    assert compliance_duty(3.0001, **kw) == pytest.approx(32, abs=0.01)  # punch at the edge
    # Rising linearly across the slope region, reaching the limit after `slope` counts.
    assert compliance_duty(3 + 16, **kw) == pytest.approx(32 + 16 * (1023 - 32) / 32)
    assert compliance_duty(3 + 32, **kw) == pytest.approx(1023)
    assert compliance_duty(200, **kw) == 1023
    assert compliance_duty(200, margin=3, slope=32, punch=32, torque_limit=300) == 300


def test_goal_step_settles_inside_the_compliance_margin(turntable):
    r = regs(cw_compliance_margin=4, ccw_compliance_margin=4, cw_compliance_slope=32,
             ccw_compliance_slope=32)
    plant = Plant(turntable, RX24F, q0=[0.0], registers=[r])
    r.goal_position = 512 + 60  # a 17.6° step
    plant.advance_to(1.0)
    rep = plant.servo_report(0)
    assert abs(rep.position - 572) <= 4
    assert rep.load == 0  # inside the margin the servo applies no torque
    assert rep.moving == 0
    assert abs(plant.qd[0]) < 1e-3


@pytest.mark.parametrize("spec", [RX24F, AX12A])
def test_free_running_speed_is_the_no_load_speed(turntable, spec):
    r = regs(goal_position=1010)
    plant = Plant(turntable, spec, q0=[spec.raw_to_position(20)], params=NO_FRICTION,
                  registers=[r], stops=None)
    plant.advance_to(0.2)
    assert plant.qd[0] == pytest.approx(spec.no_load_speed, rel=0.01)
    reported = spec.raw_to_present_speed(plant.servo_report(0).speed)
    if spec is AX12A:  # 59 rpm = 531.5 units of 0.111 rpm
        assert reported == pytest.approx(spec.no_load_speed, abs=spec.speed_unit)
    else:  # 126 rpm is beyond the register's 1023 units (113.6 rpm): it saturates
        assert plant.servo_report(0).speed == 1023
    assert plant.servo_report(0).load == 1023


def test_moving_speed_limits_the_set_point(turntable):
    r = regs(goal_position=900, moving_speed=300)  # 300 × 0.111 rpm = 3.487 rad/s
    plant = Plant(turntable, RX24F, q0=[RX24F.raw_to_position(100)], registers=[r])
    plant.advance_to(0.5)
    v = RX24F.raw_to_present_speed(plant.servo_report(0).speed)
    assert v == pytest.approx(300 * RX24F.speed_unit, rel=0.03)
    assert plant.servo_report(0).moving == 1


def test_load_saturates_at_the_torque_limit_against_a_wall(turntable):
    for limit in (1023, 512):
        r = regs(goal_position=800, torque_limit=limit)
        plant = Plant(turntable, RX24F, q0=[0.0], registers=[r])
        # A wall 5 cm beyond the rod's tip when it has turned ~30°: it pushes into it.
        plant.set_wall([0.0, 0.06, 0.0], [0.0, -1.0, 0.0], stiffness=2e4, damping=50)
        plant.advance_to(0.5)
        rep = plant.servo_report(0)
        assert rep.load == limit  # CCW load, full torque limit
        assert abs(plant.qd[0]) < 0.01
        # The stall torque the servo presses with: limit/1023 of 2.6 N·m.
        assert plant.truth().motor_torque[0] == pytest.approx(2.6 * limit / 1023, rel=0.01)
        assert plant.truth().external_torque[0] == pytest.approx(-2.6 * limit / 1023, rel=0.02)
        assert rep.error == 0


def test_overload_shuts_the_servo_down_until_torque_limit_is_written(turntable):
    r = regs(goal_position=800)
    plant = Plant(turntable, RX24F, q0=[0.0], registers=[r])
    plant.set_wall([0.0, 0.06, 0.0], [0.0, -1.0, 0.0], stiffness=2e4, damping=50)
    plant.advance_to(1.9)
    assert plant.servo_report(0).error == 0
    plant.advance_to(2.2)
    rep = plant.servo_report(0)
    assert rep.error & ERROR_OVERLOAD
    assert (rep.torque_enable, rep.torque_limit, rep.load) == (0, 0, 0)
    plant.set_wall(None)
    r.torque_enable = 1  # not enough: the torque limit is still 0
    plant.advance_to(2.4)
    assert plant.servo_report(0).error & ERROR_OVERLOAD
    r.torque_limit = 1023
    plant.advance_to(2.5)
    assert plant.servo_report(0).error == 0
    assert plant.servo_report(0).load > 0


def test_goal_outside_angle_limits_sets_the_error_and_stops_at_the_limit(turntable):
    r = regs(cw_angle_limit=400, ccw_angle_limit=600, goal_position=700)
    plant = Plant(turntable, RX24F, q0=[0.0], registers=[r])
    plant.advance_to(1.0)
    rep = plant.servo_report(0)
    assert rep.error == ERROR_ANGLE_LIMIT
    assert abs(rep.position - 600) <= 1
    r.goal_position = 550
    plant.advance_to(1.5)
    assert plant.servo_report(0).error == 0


def test_torque_off_reports_no_load_and_the_servo_is_free(turntable):
    r = regs(torque_enable=0, goal_position=800)
    plant = Plant(turntable, RX24F, q0=[0.0], qd0=[1.0], registers=[r])
    plant.advance_to(0.1)
    assert plant.servo_report(0).load == 0
    assert plant.q[0] > 0.05  # coasting on, slowed only by gear friction
    assert plant.servo_report(0).torque_enable == 0


def test_present_position_is_the_10_bit_quantised_angle():
    servo = ServoModel(RX24F, regs(), angle=0.0)
    for angle, raw in ((0.0, 512), (np.radians(150), 1023), (np.radians(-150.2), 0),
                       (np.radians(0.14), 512), (np.radians(0.15), 513), (3.0, 1023)):
        servo.update(1e-3, angle, 0.0)
        assert servo.present_position() == raw
    for angle in np.random.default_rng(5).uniform(-2.7, 2.7, 200):
        servo.update(1e-3, angle, 0.0)
        assert servo.present_position() == RX24F.position_to_raw(angle)


def test_load_word_direction_bit_when_pushing_clockwise():
    servo = ServoModel(RX24F, regs(goal_position=500), angle=0.0)
    servo.update(1e-3, 0.0, 0.0)
    load = servo.present_load()
    assert load & DIRECTION_BIT
    # 12 counts of CW error at slope 64: punch 32 + 12 × 991/64 = 217.8 -> 218.
    assert load & 0x3FF == 218
    assert RX24F.raw_to_load(load) == pytest.approx(-2.6 * 218 / 1023)


def test_wheel_mode_runs_open_loop(turntable):
    r = regs(cw_angle_limit=0, ccw_angle_limit=0, moving_speed=DIRECTION_BIT | 512)
    plant = Plant(turntable, RX24F, q0=[0.0], params=NO_FRICTION, registers=[r], stops=None)
    plant.advance_to(0.1)
    # Half duty: half the no-load speed, clockwise.
    assert plant.qd[0] == pytest.approx(-RX24F.no_load_speed * 512 / 1023, rel=0.01)
