"""The servos' firmware tick compiled to machine code
(armlab.hardware.families.dynamixel1.compiled_firmware): every state and register of a
class equal to the numpy tick's, bit for bit, through joint and wheel mode, the
compliance curve at random margins, slopes and punches, overload shutdowns and their
recovery."""

from __future__ import annotations

import numpy as np
import pytest

from armlab.hardware.families.dynamixel1 import compiled_firmware
from armlab.hardware.families.dynamixel1.batched_backend import add_sim_arm
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.families.dynamixel1.firmware import ERROR_OVERLOAD
from armlab.hardware.servos.servo_spec import RX24F
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics import load_robot, machine_code
from armlab.kinematics.batched_dynamics import FLOAT_ARMS

MODEL = load_robot("receptionist_arm")
STEPS = 1200  #: ms: stalled 0.3 s (the overload time here), shut down, then recovered


def _class() -> BatchedPlant:
    """FLOAT_ARMS + 16 arms at random registers: goals and speeds, compliance margins,
    slopes and punches, Torque Limits, a tenth of the servos in wheel mode, a tenth with
    torque off, a third too weak to lift their arm, and every third arm pressed into a
    wall at full torque (stalled: overloaded, then shut down; 0.3 s of stall here)."""
    plant = BatchedPlant(MODEL, RX24F, dt=1e-3, params=ServoParams(overload_time=0.3))
    rng = np.random.default_rng(2)
    for _ in range(FLOAT_ARMS + 16):
        add_sim_arm(plant, q0=np.array([0.0, 0.3, 0.3]) + rng.uniform(-0.5, 0.5, 3))
    shape = (plant.n_arms, plant.n)
    plant.set_goals(rng.integers(0, 1024, shape), rng.integers(0, 2048, shape))
    for name, high in (("cw_compliance_margin", 5), ("ccw_compliance_margin", 5),
                       ("cw_compliance_slope", 256), ("ccw_compliance_slope", 256),
                       ("punch", 100), ("torque_limit", 1024)):
        plant.write_registers(name, rng.integers(0, high, shape))
    cw, ccw = plant.register("cw_angle_limit").copy(), plant.register("ccw_angle_limit").copy()
    wheel = rng.random(shape) < 0.1
    cw[wheel], ccw[wheel] = 0, 0
    plant.write_registers("cw_angle_limit", cw)
    plant.write_registers("ccw_angle_limit", ccw)
    plant.write_registers("torque_enable", (rng.random(shape) < 0.9).astype(np.int64))
    limit, goal = plant.register("torque_limit").copy(), plant.register("goal_position").copy()
    weak = rng.random(shape) < 0.3
    limit[weak], goal[weak] = 20, 1023
    plant.write_registers("torque_limit", limit)
    plant.write_registers("goal_position", goal)
    for a in range(0, plant.n_arms, 3):
        q = plant.q[a]
        way = MODEL.fk(q + np.array([0.0, 0.2, 0.2]))[:3, 3] - MODEL.fk(q)[:3, 3]
        normal = -way / np.linalg.norm(way)
        plant.set_wall(a, MODEL.fk(q)[:3, 3] - 0.002 * normal, normal, stiffness=5e4,
                       damping=50.0)
        for j in (1, 2):
            plant.set_registers(a, j, goal_position=1000, torque_limit=200, torque_enable=1)
    return plant


@pytest.mark.slow
def test_the_compiled_tick_gives_the_numpy_ticks_states_and_registers(
        monkeypatch: pytest.MonkeyPatch) -> None:
    assert compiled_firmware.MACHINE.wait(), compiled_firmware.MACHINE.error
    runs: list[tuple] = []
    seen: list[tuple[bool, int, np.ndarray]] = []
    for enabled in (True, False):
        monkeypatch.setattr(machine_code, "ENABLED", enabled)
        plant = _class()
        for k in range(STEPS):
            plant.step()
            if k == STEPS - 300:  # Torque Limit and Torque Enable written again: recovered
                shape = (plant.n_arms, plant.n)
                plant.write_registers("torque_limit", np.full(shape, 1023))
                plant.write_registers("torque_enable", np.ones(shape, dtype=np.int64))
            if k in (STEPS - 350, STEPS - 1):
                seen.append((enabled, k, plant.error().copy()))
        runs.append((plant.q, plant.qd, plant.present_position(), plant.present_speed(),
                     plant.present_load(), plant.moving(), plant.error(),
                     {name: plant.register(name) for name in ("torque_limit", "torque_enable",
                                                              "goal_position")}))
    a, b = runs
    for x, y in zip(a[:-1], b[:-1], strict=True):
        assert np.array_equal(x, y)
    assert all(np.array_equal(a[-1][k], b[-1][k]) for k in a[-1])
    # the run went through an overload shutdown (Alarm Shutdown: Torque Limit 0) and back
    overloaded = [errors for enabled, k, errors in seen if k == STEPS - 350]
    assert len(overloaded) == 2 and all((e & ERROR_OVERLOAD).any() for e in overloaded)
