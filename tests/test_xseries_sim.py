"""XSimBackend: the OpenManipulator-X simulated with its own servos (XM430-W350), as the
lab opens it (``make_backend("sim", ...)`` for an arm that ships with X-series servos).

Its readings are the servos' raw values decoded (4096 counts a turn, the current's
unit); it holds its pose, follows a goal at the given speed, reports the torque that
holds the arm up, and an overload shutdown needs the REBOOT that torque-on sends.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from armlab.app.arm.backends import make_backend
from armlab.control.experiments.thesis import line_plan, run_line
from armlab.control.params import preset
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.families.xseries.sim_backend import XSimBackend
from armlab.hardware.families.xseries.table import (
    CURRENT_POSITION_D_GAIN,
    XM430_W350,
    OperatingMode,
)
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import rnea

OMX = load_robot("open_manipulator_x")
COUNT = XM430_W350.position_unit


def test_the_lab_simulates_open_manipulator_x_with_its_own_servos():
    b = make_backend("sim", OMX)
    assert isinstance(b, XSimBackend)
    assert all(s.regs.operating_mode == OperatingMode.CURRENT_BASED_POSITION
               for s in b.plant.servos)
    assert all(s.regs.goal_current == 1193 for s in b.plant.servos)
    assert not isinstance(make_backend("sim", load_robot("receptionist_arm")), XSimBackend)
    assert type(make_backend("sim", load_robot("receptionist_arm"))) is SimBackend


def test_readings_are_the_servos_counts_and_the_torque_holds_the_arm_up():
    b = XSimBackend(OMX, spec=XM430_W350)
    b.sync(1.0)
    s = b.read()
    counts = s.position / COUNT
    assert np.allclose(counts, np.round(counts), atol=1e-9)  # 4096 a turn, quantised
    gravity = rnea(OMX, b.plant.q, np.zeros(4), np.zeros(4))
    # the measured current's torque (2.69 mA a count) is the gravity torque it holds
    assert s.load == pytest.approx(gravity, abs=0.05)


def test_a_goal_is_followed_at_its_speed():
    b = XSimBackend(OMX, spec=XM430_W350)
    b.sync(0.5)
    start = b.read().position
    goal = start + np.array([math.radians(60), 0.0, 0.0, 0.0])
    b.write(goal, np.array([0.5, 1.0, 1.0, 1.0]))  # joint 1 at 0.5 rad/s: about 2 s
    b.sync(1.5)
    moved = b.read().position[0] - start[0]
    assert moved == pytest.approx(0.5, abs=0.08)  # 1 s at 0.5 rad/s
    b.sync(4.0)
    assert b.read().position[0] == pytest.approx(goal[0], abs=math.radians(1.0))


def test_torque_on_reboots_a_servo_that_shut_down():
    b = XSimBackend(OMX, spec=XM430_W350)
    servo = b.plant.servos[1]
    servo._hardware_error = 0x20  # an overload the firmware reported
    b.sync(0.1)
    assert not b.read().torque_on[1]
    assert b.read().alarms[1].startswith("Overload (Hardware Error Status 0x20)")
    b.set_torque(True)
    b.sync(0.2)
    assert all(b.read().torque_on) and b.read().errors[1] == 0


@pytest.mark.slow
def test_the_compliance_loop_holds_open_manipulator_x_steady():
    """The thesis gains on the X-series arm: holding the line's start, the shoulder stays
    within a few counts of the thesis servos (without the Position D Gain the backends
    write, it swings by about 20° peak to peak: the current loop cancels the back-EMF)."""
    b = make_backend("sim", OMX)
    assert all(s.regs.position_d_gain == CURRENT_POSITION_D_GAIN for s in b.plant.servos)
    run = run_line(OMX, lambda model, **kw: b, preset("well-damped default"),
                   controller="compliance")
    snap = run.snapshot
    plan, _, _ = line_plan(OMX)
    at_start = np.all(np.abs(snap["q_cmd"] - plan.q[0]) < 1e-9, axis=1)  # holding the start
    t_hold = snap["t"][at_start]
    assert t_hold[-1] - t_hold[0] > 0.8
    holding = at_start & (snap["t"] > t_hold[0] + 0.3)  # after 0.3 s to settle
    swing = np.ptp(snap["q"][holding], axis=0)
    assert np.all(swing < math.radians(2.5)), np.degrees(swing)
