"""Seed 003 quadruped model: generated URDF, leg IK round trip, centre of mass; and the
seed robots' URDFs in yourdfpy and a real viser server."""

import math
from pathlib import Path

import numpy as np
import pytest
import viser
import yourdfpy
from hypothesis import given, settings
from hypothesis import strategies as st
from viser.extras import ViserUrdf

from armlab.kinematics import load_robot
from armlab.kinematics.catalog import ROBOTS_DIR
from armlab.kinematics.leg_ik import LegGeometry, leg_fk, leg_ik
from armlab.kinematics.quadruped import (
    LEGS,
    QuadrupedGeometry,
    body_to_leg,
    hip_position,
    leg_to_body,
    quadruped_urdf,
)
from armlab.kinematics.stability import centre_of_mass, centre_of_mass_model
from armlab.kinematics.urdf_read import quadruped_from_urdf

SEED_ROBOTS = ("redundant_planar", "planar_servo_arm", "quadruped")


def test_shipped_urdf_is_the_generators_default_output():
    assert (ROBOTS_DIR / "quadruped.urdf").read_text() == quadruped_urdf()


def test_generated_urdf_follows_its_leg_lengths(tmp_path: Path):
    geom = QuadrupedGeometry(leg=LegGeometry(femur=0.06, tibia=0.13), hip_x=0.1)
    path = tmp_path / "long_legs.urdf"
    path.write_text(quadruped_urdf(geom))
    robot = quadruped_from_urdf(path)
    for leg in LEGS:
        chain = robot.legs[leg]
        np.testing.assert_allclose(chain.base_pose[:3, 3], hip_position(leg, geom))
        # Leg stretched out at θ = 0: femur + tibia from the hip, outward.
        assert np.linalg.norm(chain.fk(np.zeros(3))[:3, 3]) == pytest.approx(0.19)


def test_urdf_joint_angles_are_the_seeds_angles_on_every_leg():
    robot = load_robot("quadruped")
    geom = QuadrupedGeometry()
    rng = np.random.default_rng(5)
    for leg, chain in robot.legs.items():
        assert chain.link_names[-1] == f"{leg}_tibia"
        for _ in range(10):
            q = rng.uniform(-1.2, 1.2, 3)
            foot_body = (chain.base_pose @ chain.fk(q))[:3, 3]
            np.testing.assert_allclose(foot_body, leg_to_body(leg_fk(q, geom.leg), leg, geom),
                                       atol=1e-12)
            np.testing.assert_allclose(body_to_leg(foot_body, leg, geom), leg_fk(q, geom.leg),
                                       atol=1e-12)


def test_right_legs_mirror_the_left_legs():
    robot = load_robot("quadruped")
    q = np.array([0.3, 0.2, 1.1])  # yaw towards forward, femur down, knee bent
    lf = (robot.legs["LF"].base_pose @ robot.legs["LF"].fk(q))[:3, 3]
    rf = (robot.legs["RF"].base_pose @ robot.legs["RF"].fk(q))[:3, 3]
    np.testing.assert_allclose(rf, lf * [1, -1, 1], atol=1e-12)
    assert lf[0] > 0.08 and lf[1] > 0.06 and lf[2] < 0  # forward, outward, below the hip


@settings(max_examples=300, deadline=None)
@given(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-0.2, 0.05),
       st.sampled_from([1, -1]))
def test_leg_ik_round_trip(x, y, z, knee):
    geom = LegGeometry()
    d = math.sqrt(x * x + y * y + z * z)
    r = leg_ik((x, y, z), geom, knee=knee)
    assert all(math.isfinite(a) for a in r.angles)
    foot = np.array(leg_fk(r.angles, geom))
    if abs(geom.femur - geom.tibia) + 1e-9 < d < geom.femur + geom.tibia - 1e-9 \
            and math.hypot(x, y) > 1e-6:
        assert r.reachable
        np.testing.assert_allclose(foot, [x, y, z], atol=1e-9)
        # The seed's root (knee=+1) bends the knee downwards: θ3 in [0, π].
        assert (r.angles[2] >= 0) if knee == 1 else (r.angles[2] <= 0)
    elif not r.reachable:
        # Nearest reachable pose: on the ray to the target at the workspace boundary.
        assert r.message
        assert np.linalg.norm(foot) == pytest.approx(
            geom.femur + geom.tibia if d > geom.femur + geom.tibia
            else geom.tibia - geom.femur, abs=1e-9)


def test_seed_ik_formulas_give_a_spider_stance():
    r = leg_ik((0.0, 0.10, -0.09))
    t1, t2, t3 = np.degrees(r.angles)
    assert t1 == pytest.approx(0.0)
    assert -15 < t2 < 15 and 70 < t3 < 110  # femur about level, tibia steeply down


def test_centre_of_mass_from_geometry_matches_the_urdf_inertials():
    robot = load_robot("quadruped")
    rng = np.random.default_rng(6)
    for _ in range(5):
        angles = {leg: rng.uniform(-1, 1, 3) for leg in LEGS}
        np.testing.assert_allclose(centre_of_mass(angles), centre_of_mass_model(robot, angles),
                                   atol=1e-12)
    total = robot.body_mass + sum(lk.mass for ch in robot.legs.values() for lk in ch.links)
    assert total == pytest.approx(0.55 + 4 * (0.06 + 0.07 + 0.03))


@pytest.mark.parametrize("name", SEED_ROBOTS)
def test_seed_robot_loads_in_yourdfpy_and_viser(name):
    path = ROBOTS_DIR / f"{name}.urdf"
    urdf = yourdfpy.URDF.load(str(path))
    model = load_robot(name)
    n = 12 if name == "quadruped" else model.n
    assert len(urdf.actuated_joint_names) == n
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = ViserUrdf(server, path, root_node_name=f"/{name}")
        view.update_cfg(np.zeros(n))
        assert len(view.get_actuated_joint_names()) == n
    finally:
        server.stop()


def test_foot_point_of_the_geometry_is_the_urdf_foot():
    """The floor's push on a stance foot (gait loop) lands where the URDF puts the foot."""
    from armlab.kinematics.quadruped import LEGS, foot_in_tibia

    robot = load_robot("quadruped")
    for leg in LEGS:
        np.testing.assert_allclose(robot.legs[leg].tip[:3, 3], foot_in_tibia(leg), atol=1e-12)
