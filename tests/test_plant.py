"""The simulated arm: rigid body + servos + pushes, springs and a wall
(armlab.hardware.sim.plant)."""

import numpy as np
import pytest

from armlab.hardware.families.dynamixel1.firmware import ServoRegisters
from armlab.hardware.families.dynamixel1.sim_backend import thesis_registers
from armlab.hardware.servos.servo_spec import RX24F
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import IDEAL
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import potential_energy
from armlab.kinematics.points import point_force_torques, point_position


@pytest.fixture(scope="module")
def arm():
    return load_robot("receptionist_arm")


def holding(arm, q0, **kw) -> Plant:
    """The arm with the thesis's servo settings, holding q0."""
    regs = [thesis_registers(RX24F, goal=RX24F.position_to_raw(q), cw_limit=0, ccw_limit=1023)
            for q in q0]
    return Plant(arm, RX24F, q0=q0, registers=regs, **kw)


def test_unactuated_undamped_arm_conserves_energy(arm):
    """Torque off, no friction, no rotor: the arm swings freely for 2 s and keeps its
    mechanical energy (above hanging at rest) within 0.5 %."""
    plant = Plant(arm, RX24F, q0=[0.5, 0.8, -0.6], qd0=[1.0, -0.5, 2.0], params=IDEAL,
                  stops=None)
    rest = potential_energy(arm, np.zeros(3))
    e0 = sum(plant.energy()) - rest
    worst = 0.0
    for _ in range(20):
        plant.advance_to(plant.t + 0.1)
        worst = max(worst, abs(sum(plant.energy()) - rest - e0))
    assert plant.t == pytest.approx(2.0)
    assert np.ptp(plant.q) > 0.5  # it did swing
    assert worst < 0.005 * e0


def test_torque_off_arm_falls_to_hanging(arm):
    plant = Plant(arm, RX24F, q0=[0.0, 1.2, 0.0])  # torque off, with gear friction and rotor
    plant.advance_to(3.0)
    assert abs(plant.q[1]) < 0.5 * 1.2  # swung down, damped by the gear friction
    assert plant.reports()[1].load == 0


def test_servos_hold_the_arm_against_gravity_with_the_compliance_droop(arm):
    q0 = np.array([0.0, 1.0, 0.0])  # upper arm and forearm lifted 57° from hanging
    plant = holding(arm, q0)
    plant.advance_to(1.0)
    truth = plant.truth()
    # The shoulder servo carries the static load ...
    gravity = (0.176 * 0.0925 + 0.19 * 0.31) * 9.81 * np.sin(truth.q[1])
    assert truth.motor_torque[1] + truth.friction_torque[1] == pytest.approx(gravity, rel=0.02)
    # ... by the droop its compliance slope needs: about 7.7 N·m/rad at slope 64.
    droop = q0[1] - truth.q[1]
    assert 0.03 < droop < 0.12
    assert abs(truth.qd).max() < 1e-3


def test_push_displaces_the_arm_and_it_returns(arm):
    q0 = np.array([0.0, 0.5, 0.5])
    plant = holding(arm, q0)
    plant.advance_to(0.5)
    before = plant.q
    hand = arm.tip[:3, 3]
    plant.push([0.0, -3.0, 0.0], link=2, point=hand, duration=0.5)  # 3 N, base frame -y
    plant.advance_to(0.9)
    pushed = plant.truth()
    expected = point_force_torques(arm, pushed.q, 2, hand, [0.0, -3.0, 0.0])
    np.testing.assert_allclose(pushed.external_torque, expected, atol=0.05)
    assert np.abs(pushed.q - before).max() > 0.05
    plant.advance_to(2.0)
    assert np.abs(plant.truth().external_torque).max() == 0.0
    assert np.abs(plant.q - before).max() < 0.02


