"""The arm's collision shapes and the boxes they meet: a URDF's ``<collision>`` read into
capsules (fixed children folded in), the capsules as contact balls, a box's distance and
normal (face, edge, inside), and the arm falling onto a table top with its forearm.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from armlab.hardware.servos.servo_spec import RX24F
from armlab.hardware.sim.contact import Obstacle, checked_size, face_axes, surface
from armlab.hardware.sim.plant import Plant
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.collision import SPACING, contact_balls
from armlab.kinematics.urdf_read import chain_from_urdf

ARM = load_robot("receptionist_arm")

URDF = """<?xml version="1.0"?>
<robot name="shapes">
  <link name="base"/>
  <link name="a">
    <inertial><mass value="0.1"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>
    <collision><origin xyz="0.1 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.02" length="0.2"/></geometry></collision>
    <collision><geometry><mesh filename="package://x/a.stl"/></geometry></collision>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="b"><collision><origin xyz="0 0 0.01"/>
    <geometry><box size="0.02 0.1 0.04"/></geometry></collision>
    <collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="fix" type="fixed"><parent link="a"/><child link="b"/><origin xyz="0.2 0 0"/></joint>
</robot>
"""


def test_a_urdfs_collision_shapes_are_read_as_capsules_with_fixed_children_folded_in(
        tmp_path: Path):
    path = tmp_path / "shapes.urdf"
    path.write_text(URDF)
    chain = chain_from_urdf(path)
    shapes = chain.links[0].collision
    assert len(shapes) == 3  # the cylinder, the box and the sphere: no mesh
    cyl, box, ball = shapes
    # the cylinder along its origin's z (the link's x): its ends rounded within its length
    assert cyl.radius == pytest.approx(0.02)
    assert np.allclose(cyl.a, [0.02, 0, 0], atol=1e-12)
    assert np.allclose(cyl.b, [0.18, 0, 0], atol=1e-12)
    # the box along its longest edge (y, 0.1 m), radius half its next (z, 0.04 m), moved
    # by the fixed joint's 0.2 m and its own 1 cm up
    assert box.radius == pytest.approx(0.02)
    assert np.allclose(box.a, [0.2, -0.03, 0.01]) and np.allclose(box.b, [0.2, 0.03, 0.01])
    assert ball.radius == pytest.approx(0.03)
    assert np.allclose(ball.a, [0.2, 0, 0]) and np.allclose(ball.b, ball.a)
    balls = contact_balls(chain)
    along = [b for b in balls if b.radius == pytest.approx(0.02) and b.centre[1] == 0.0]
    gaps = np.diff(sorted(b.centre[0] for b in along))
    assert len(along) >= 2 and gaps.max() <= SPACING * 0.02 + 1e-12
    assert balls[0].centre == pytest.approx((0.02, 0.0, 0.0))


def test_the_receptionist_arms_tubes_are_its_upper_arms_and_its_forearms():
    upper, fore = ARM.links[1].collision, ARM.links[2].collision
    assert len(upper) == 1 and upper[0].radius == pytest.approx(0.018)
    assert len(fore) == 1 and fore[0].radius == pytest.approx(0.016)
    # the forearm's tube stops where the hand's sphere begins (0.25 − 0.022 m): the hand
    # touches with its tip
    assert float(fore[0].b[0]) == pytest.approx(0.25 - 0.022 - 0.016)
    assert ARM.links[0].collision == ()


def _box(size: tuple[float, float, float]) -> Obstacle:
    n = np.array([0.0, 0.0, 1.0])
    across, up = face_axes(n)
    return Obstacle((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1e4, 0.0, (), 0.0, size,
                    tuple(across), tuple(up))  # type: ignore[arg-type]


def test_a_box_is_a_face_an_edge_and_a_corner_outside_and_its_nearest_face_inside():
    box = _box((0.4, 0.2, 0.1))  # 40 × 20 cm across, 10 cm thick under the face z = 0
    d, n = surface(box, (0.05, 0.02, 0.03))  # above the face
    assert d == pytest.approx(0.03) and n == pytest.approx((0.0, 0.0, 1.0))
    d, n = surface(box, (0.23, 0.0, 0.04))  # past the edge at x = 0.2, above the face
    assert d == pytest.approx(math.hypot(0.03, 0.04))
    assert n == pytest.approx((0.6, 0.0, 0.8))
    d, n = surface(box, (0.0, 0.0, -0.02))  # 2 cm in under the face
    assert d == pytest.approx(-0.02) and n == pytest.approx((0.0, 0.0, 1.0))
    d, n = surface(box, (0.0, 0.0, -0.09))  # nearer its underside
    assert d == pytest.approx(-0.01) and n == pytest.approx((0.0, 0.0, -1.0))
    d, n = surface(box, (0.0, -0.25, -0.05))  # beside it
    assert d == pytest.approx(0.15) and n[1] == pytest.approx(-1.0)
    with pytest.raises(ValueError, match="size"):
        checked_size((0.4, 0.0, 0.1))
    with pytest.raises(ValueError, match="size"):
        checked_size((0.4, float("nan"), 0.1))


def _table_under_the_forearm(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A table top's face (a point (3,) m, its unit normal (3,) against gravity), 1 cm
    below the lowest point of the forearm's tube at ``q``, under the tube's elbow end."""
    g = np.asarray(ARM.gravity, dtype=float)
    up = -g / np.linalg.norm(g)
    balls = [b for b in contact_balls(ARM) if b.link == 2]
    T = _link_pose(q, 2)
    centres = np.array([T[:3, :3] @ np.array(b.centre) + T[:3, 3] for b in balls])
    low = min(float(c @ up) - b.radius for c, b in zip(centres, balls, strict=True))
    elbow = centres[0]
    top = elbow - (float(elbow @ up) - low + 0.01) * up
    return top, up


