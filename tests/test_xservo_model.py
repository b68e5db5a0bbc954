"""The simulated X-series firmware (armlab/hardware/families/xseries/firmware.py) on the
OpenManipulator-X's chain:
the numbers of the e-manual's control tables and block diagrams, checked in motion.

- Position Control with the XM430-W350's factory gains reaches a 30° goal, and its
  steady error is the one the P gain predicts for the torque it holds (KPP = P/128
  PWM counts per count, 885 = full duty).
- Profile Velocity: the desired position moves at PV · 0.229 rpm.
- Current-based Position Control: Goal Current bounds the current, hence the torque.
- The D term damps with the horn's sensed velocity: the current a slowly turning horn
  reports has no spike where the encoder crosses a count.
- Overload: a servo held at full PWM without moving shuts its torque off after
  ``overload_time``, its alert stays until REBOOT.
- An injected Hardware Error Status flag (``armlab emulate --fault JOINT:FLAG@S``) comes
  after S s of torque on; the Shutdown register decides whether the torque goes off.
- The XL430-W250 has no current sensor: address 126 is Present Load (0.1 %).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from armlab.app.commands.emulate import parse_fault
from armlab.hardware.families.xseries.firmware import (
    HW_OVERLOAD,
    PROFILE_VELOCITY_UNIT,
    PWM_FULL,
    XRegisters,
    XServoModel,
)
from armlab.hardware.families.xseries.packets import HardwareError
from armlab.hardware.families.xseries.table import (
    CENTRE,
    XL430_W250,
    XM430_W350,
    XM430_W350_TABLE,
    OperatingMode,
)
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics import load_robot

OMX = load_robot("open_manipulator_x")
UNIT = XM430_W350.position_unit


def _counts(deg: float) -> int:
    return CENTRE + round(math.radians(deg) / UNIT)


def _plant(spec=XM430_W350, **kw) -> Plant:
    plant = Plant(OMX, spec, **kw)
    for s in plant.servos:
        s.regs.torque_enable = 1
    plant.advance_to(0.5)  # holding where torque came on
    return plant


def test_factory_registers_are_the_e_manuals():
    regs = XRegisters.factory(XM430_W350_TABLE)
    assert (regs.position_p_gain, regs.position_i_gain, regs.position_d_gain) == (800, 0, 0)
    assert (regs.velocity_p_gain, regs.velocity_i_gain) == (100, 1920)
    assert regs.current_limit == regs.goal_current == 1193
    assert regs.pwm_limit == regs.goal_pwm == 885 == PWM_FULL
    assert regs.shutdown == 52 and regs.operating_mode == OperatingMode.POSITION


def test_position_control_reaches_its_goal_with_the_p_gain_s_steady_error():
    plant = _plant()
    servo = plant.servos[1]
    servo.regs.goal_position = _counts(30.0)
    plant.advance_to(3.0)
    r = servo.report()
    assert r.moving == 0
    error = servo.desired - r.position  # counts
    # P only (I = D = 0): the PWM it holds is KPP · error, KPP = 800 / 128
    assert r.pwm == pytest.approx(800 / 128 * error, abs=800 / 128)
    assert abs(error) > 0  # gravity on joint 2: a P-only servo holds with an error
    assert math.degrees(plant.q[1]) == pytest.approx(30.0, abs=4.0)


def test_the_profile_moves_the_desired_position_at_profile_velocity():
    plant = _plant()
    servo = plant.servos[0]  # joint 1: about the vertical, no gravity load
    servo.regs.profile_velocity = 40  # 40 · 0.229 rpm
    servo.regs.goal_position = _counts(90.0)
    start = servo.desired
    plant.advance_to(0.7)
    speed = (servo.desired - start) / 0.2  # counts/s, no acceleration limit (PA = 0)
    assert speed == pytest.approx(40 * PROFILE_VELOCITY_UNIT, rel=0.02)
    plant.advance_to(2.5)
    assert servo.desired == _counts(90.0)
    assert math.degrees(plant.q[0]) == pytest.approx(90.0, abs=1.0)


def test_goal_current_bounds_the_current_in_current_based_position_control():
    plant = _plant()
    servo = plant.servos[0]
    servo.regs.operating_mode = OperatingMode.CURRENT_BASED_POSITION
    servo.regs.goal_current = 100  # 0.269 A
    servo.regs.goal_position = _counts(120.0)
    peak = 0
    for k in range(1, 200):
        plant.advance_to(0.5 + 0.005 * k)
        peak = max(peak, abs(plant.servos[0].report().current))
    assert 90 <= peak <= 100  # it pushes with all the current it may, never more


def test_the_d_term_damps_with_the_horn_velocity_not_the_encoder_s_count_steps():
    """Held at the centre with the lab's D gain while the horn turns at 0.05 rad/s (a count
    every 30 ticks or so): every tick the current is KPP · error − KPD · the velocity in
    counts per tick. The difference of two counts would put a 50-count (0.24 N·m) spike
    into the reading at every count crossed, and a reading's timing would decide the load."""
    regs = XRegisters.factory(XM430_W350_TABLE)
    regs.operating_mode = OperatingMode.CURRENT_BASED_POSITION
    regs.position_d_gain = 800
    regs.torque_enable = 1
    servo = XServoModel(XM430_W350, regs)
    dt, speed = 1e-3, 0.05  # s, rad/s
    per_tick = speed / UNIT * dt  # counts the horn turns in a tick
    currents = []
    for k in range(300):
        servo.update(dt, speed * k * dt, speed)
        r = servo.report()
        want = 800 / 128 * (CENTRE - r.position) - 800 / 16 * per_tick
        assert r.current == pytest.approx(want, abs=1.0)
        currents.append(r.current)
    assert np.max(np.abs(np.diff(currents))) <= 800 / 128 + 1  # the P term's count step