def test_spring_drags_the_hand_towards_the_anchor_when_torque_is_off(arm):
    plant = Plant(arm, RX24F, q0=[0.0, 0.0, 0.0])
    hand = arm.tip[:3, 3]
    anchor = np.array([0.35, 0.2, 0.0])
    plant.set_spring(anchor, stiffness=200.0, link=2, point=hand, damping=5.0)
    plant.advance_to(3.0)
    # Spring 200 N/m against 3.6 N of arm weight: the hand ends within a few cm.
    assert np.linalg.norm(point_position(arm, plant.q, 2, hand) - anchor) < 0.03
    plant.set_spring(None, stiffness=0, link=2, point=hand)
    assert np.abs(plant.truth().external_torque).max() == 0.0


def test_wall_stops_the_hand(arm):
    plant = holding(arm, np.zeros(3))
    for servo in plant.servos:
        servo.regs.goal_position = RX24F.position_to_raw(0.8)
    # A wall across the hand's path: the plane y = 0.15 m (base frame), free side y < 0.15.
    plant.set_wall([0.0, 0.15, 0.0], [0.0, -1.0, 0.0], stiffness=5000, damping=30)
    plant.advance_to(1.0)
    hand_y = point_position(arm, plant.q, 2, arm.tip[:3, 3])[1]
    # The servos press with their stall torque: a few N, a couple of mm into 5000 N/m.
    assert 0.15 < hand_y < 0.155
    assert np.abs(plant.truth().external_torque).max() > 0.5


def test_stiffest_servo_setting_stays_bounded(arm):
    regs = [ServoRegisters(torque_enable=1, goal_position=600, cw_compliance_margin=0,
                           ccw_compliance_margin=0, cw_compliance_slope=2,
                           ccw_compliance_slope=2) for _ in range(3)]
    plant = Plant(arm, RX24F, registers=regs)
    plant.advance_to(1.0)
    worst = 0
    for _ in range(1000):
        plant.step()
        worst = max(worst, *(abs(r.position - 600) for r in plant.reports()))
    # Slope 2 is ~250 N·m/rad: the quantised loop buzzes by a few counts, no more.
    assert worst <= 4


def test_joint_stop_catches_a_falling_arm(arm):
    plant = Plant(arm, RX24F, q0=[0.0, -1.5, 0.0], qd0=[0.0, -3.0, 0.0])
    lowest, pushed = plant.q[1], 0.0
    for k in range(1, 301):  # 0.3 s, looked at every ms
        plant.advance_to(k * 1e-3)
        lowest = min(lowest, plant.q[1])
        pushed = max(pushed, plant.truth().stop_torque[1])
    assert arm.lower[1] - 0.15 < lowest < arm.lower[1]  # it reached the stop, not far past
    assert pushed > 0.1  # N·m: the stop pushed back
    assert plant.q[1] > lowest + 0.5  # and sent it back up


def test_directions_mirror_the_servo(arm):
    plant = Plant(arm, RX24F, q0=[0.2, 0.3, -0.4], directions=[1, -1, -1])
    positions = [r.position for r in plant.reports()]
    assert positions == [RX24F.position_to_raw(0.2), RX24F.position_to_raw(-0.3),
                         RX24F.position_to_raw(0.4)]


def test_advance_to_takes_whole_steps(arm):
    plant = Plant(arm, RX24F, dt=2e-3)
    assert plant.advance_to(0.1) == 50
    assert plant.advance_to(0.1) == 0
    assert plant.advance_to(0.1009) == 0
    assert plant.advance_to(0.1011) == 1


def test_bad_arguments_are_refused_with_their_name(arm):
    plant = Plant(arm, RX24F)
    with pytest.raises(ValueError, match="force_base"):
        plant.push([np.nan, 0, 0], link=2, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="link"):
        plant.push([1, 0, 0], link=5, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="dt"):
        Plant(arm, RX24F, dt=0.0)
    with pytest.raises(ValueError, match="specs"):
        Plant(arm, [RX24F, RX24F])