def _link_pose(q: np.ndarray, link: int) -> np.ndarray:
    """(4, 4) base <- frame of moving link ``link`` at ``q`` (the plant's own frames)."""
    plant = Plant(ARM, RX24F, q0=q)
    fr = plant._dyn.frames(list(q))
    o = 12 * link
    T = np.eye(4)
    T[:3, :3] = np.array(fr[o:o + 9]).reshape(3, 3)
    T[:3, 3] = fr[o + 9:o + 12]
    return T


@pytest.mark.slow
def test_a_torque_off_arm_falls_onto_a_table_top_with_its_forearm_and_comes_to_rest():
    """A table top (a box) under the forearm, well clear of the hand's tip: torque off,
    the arm falls onto it, the forearm's tube takes the weight (the tip never reaches the
    table), the energy never rises above where it started, and the arm ends at rest on it."""
    q0 = np.radians([0.0, 30.0, -100.0])
    plant = Plant(ARM, RX24F, q0=q0)
    top, up = _table_under_the_forearm(q0)
    plant.set_wall(top, up, stiffness=2e4, damping=20.0, friction=0.5, size=(0.6, 0.6, 0.03))
    assert plant.wall_size == (0.6, 0.6, 0.03)
    e0 = sum(plant.energy())
    energies, touched, tip_heights = [], 0.0, []
    for _ in range(3000):  # 3 s
        plant.step()
        energies.append(sum(plant.energy()))
        touched = max(touched, plant.wall_force())
        tip_heights.append(float((ARM.fk(plant.q)[:3, 3] - top) @ up))
    assert touched > 0.0, "the forearm never reached the table"
    assert min(tip_heights) > 0.0, "the tip reached the table: not the forearm's contact"
    assert max(energies) <= e0 + 1e-6, (max(energies), e0)
    assert np.abs(plant.qd).max() < 0.05, plant.qd
    assert plant.wall_force() > 0.1  # resting on it: the table holds part of its weight


