"""Recursive Newton–Euler (thesis eq. 2.41–2.50) against hand-worked cases and invariants."""

import math
from pathlib import Path

import numpy as np
import pytest

from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import (
    bias_torques,
    dynamics_model,
    forward_dynamics,
    gravity_torques,
    kinetic_energy,
    mass_matrix,
    newton_euler,
    potential_energy,
    rnea,
)
from armlab.kinematics.fk import link_poses
from armlab.kinematics.points import point_force_torques, point_jacobian, point_position
from armlab.kinematics.thesis_dynamics import thesis_closed_form
from armlab.kinematics.urdf_read import chain_from_urdf

# The thesis's arm: L1 = 18.5 cm, L2 = 25 cm, m1 = 176 g, m2 = 190 g, g = 9.81.
L1, L2, M1, M2, G = 0.185, 0.25, 0.176, 0.19, 9.81


def rod(mass: float, length: float) -> str:
    i = mass * length**2 / 12.0
    return (f'<inertial><origin xyz="{length / 2} 0 0"/><mass value="{mass}"/>'
            f'<inertia ixx="1e-9" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial>')


@pytest.fixture(scope="module")
def planar(tmp_path_factory) -> object:
    """Two rods in the vertical x-z plane, joints about y (URDF world: gravity -z)."""
    path = Path(tmp_path_factory.mktemp("urdf")) / "two_link.urdf"
    path.write_text(f"""<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <link name="l1">{rod(M1, L1)}</link>
  <link name="l2">{rod(M2, L2)}</link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="3" velocity="10"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="{L1} 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="3" velocity="10"/></joint>
  <joint name="wrist" type="fixed"><parent link="l2"/><child link="tip"/>
    <origin xyz="{L2} 0 0"/></joint>
</robot>""")
    return chain_from_urdf(path)


def hand_gravity(q1: float, q2: float) -> np.ndarray:
    """Holding torques worked out by hand: V = g (m1 z_c1 + m2 z_c2), tau = dV/dq, with
    z_c1 = -(L1/2) sin q1 and z_c2 = -L1 sin q1 - (L2/2) sin(q1 + q2) (rotation about +y
    turns +x towards -z)."""
    c1, c12 = np.cos(q1), np.cos(q1 + q2)
    return np.array([-G * ((M1 * L1 / 2 + M2 * L1) * c1 + M2 * L2 / 2 * c12),
                     -G * M2 * L2 / 2 * c12])


@pytest.mark.parametrize("q", [(0.0, 0.0), (0.3, -0.7), (-1.2, 2.0), (np.pi / 2, 0.4)])
def test_rnea_at_rest_equals_hand_worked_gravity_torques(planar, q):
    np.testing.assert_allclose(rnea(planar, q, [0, 0], [0, 0]), hand_gravity(*q), atol=1e-12)
    np.testing.assert_allclose(gravity_torques(planar, q), hand_gravity(*q), atol=1e-12)


def test_horizontal_arm_numbers(planar):
    # Arm straight out horizontally: shoulder holds (m1 L1/2 + m2 (L1 + L2/2)) g
    # = (0.176·0.0925 + 0.19·0.31)·9.81 = 0.7375 N·m; elbow 0.19·0.125·9.81 = 0.2330 N·m.
    tau = rnea(planar, [0, 0], [0, 0], [0, 0])
    np.testing.assert_allclose(-tau, [0.73751, 0.23299], atol=5e-5)


