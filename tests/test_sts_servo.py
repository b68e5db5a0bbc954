"""The simulated STS3215: its position loop, torque limit, current reading, supply scaling
and overload, alone and in the plant."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armlab.hardware.families.feetech.firmware import KP_UNIT, StsRegisters, StsServoModel
from armlab.hardware.families.feetech.packets import ErrorBits
from armlab.hardware.families.feetech.table import CENTRE, CURRENT_UNIT, STS3215, STS3215_TABLE
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.catalog import load_robot


def held(model: StsServoModel, seconds: float, *, angle: float = 0.0) -> None:
    """Tick the firmware with the horn held still at ``angle``."""
    for _ in range(round(seconds / 1e-3)):
        model.update(1e-3, angle, 0.0)


def test_the_datasheet_figures_scale_with_the_supply():
    at5 = StsServoModel(STS3215, params=ServoParams(voltage=5.0))
    assert at5.stall_torque == pytest.approx(16.5 * 0.0980665 * 5 / 6)
    assert at5.no_load_speed == pytest.approx(45 * 2 * math.pi / 60 * 5 / 6)
    assert STS3215_TABLE.spec.model_number == 777


def test_the_p_coefficient_sets_the_duty_and_the_torque_limit_bounds_it():
    regs = StsRegisters.factory(STS3215_TABLE, goal_position=CENTRE + 10)
    regs.torque_enable = 1
    servo = StsServoModel(STS3215, regs)
    held(servo, 0.002)
    assert servo.duty == pytest.approx(32 * KP_UNIT * 10)  # P 32, 10 counts of error
    regs.goal_position = CENTRE + 1000
    regs.torque_limit = 100  # 10 % of full
    held(servo, 0.002)
    assert servo.duty == pytest.approx(0.1)
    assert servo.drive == pytest.approx(0.1 * servo.stall_torque)
    report = servo.report()
    assert report.load == 100
    torque = 0.1 * servo.stall_torque  # at rest: the whole drive
    assert report.current == round(torque / STS3215.torque_constant / CURRENT_UNIT)
    regs.goal_position = CENTRE - 1000
    held(servo, 0.002)
    assert servo.report().load == -100  # CW: the sign of the load


def test_torque_off_drives_nothing():
    servo = StsServoModel(STS3215)
    servo.regs.goal_position = CENTRE + 500
    held(servo, 0.01)
    assert servo.drive == 0.0 and servo.report().current == 0


def test_a_stall_at_the_limit_raises_overload_and_holds_to_overload_torque():
    regs = StsRegisters.factory(STS3215_TABLE, goal_position=CENTRE + 2000)
    regs.torque_enable, regs.overload_torque = 1, 25
    servo = StsServoModel(STS3215, regs, params=ServoParams(voltage=5.0, overload_time=0.5))
    held(servo, 0.4)
    assert servo.error() == 0 and servo.duty == pytest.approx(1.0)
    held(servo, 0.2)
    assert servo.error() & ErrorBits.OVERLOAD
    assert servo.duty == pytest.approx(0.25)
    regs.torque_enable = 0
    held(servo, 0.002)
    regs.torque_enable = 1
    held(servo, 0.002)
    assert servo.error() == 0  # torque off and on again clears it


def test_goal_speed_paces_the_desired_position():
    regs = StsRegisters.factory(STS3215_TABLE, goal_position=CENTRE + 1000)
    regs.torque_enable, regs.goal_speed = 1, 500  # counts/s
    servo = StsServoModel(STS3215, regs)
    held(servo, 0.5)
    assert servo.desired == pytest.approx(CENTRE + 250, abs=2)
    assert servo.report().moving == 1


def test_sts3215s_hold_an_arm_in_the_plant():
    arm = load_robot("receptionist_arm")
    plant = Plant(arm, STS3215, q0=np.zeros(arm.n))
    assert all(type(s) is StsServoModel for s in plant.servos)
    for s in plant.servos:
        s.regs.torque_enable = 1
    plant.advance_to(1.5)
    assert np.max(np.abs(plant.q)) < math.radians(5)  # holds near its goal
    reports = plant.reports()
    assert all(r.voltage == 60 for r in reports)  # the datasheet's supply by default


# -- the emulated STS servos' instruction semantics (no pty: the network itself) -------

def _send(net, packet: bytes, baud: float = 1_000_000):
    from armlab.hardware.families.feetech import packets as ft

    return [ft.decode_status(r) for _, r in net.handle(ft.decode_instruction(packet),
                                                       baud=baud)]


def _so101_network():
    from armlab.hardware.families.feetech.emulator import emulated_sts_network

    return emulated_sts_network(load_robot("so101"), [1, 2, 3, 4, 5])


def test_eeprom_writes_need_the_lock_open_as_lerobot_opens_it():
    from armlab.hardware.families.feetech import packets as ft

    net = _so101_network()
    s = net.servos[0]
    (st,) = _send(net, ft.write(1, 21, bytes((16,))))  # P coefficient, locked
    assert st.error == 0 and s.get("p_coefficient") == 32
    _send(net, ft.write(1, 55, bytes((0,))))  # Lock 0
    _send(net, ft.write(1, 21, bytes((16,))))
    assert s.get("p_coefficient") == 16
    assert net.physics.plant.servos[0].regs.p_coefficient == 16  # the firmware has it
    _send(net, ft.write(1, 31, STS3215_TABLE.encode("homing_offset", -300)[1]))
    assert s.get("homing_offset") == -300


def test_reg_write_waits_for_action_and_reset_restores_the_factory_table():
    from armlab.hardware.families.feetech import packets as ft

    net = _so101_network()
    s = net.servos[2]
    goal = s.get("present_position") + 200
    _send(net, ft.reg_write(3, 42, STS3215_TABLE.encode("goal_position", goal)[1]))
    assert s.get("goal_position") != goal
    assert _send(net, ft.action()) == []  # broadcast: no reply
    assert s.get("goal_position") == goal
    _send(net, ft.write(3, 55, bytes((0,))))
    _send(net, ft.write(3, 5, bytes((9,))))  # ID 9
    assert s.servo_id == 9
    _send(net, ft.reset(9, confirm=True))
    assert s.servo_id == 1 and s.get("lock") == 1


def test_sync_read_answers_in_the_order_named_and_read_only_items_stay():
    from armlab.hardware.families.feetech import packets as ft

    net = _so101_network()
    answers = _send(net, ft.sync_read(3, 2, [5, 2, 4]))
    assert [(a.servo_id, int.from_bytes(a.params, "little")) for a in answers] == \
        [(5, 777), (2, 777), (4, 777)]
    _send(net, ft.write(2, 3, (1).to_bytes(2, "little")))  # model number: read-only
    assert net.servos[1].get("model_number") == 777