def _readable(plant: Plant) -> None:
    """One step of ``plant`` through its readable RK4 (Plant._readable_step), as
    Plant.step takes it when no stop, spring or wall acts."""
    if plant._pushes:
        plant._update_pushes(plant._q)
    plant._readable_step(plant._q, plant._qd, plant._held_torques(), [], stops=False)
    plant._k += 1


@pytest.mark.parametrize("params", [None, IDEAL], ids=["friction", "ideal"])
def test_the_straight_line_step_equals_the_readable_one_bit_for_bit(arm, params):
    """Plant.step's generated step (armlab.hardware.sim.plant_step) and the readable RK4
    give the same state to the last bit, step after step: servos moving to a goal, a push
    that ends, applied joint torques that start and add up."""
    q0 = [0.3, 0.6, -0.4]
    fast, readable = holding(arm, q0, params=params), holding(arm, q0, params=params)
    for plant in (fast, readable):
        for servo, goal in zip(plant.servos, (700, 400, 600), strict=True):
            servo.regs.goal_position = goal
        plant.push([2.0, -1.0, 0.5], link=2, point=[0.1, 0.0, 0.0], duration=0.2)
        plant.apply_joint_torque(1, 0.3, start=0.1)
        plant.apply_joint_torque(1, -0.1, start=0.3)
    for _ in range(500):
        fast.step()
        _readable(readable)
        assert fast._q == readable._q and fast._qd == readable._qd
    assert fast.t == readable.t and abs(fast.q - np.array(q0)).max() > 0.1  # it moved


def _readable_with_fields(plant: Plant) -> None:
    """One step of ``plant`` through its readable RK4 with its spring and wall (the
    touches near the wall held from the step's start), as Plant.step took every such
    step before its straight-line step took them too."""
    if plant._pushes:
        plant._update_pushes(plant._q)
    stops = plant.stops is not None and any(
        x < lo + 0.05 or x > hi - 0.05
        for x, lo, hi in zip(plant._q, plant._lower, plant._upper, strict=True))
    plant._readable_step(plant._q, plant._qd, plant._held_torques(), plant._near_touches(),
                         stops=stops)
    plant._k += 1


@pytest.mark.parametrize("shape", ["plane", "box"])
def test_the_straight_line_step_with_a_wall_and_a_spring_equals_the_readable_one(arm, shape):
    """With a wall (a plane the hand meets, with friction; or a box the links' balls
    meet) and a spring, Plant.step's generated step re-evaluates their torques at each
    RK4 stage as the readable step does: the same state to the last bit, step after
    step, through the impact, the pressing and the spring's release."""
    q0 = [0.0, 0.5, 0.6]
    fast, readable = holding(arm, q0), holding(arm, q0)
    hand = point_position(arm, np.array(q0), 2, arm.tip[:3, 3])
    down = np.array([0.0, 0.0, -1.0])
    for plant in (fast, readable):
        for servo, q in zip(plant.servos, (0.1, 0.9, 0.9), strict=True):
            servo.regs.goal_position = RX24F.position_to_raw(q)  # down, into the table
        size = (0.3, 0.3, 0.05) if shape == "box" else None
        plant.set_wall(hand + 0.01 * down, -down, stiffness=2e4, damping=50.0,
                       friction=0.4 if shape == "plane" else 0.0, size=size)
        plant.set_spring(hand + np.array([0.0, 0.05, 0.0]), stiffness=40.0, link=2,
                         point=arm.tip[:3, 3], damping=1.0)
    pressed = 0.0
    for k in range(600):
        if k == 400:
            for plant in (fast, readable):
                plant.set_spring(None, stiffness=0.0, link=2, point=arm.tip[:3, 3])
        fast.step()
        _readable_with_fields(readable)
        assert fast._q == readable._q and fast._qd == readable._qd, k
        pressed = max(pressed, fast.wall_force())
    assert pressed > 1.0  # the wall was met and pressed
    assert fast.t == readable.t