def test_rnea_model_gravity_is_the_thesis_plus_x():
    arm = load_robot("receptionist_arm")
    # theta0 = 90°: both links horizontal in the thesis frame (gravity +x).
    tau = rnea(arm, [0, np.pi / 2, 0], np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(tau, [0, (M1 * L1 / 2 + M2 * (L1 + L2 / 2)) * G, 0], atol=1e-12)
    # A gravity given by the caller replaces the model's.
    assert np.allclose(rnea(arm, [0, np.pi / 2, 0], np.zeros(3), np.zeros(3),
                            gravity=np.zeros(3)), 0)


def jacobian_mass_matrix(model, q) -> np.ndarray:
    """Independent M(q) = Σ m Jv^T Jv + Jw^T I Jw from the FK module's link poses."""
    poses = link_poses(model, q)
    M = np.zeros((model.n, model.n))
    for i, link in enumerate(model.links):
        R = poses[i][:3, :3]
        c = R @ link.com + poses[i][:3, 3]
        Jv = np.zeros((3, model.n))
        Jw = np.zeros((3, model.n))
        for j in range(i + 1):
            z = poses[j][:3, :3] @ model.joints[j].axis
            Jv[:, j] = np.cross(z, c - poses[j][:3, 3])
            Jw[:, j] = z
        M += link.mass * Jv.T @ Jv + Jw.T @ (R @ link.inertia @ R.T) @ Jw
    return M


@pytest.mark.parametrize("name", ["receptionist_arm", "planar"])
def test_mass_matrix_symmetric_positive_definite(name, planar):
    model = planar if name == "planar" else load_robot(name)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(model.lower, model.upper)
        M = mass_matrix(model, q)
        np.testing.assert_allclose(M, M.T, atol=1e-15)
        assert np.linalg.eigvalsh(M).min() > 0
        np.testing.assert_allclose(M, jacobian_mass_matrix(model, q), atol=1e-14)


def test_inverse_then_forward_round_trip():
    arm = load_robot("receptionist_arm")
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = rng.uniform(arm.lower, arm.upper)
        qd, qdd = rng.normal(0, 3, 3), rng.normal(0, 20, 3)
        tau = rnea(arm, q, qd, qdd)
        np.testing.assert_allclose(forward_dynamics(arm, q, qd, tau), qdd, atol=1e-9)
        np.testing.assert_allclose(mass_matrix(arm, q) @ qdd + bias_torques(arm, q, qd), tau,
                                   atol=1e-12)
        arm_inertia = np.array([3e-3, 3e-3, 3e-3])
        tau_a = tau + arm_inertia * qdd
        np.testing.assert_allclose(forward_dynamics(arm, q, qd, tau_a, armature=arm_inertia),
                                   qdd, atol=1e-9)


def test_coriolis_matrix_is_consistent_with_mass_matrix():
    """dT/dt = qd·(tau - g) when tau = rnea(q, qd, qdd): the power balance that makes an
    unforced arm conserve energy."""
    arm = load_robot("receptionist_arm")
    rng = np.random.default_rng(11)
    for _ in range(10):
        q, qd, qdd = rng.uniform(-1, 1, 3), rng.normal(size=3), rng.normal(size=3)
        h = 1e-6
        dT = (kinetic_energy(arm, q + h * qd, qd + h * qdd)
              - kinetic_energy(arm, q - h * qd, qd - h * qdd)) / (2 * h)
        power = qd @ (rnea(arm, q, qd, qdd) - gravity_torques(arm, q))
        assert dT == pytest.approx(power, abs=1e-7)


def test_free_double_pendulum_conserves_energy_with_rk4(planar):
    q, qd = np.array([0.4, -0.3]), np.array([0.0, 2.0])
    dt = 1e-3

    def f(q, qd):
        return forward_dynamics(planar, q, qd, np.zeros(2))

    def energy(q, qd):
        return kinetic_energy(planar, q, qd) + potential_energy(planar, q)

    e0 = energy(q, qd)
    rest = potential_energy(planar, [np.pi / 2, 0])  # hanging straight down (+y turns x to -z)
    for _ in range(2000):
        k1v = f(q, qd)
        k2v = f(q + dt / 2 * qd, qd + dt / 2 * k1v)
        k3v = f(q + dt / 2 * (qd + dt / 2 * k1v), qd + dt / 2 * k2v)
        k4v = f(q + dt * (qd + dt / 2 * k2v), qd + dt * k3v)
        q = q + dt / 6 * (qd + 2 * (qd + dt / 2 * k1v) + 2 * (qd + dt / 2 * k2v)
                          + (qd + dt * k3v))
        qd = qd + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    assert abs(energy(q, qd) - e0) < 0.005 * (e0 - rest)


def test_external_point_force_is_jacobian_transpose(planar):
    q = np.array([0.3, 0.5])
    F = np.array([0.0, 0.0, -2.0])  # 2 N straight down at the tip
    tip = np.array([L2, 0, 0])
    wrench = np.zeros((2, 6))
    p = point_position(planar, q, 1, tip)
    o2 = planar.link_poses(q)[1][:3, 3]
    wrench[1, :3] = F
    wrench[1, 3:] = np.cross(p - o2, F)  # the force moved to link 2's origin
    static = rnea(planar, q, [0, 0], [0, 0], f_ext=wrench)
    # By hand: pressing down on the tip is like more weight there: the holding torques
    # grow by 2 N times each joint's horizontal lever (same sign as the gravity torques).
    lever1 = L1 * np.cos(0.3) + L2 * np.cos(0.8)
    lever2 = L2 * np.cos(0.8)
    np.testing.assert_allclose(static - hand_gravity(*q), [-2.0 * lever1, -2.0 * lever2],
                               atol=1e-12)
    np.testing.assert_allclose(point_force_torques(planar, q, 1, tip, F),
                               point_jacobian(planar, q, 1, tip).T @ F)
    np.testing.assert_allclose(point_force_torques(planar, q, 1, tip, F),
                               [2.0 * lever1, 2.0 * lever2], atol=1e-12)


def test_point_jacobian_matches_end_effector_jacobian():
    arm = load_robot("receptionist_arm")
    q = np.array([0.2, -0.4, 0.9])
    np.testing.assert_allclose(point_jacobian(arm, q, 2, arm.tip[:3, 3]),
                               arm.jacobian(q)[:3], atol=1e-14)
    np.testing.assert_allclose(point_position(arm, q, 2, arm.tip[:3, 3]), arm.fk(q)[:3, 3],
                               atol=1e-15)


def test_prismatic_joint_lifts_its_mass(tmp_path):
    path = tmp_path / "lift.urdf"
    path.write_text("""<?xml version="1.0"?>
<robot name="lift"><link name="base"/>
  <link name="car"><inertial><mass value="2.0"/><inertia ixx="1e-3" iyy="1e-3" izz="1e-3"
   ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="z" type="prismatic"><parent link="base"/><child link="car"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="1" effort="100" velocity="1"/></joint></robot>""")
    lift = chain_from_urdf(path)
    # F = m (qdd + g) = 2 (0.5 + 9.81).
    assert rnea(lift, [0.3], [0.2], [0.5])[0] == pytest.approx(2.0 * 10.31)


def test_bad_input_names_the_argument():
    arm = load_robot("receptionist_arm")
    with pytest.raises(ValueError, match="qd"):
        rnea(arm, np.zeros(3), [0, np.nan, 0], np.zeros(3))
    with pytest.raises(ValueError, match="q must have shape"):
        rnea(arm, np.zeros(2), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="link"):
        point_jacobian(arm, np.zeros(3), 3, np.zeros(3))


def test_compiled_model_is_built_once_and_readable():
    arm = load_robot("receptionist_arm")
    dm = dynamics_model(arm)
    assert dm is dynamics_model(arm)
    # the readable source is the code that runs: executed on its own it gives RNEA's torques
    namespace: dict = {"_sin": math.sin, "_cos": math.cos}
    exec(compile(dm.source, "<source>", "exec"), namespace)  # noqa: S102
    q, qd, qdd = np.array([0.3, -0.7, 1.1]), np.array([0.5, -1.2, 2.0]), np.array([1, 2, -3.0])
    got = np.array(namespace["rnea"](q, qd, qdd, arm.gravity), dtype=float)
    np.testing.assert_allclose(got, rnea(arm, q, qd, qdd), rtol=1e-12, atol=1e-12)


def shipped_chains() -> list[tuple[str, object]]:
    """Every serial chain the lab ships: each URDF in armlab/kinematics/robots (a quadruped's four
    legs). The hand's fingers are planar tendon linkages (armlab/kinematics/hand_statics.py),
    not chains."""
    from armlab.kinematics.catalog import ROBOTS_DIR
    from armlab.kinematics.model import Quadruped

    out = []
    for path in sorted(ROBOTS_DIR.glob("*.urdf")):
        model = load_robot(path)
        if isinstance(model, Quadruped):
            out += [(f"{path.stem}:{leg}", chain) for leg, chain in model.legs.items()]
        else:
            out.append((path.stem, model))
    return out


@pytest.mark.parametrize("name,chain", shipped_chains(), ids=[n for n, _ in shipped_chains()])
def test_generated_rnea_equals_the_readable_recursion_on_every_shipped_robot(name, chain):
    """The fast path (generated code) and :func:`newton_euler` (the teaching text): one
    recursion, so equal to round-off at random states (and at rest, gravity alone)."""
    rng = np.random.default_rng(7)
    n = chain.n
    for _ in range(25):
        q = rng.uniform(-np.pi, np.pi, n)
        qd, qdd = rng.normal(0.0, 3.0, n), rng.normal(0.0, 20.0, n)
        np.testing.assert_allclose(rnea(chain, q, qd, qdd), newton_euler(chain, q, qd, qdd),
                                   rtol=0, atol=1e-12, err_msg=name)
    q = rng.uniform(-1, 1, n)
    np.testing.assert_allclose(gravity_torques(chain, q),
                               newton_euler(chain, q, np.zeros(n), np.zeros(n)),
                               rtol=0, atol=1e-12, err_msg=name)
    assert np.any(np.abs(newton_euler(chain, q, np.zeros(n), np.ones(n))) > 1e-6), name


def test_readable_recursion_on_a_prismatic_joint_and_a_tilted_gravity(tmp_path):
    """A slide carried by a turning joint: the Coriolis term 2 ω × ḋ (eq. 2.47) and the
    prismatic rows (eq. 2.42, 2.44) agree with the generated code."""
    path = tmp_path / "arm_slide.urdf"
    link = ('<inertial><origin xyz="0.05 0.01 0"/><mass value="{m}"/><inertia ixx="2e-3" '
            'iyy="3e-3" izz="4e-3" ixy="1e-4" ixz="0" iyz="-2e-4"/></inertial>')
    path.write_text(f"""<?xml version="1.0"?>
<robot name="arm_slide"><link name="base"/>
  <link name="a">{link.format(m=1.5)}</link><link name="b">{link.format(m=0.7)}</link>
  <joint name="turn" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.1" rpy="0.2 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0.2 0 0" rpy="0 0.3 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" effort="50" velocity="1"/></joint></robot>""")
    chain = chain_from_urdf(path)
    g = np.array([1.0, -2.0, -9.5])
    for q, qd, qdd in [([0.4, 0.1], [1.5, -0.3], [2.0, 0.7]), ([-1.2, 0.25], [0, 0.5], [0, 0])]:
        np.testing.assert_allclose(rnea(chain, q, qd, qdd, gravity=g),
                                   newton_euler(chain, q, qd, qdd, gravity=g),
                                   rtol=0, atol=1e-12)


# -- thesis §3.4 closed forms against RNEA (docs/dynamics.md) ---------------------------


@pytest.mark.parametrize("theta0", [0.3, 1.0, -0.8])
def test_thesis_servo1_misses_link2_moment_about_the_elbow(theta0):
    """At rest with theta1 = theta2 = 0 the thesis's eq. 3.28 carries only the force F21
    to link 1; the moment of link 2's weight about the elbow, m2 g (L2/2) sin theta0, is
    lost."""
    arm = load_robot("receptionist_arm")
    q = np.array([0.0, theta0, 0.0])
    thesis = thesis_closed_form(q, np.zeros(3), np.zeros(3))
    exact = rnea(arm, q, np.zeros(3), np.zeros(3))
    assert exact[1] - thesis[1] == pytest.approx(M2 * G * L2 / 2 * np.sin(theta0), abs=1e-12)


@pytest.mark.parametrize("theta1,theta2", [(0.4, 0.3), (-0.9, 1.2)])
def test_thesis_elbow_statics_right_once_typo_fixed(theta1, theta2):
    """With theta0 = 0 the elbow axis is the world z axis; eq. 3.36 with (y_B - y_C2) gives
    the exact static elbow torque, the printed (z_B - z_C2) gives zero."""
    arm = load_robot("receptionist_arm")
    q = np.array([theta1, 0.0, theta2])
    exact = rnea(arm, q, np.zeros(3), np.zeros(3))
    assert exact[2] == pytest.approx(M2 * G * L2 / 2 * np.sin(theta1 + theta2), abs=1e-12)
    assert thesis_closed_form(q, np.zeros(3), np.zeros(3))[2] == pytest.approx(exact[2],
                                                                              abs=1e-12)
    assert thesis_closed_form(q, np.zeros(3), np.zeros(3), literal=True)[2] == pytest.approx(0)


def test_thesis_eq_3_31_as_printed_has_the_sign_of_servo2_reversed():
    arm = load_robot("receptionist_arm")
    q = np.array([0.5, 0.0, 0.0])
    fixed = thesis_closed_form(q, np.zeros(3), np.zeros(3))[0]
    literal = thesis_closed_form(q, np.zeros(3), np.zeros(3), literal=True)[0]
    assert literal == pytest.approx(-fixed)
    # Both miss the same elbow moment as servo 1 does.
    exact = rnea(arm, q, np.zeros(3), np.zeros(3))[0]
    assert exact - fixed == pytest.approx(M2 * G * L2 / 2 * np.sin(0.5), abs=1e-12)


def test_thesis_closed_form_in_motion_differs_by_dropped_dynamics():
    """Moving along the chapter-4 line speeds, the simplified forms are off by a visible
    fraction of the gravity load (reported in docs/dynamics.md), never by less than the
    dropped elbow moment alone would explain at rest."""
    arm = load_robot("receptionist_arm")
    q, qd, qdd = np.array([0.6, 0.4, 0.8]), np.array([0.5, -0.4, 0.6]), np.array([2, -1, 3.0])
    diff = rnea(arm, q, qd, qdd) - thesis_closed_form(q, qd, qdd)
    assert np.abs(diff).max() > 0.05  # N·m, 0.5 kgf·cm
