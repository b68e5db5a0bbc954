"""The wall's Coulomb friction (``friction`` μ): against the sliding, capped at μ times the
wall's push, a damper on the sliding speed below that (the regularised stick, stable at
the plant's 1 ms RK4 step); it only ever takes energy out, a dragged hand slides less on
a rough wall than on a smooth one, and the batched plant of a class gives the single
plant's numbers."""

from __future__ import annotations

import numpy as np
import pytest

from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.servos.servo_spec import RX24F
from armlab.hardware.sim.contact import FRICTION_DAMPING, Obstacle, rub
from armlab.hardware.sim.plant import Plant
from armlab.kinematics.catalog import load_robot

ARM = load_robot("receptionist_arm")
UP = np.array([0.0, 0.0, 1.0])
UP_T = (0.0, 0.0, 1.0)


def test_friction_opposes_the_sliding_is_capped_and_needs_a_push():
    wall = Obstacle((0.0, 0.0, 0.0), UP_T, 2e4, 0.0, (), 0.5)
    slow = rub(wall, 10.0, [0.001, 0.0, 0.0])  # 1 mm/s along
    assert slow == pytest.approx([-FRICTION_DAMPING * 0.001, 0.0, 0.0])  # below the cap
    fast = rub(wall, 10.0, [0.0, 2.0, 0.0])
    assert fast == pytest.approx([0.0, -5.0, 0.0])  # Coulomb's μ·push = 5 N
    assert rub(wall, 0.0, [0.0, 2.0, 0.0]) == (0.0, 0.0, 0.0)  # no push
    smooth = Obstacle((0.0, 0.0, 0.0), UP_T, 2e4, 0.0, (), 0.0)
    assert rub(smooth, 10.0, [0.0, 2.0, 0.0]) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("friction", [-0.1, 2.5, float("nan")])
def test_a_friction_out_of_range_is_refused(friction):
    plant = Plant(ARM, RX24F, q0=np.zeros(3))
    with pytest.raises(ValueError, match="friction"):
        plant.set_wall(np.zeros(3), UP, friction=friction)


def _dropped(friction: float) -> tuple[float, list[float], float, float]:
    """A torque-off arm falling onto a table under its hand: (start energy, energies,
    largest push, how far the hand slid along the table after touching it, m)."""
    q0 = np.radians([0.0, 30.0, 20.0])
    plant = Plant(ARM, RX24F, q0=q0)
    tip = ARM.fk(q0)[:3, 3]
    g = np.asarray(ARM.gravity, dtype=float)
    down = g / np.linalg.norm(g)
    plant.set_wall(tip + 0.03 * down, -down, stiffness=2e4, damping=20.0, friction=friction)
    e0 = sum(plant.energy())
    energies, touched, first = [], 0.0, None
    slid = 0.0
    for _ in range(3000):  # 3 s
        plant.step()
        energies.append(sum(plant.energy()))
        touched = max(touched, plant.wall_force())
        hand = ARM.fk(plant.q)[:3, 3]
        if first is None and plant.wall_force() > 0.0:
            first = hand
        if first is not None:
            along = (hand - first) - ((hand - first) @ down) * down
            slid = max(slid, float(np.linalg.norm(along)))
    return e0, energies, touched, slid


@pytest.mark.slow
@pytest.mark.parametrize("friction", [0.3, 1.0])
def test_a_dropped_arm_on_a_rough_table_never_gains_energy_and_slides_less(friction):
    e0, energies, touched, slid = _dropped(friction)
    assert touched > 0.0, "the hand never reached the table"
    assert max(energies) <= e0 + 1e-6, (max(energies), e0)
    _, _, _, smooth_slid = _dropped(0.0)
    assert slid < smooth_slid, (slid, smooth_slid)


@pytest.mark.slow
def test_the_batched_plant_gives_the_single_plants_numbers_with_friction():
    q0s = [np.radians([0.0, 30.0, 20.0]), np.radians([10.0, 40.0, 10.0]),
           np.radians([-5.0, 20.0, 35.0])]
    singles = [Plant(ARM, RX24F, q0=q) for q in q0s]
    batch = BatchedPlant(ARM, RX24F)
    ids = [batch.add_arm(q0=q) for q in q0s]
    g = np.asarray(ARM.gravity, dtype=float)
    down = g / np.linalg.norm(g)
    for k, (plant, arm, q) in enumerate(zip(singles, ids, q0s, strict=True)):
        tip = ARM.fk(q)[:3, 3]
        mu = (0.0, 0.4, 1.2)[k]
        plant.set_wall(tip + 0.02 * down, -down, stiffness=2e4, damping=20.0, friction=mu)
        batch.set_wall(arm, tip + 0.02 * down, -down, stiffness=2e4, damping=20.0,
                       friction=mu)
    for _ in range(1500):
        for plant in singles:
            plant.step()
        batch.step()
    for plant, row in zip(singles, range(len(ids)), strict=True):
        np.testing.assert_allclose(batch.q[row], plant.q, atol=1e-9)
    assert np.ptp([p.q[1] for p in singles]) > 0.0  # (the arms moved apart: not trivial)