def test_a_plane_is_met_by_the_tip_alone_and_a_box_by_the_shapes_too():
    """The same arm, a plane and a box through the same face: the plane pushes on the tip
    only (the arm's links may reach past an unbounded plane), the box on the shapes it
    holds too."""
    q = np.radians([0.0, 30.0, -100.0])
    plant = Plant(ARM, RX24F, q0=q)
    top, up = _table_under_the_forearm(q)
    sunk = top + 0.02 * up  # the face 2 cm up: the forearm's tube 1 cm into it
    plant.set_wall(sunk, up, stiffness=2e4, damping=0.0)
    tip_in = -float((ARM.fk(q)[:3, 3] - sunk) @ up)
    assert plant.wall_force() == pytest.approx(max(0.0, 2e4 * tip_in), abs=1e-9)
    plant.set_wall(sunk, up, stiffness=2e4, damping=0.0, size=(0.6, 0.6, 0.03))
    assert plant.wall_force() > 2e4 * 0.005  # the tube's balls, a centimetre in


def test_the_simulated_arm_keeps_its_box():
    """The simulated arm's backend says the box it holds (what a restarted arm meets
    again), and a plane after it holds none."""
    from armlab.hardware.families.dynamixel1.sim_backend import SimBackend

    backend = SimBackend(ARM)
    try:
        backend.set_wall(np.zeros(3), np.array([1.0, 0.0, 0.0]), stiffness=2e4, damping=50.0,
                         size=(0.3, 0.2, 0.05))
        setting = backend.wall_setting()
        assert setting is not None and setting.size == (0.3, 0.2, 0.05)
        backend.set_wall(np.zeros(3), np.array([1.0, 0.0, 0.0]), stiffness=2e4, damping=50.0)
        assert backend.wall_setting().size is None
    finally:
        backend.close()


@pytest.mark.slow
def test_a_class_of_arms_falling_on_tables_and_blocks_moves_as_single_plants():
    """Torque off, four arms of one batched plant and four single plants fall 1.5 s: onto a
    table top under the forearm (its tube's balls), the same with friction, onto a small
    block under the hand (its tip, its edges and corners), and onto the table's plane (the
    tip alone): every step's q and q̇ within 1e-9 of the single plants', and each wall's
    force as theirs."""
    from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant

    starts = [np.radians(a) for a in ([0.0, 30.0, -100.0], [10.0, 35.0, -95.0],
                                       [0.0, 20.0, -60.0], [0.0, 30.0, -100.0])]
    singles = [Plant(ARM, RX24F, q0=q) for q in starts]
    batch = BatchedPlant(ARM, RX24F)
    arms = [batch.add_arm(q0=q) for q in starts]
    walls = []
    for i, q in enumerate(starts):
        top, up = _table_under_the_forearm(q)
        if i == 2:  # a 4 cm block 1 cm under the hand, its corner near the tip
            tip = ARM.fk(q)[:3, 3]
            walls.append(dict(origin_base=tip - 0.01 * up + np.array([0.0, 0.015, 0.0]),
                              normal_base=up, stiffness=5e4, damping=30.0,
                              size=(0.04, 0.04, 0.04)))
        else:
            walls.append(dict(origin_base=top, normal_base=up, stiffness=2e4, damping=20.0,
                              friction=0.5 if i == 1 else 0.0,
                              size=None if i == 3 else (0.6, 0.6, 0.03)))
    for i, wall in enumerate(walls):
        singles[i].set_wall(**wall)
        batch.set_wall(arms[i], **wall)
    worst, touched = 0.0, set()
    for _ in range(1500):
        for p in singles:
            p.step()
        batch.step()
        worst = max(worst, float(np.max(np.abs(batch.q - np.array([p.q for p in singles])))),
                    float(np.max(np.abs(batch.qd - np.array([p.qd for p in singles])))))
        ids, forces = batch.wall_forces()
        by_arm = dict(zip(ids.tolist(), forces.tolist(), strict=True))
        for i, p in enumerate(singles):
            assert by_arm.get(arms[i], 0.0) == pytest.approx(p.wall_force(), abs=1e-6)
            if p.wall_force() > 0.0:
                touched.add(i)
    assert worst <= 1e-9, worst
    assert touched == {0, 1, 2, 3}, touched