@pytest.mark.slow
def test_an_overload_shuts_the_torque_off_until_a_reboot():
    plant = _plant(params=ServoParams(overload_time=0.5))
    servo = plant.servos[1]
    servo.regs.goal_pwm = 885
    servo.regs.goal_position = _counts(30.0)
    plant.set_wall(np.array(OMX.fk(plant.q)[:3, 3]), np.array([0.0, 0.0, 1.0]),
                   stiffness=1e5, damping=50.0, link=3)  # a hard stop in its way
    plant.advance_to(3.0)  # stalled at full PWM against it for more than 0.5 s
    assert servo.hardware_error & HW_OVERLOAD and servo.regs.torque_enable == 0
    assert servo.duty == 0.0
    servo.regs.torque_enable = 1  # the servo does not take it back ...
    plant.advance_to(3.2)
    assert servo.regs.torque_enable == 0
    servo.reboot()  # ... until a REBOOT
    assert servo.hardware_error == 0
    servo.regs.torque_enable = 1
    plant.set_wall(None)
    plant.advance_to(3.5)
    assert servo.report().torque_enable == 1


def test_an_injected_flag_comes_after_its_torque_on_time_and_shutdown_decides_the_torque():
    """Shutdown's factory value 52 (0x34: Overheating, Electrical Shock, Overload): an
    overheating servo switches its torque off, one with its input voltage out of range
    keeps it; both raise their alert, which only a REBOOT clears (and it stays cleared)."""
    plant = Plant(OMX, XM430_W350)  # torque off
    hot, low = plant.servos[1], plant.servos[2]
    assert hot.regs.shutdown == 0x34
    hot.inject_error(HardwareError.OVERHEATING, after=0.5)
    low.inject_error(HardwareError.INPUT_VOLTAGE, after=0.5)
    plant.advance_to(1.0)
    assert hot.hardware_error == low.hardware_error == 0  # its clock runs with torque on
    for s in (hot, low):
        s.regs.torque_enable = 1
    plant.advance_to(1.4)
    assert hot.hardware_error == low.hardware_error == 0
    plant.advance_to(1.6)
    assert hot.report().hardware_error == 0x04 and hot.report().torque_enable == 0
    assert low.report().hardware_error == 0x01 and low.report().torque_enable == 1
    hot.reboot()
    hot.regs.torque_enable = 1
    plant.advance_to(3.0)
    assert hot.hardware_error == 0 and hot.report().torque_enable == 1  # once only
    for bits, after in ((0x02, 0.0), (0x40, 0.0), (0, 0.0), (0x20, -1.0)):
        with pytest.raises(ValueError, match="bits|after"):
            hot.inject_error(bits, after=after)


@pytest.mark.parametrize("text,want", [
    ("joint2:overload@3", (1, HardwareError.OVERLOAD, 3.0)),
    (" 0:Electrical_Shock@0 ", (0, HardwareError.ELECTRICAL_SHOCK, 0.0))])
def test_emulate_fault_takes_a_joint_a_flag_and_the_torque_on_time(text, want):
    assert parse_fault(text, OMX.joint_names) == want


@pytest.mark.parametrize("text,why", [("joint2:overload", "not JOINT:FLAG@S"),
                                      ("joint9:overload@1", "joint must be"),
                                      ("1:overlod@1", "no flag 'overlod'"),
                                      ("1:overload@-2", "must be >= 0")])
def test_a_bad_emulate_fault_gets_one_line_naming_the_flags(text, why):
    with pytest.raises(ValueError, match=why) as err:
        parse_fault(text, OMX.joint_names)
    msg = str(err.value)
    assert msg.startswith(f"--fault {text!r}: ") and "\n" not in msg
    assert "input_voltage, overheating, motor_encoder, electrical_shock, overload" in msg


def test_the_emulator_refuses_fault_on_protocol_1_servos_before_it_serves(capsys):
    from armlab.app.commands.cli import main

    assert main(["emulate", "--robot", "receptionist_arm", "--fault", "1:overload@1"]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # no "port: " line: nothing was served
    assert err.count("\n") == 1 and "RX-24F has none" in err


def test_the_xl430_reports_load_not_current():
    plant = _plant(spec=XL430_W250)
    r = plant.servos[1].report()
    torque = plant.servos[1].motor_torque(float(plant.qd[1]))
    assert r.current == round(torque / XL430_W250.stall_torque / 0.001)  # 0.1 % units
    assert abs(r.current) <= 1000


def test_a_model_without_current_sensing_has_no_current_torque():
    servo = XServoModel(XL430_W250)
    assert servo._current_torque(500) == 0.0