@pytest.mark.slow
def test_a_block_across_the_line_meets_the_forearm_too(capsys):
    """``armlab experiment contact --block-cm``: a 6 × 4 cm block in the wall's place. The
    hand presses its face as it pressed the plane, and the forearm, which reaches past the
    face's plane beside the hand, meets the block's side: the arm is held harder than the
    law's prediction for the hand alone (which the plane, met by the tip, gives)."""
    from dataclasses import replace

    from armlab.app.commands.cli import main
    from armlab.control.experiments.contact import run_contact
    from armlab.control.params import DEFAULT
    from armlab.hardware.families.dynamixel1.sim_backend import SimBackend

    params = replace(DEFAULT, alpha=0.6, k_env=64.0)
    runs = {size: run_contact(ARM, lambda model, q0: SimBackend(model, q0=q0), params,
                              controller="compliance", wall=0.04, depth=0.02,
                              stiffness=2e4, damping=50.0, size=size)
            for size in (None, (0.06, 0.04, 0.05))}
    plane, block = runs[None], runs[(0.06, 0.04, 0.05)]
    assert plane["fault"] is None and block["fault"] is None
    assert plane["steady_force_n"] == pytest.approx(plane["predicted_force_n"], rel=0.08)
    assert block["steady_force_n"] > 2.0 * plane["steady_force_n"]
    assert block["wall"]["size_m"] == [0.06, 0.04, 0.05]
    assert main(["experiment", "contact", "--block-cm", "6,0,5"]) != 0
    err = capsys.readouterr().err
    assert "--block-cm" in err and "three sizes" in err and "Traceback" not in err


class _EveryStage(Plant):
    """The plant with its wall's touches worked out afresh at every RK4 stage (forward
    kinematics a stage), not held from the step's start: the reference the held
    Jacobian is measured against."""

    def _field_torques(self, q, qd, near, q0):  # noqa: ANN001, ANN202 - Plant's own
        saved = self._q, self._qd, self._near
        self._q, self._qd, self._near = list(q), list(qd), None
        try:
            exact = self._near_touches()
        finally:
            self._q, self._qd, self._near = saved
        return super()._field_torques(q, qd, exact, q)


@pytest.mark.slow
@pytest.mark.parametrize("obstacle", ["table", "plate"])
def test_touches_held_from_the_steps_start_move_the_arm_as_touches_worked_out_every_stage(
        obstacle: str):
    """A torque-off arm falling 1.5 s onto a wooden table top (its forearm's tube) and
    onto a 10⁵ N/m plate 2 cm under its tip, with friction: the plant holding each touch's
    Jacobian over a step keeps within 10⁻³ rad of one working every touch out at every
    stage (the impacts' bounces included), and its peak force within 0.2 %."""
    q0 = np.radians([0.0, 30.0, -100.0])
    top, up = _table_under_the_forearm(q0)
    plants = [Plant(ARM, RX24F, q0=q0), _EveryStage(ARM, RX24F, q0=q0)]
    for p in plants:
        if obstacle == "table":
            p.set_wall(top, up, stiffness=2e4, damping=20.0, friction=0.5,
                       size=(0.6, 0.6, 0.03))
        else:
            p.set_wall(ARM.fk(q0)[:3, 3] - 0.02 * up, up, stiffness=1e5, damping=20.0,
                       friction=0.5)
    worst, peaks = 0.0, [0.0, 0.0]
    for _ in range(1500):
        for i, p in enumerate(plants):
            p.step()
            peaks[i] = max(peaks[i], p.wall_force())
        worst = max(worst, float(np.max(np.abs(plants[0].q - plants[1].q))))
    assert peaks[1] > 10.0  # it did land
    assert worst < 1e-3, worst
    assert peaks[0] == pytest.approx(peaks[1], rel=2e-3)
