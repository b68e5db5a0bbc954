"""Forward kinematics and the Jacobian against the thesis (seed 000 §3.2-3.3) and finite
differences, for every robot armlab knows; malformed URDFs and unknown names."""

from pathlib import Path

import numpy as np
import pytest

from armlab.kinematics import Quadruped, URDFError, load_robot
from armlab.kinematics.catalog import ROBOT_FILES, ROBOTS_DIR
from armlab.kinematics.fk import fk, fk_and_jacobian, jacobian
from armlab.kinematics.urdf_read import chain_from_urdf

PRESETS = [("18.5/25", 0.185, 0.25), ("18.5/18.5", 0.185, 0.185), ("17/25", 0.17, 0.25)]


def thesis_position(t1, t0, t2, L1, L2):
    """Thesis eq. 3.13: hand position (x, y, z) in the shoulder (thesis) frame."""
    c0, s0, c1, s1, c2, s2 = np.cos(t0), np.sin(t0), np.cos(t1), np.sin(t1), np.cos(t2), np.sin(t2)
    return np.array([
        L1 * c0 * c1 - L2 * (s1 * s2 - c0 * c1 * c2),
        L2 * (c1 * s2 + c0 * c2 * s1) + L1 * c0 * s1,
        -L1 * s0 - L2 * c2 * s0,
    ])


def thesis_jacobian(t1, t0, t2, L1, L2):
    """The thesis's printed J11..J33 (§3.3), columns theta1, theta2, theta0, transcribed."""
    c0, s0, c1, s1, c2, s2 = np.cos(t0), np.sin(t0), np.cos(t1), np.sin(t1), np.cos(t2), np.sin(t2)
    J11 = -L1 * c0 * s1 - L2 * (c1 * s2 + c0 * s1 * c2)
    J12 = -L2 * (s1 * c2 + c0 * c1 * s2)
    J13 = -L1 * s0 * c1 - L2 * (s0 * c1 * c2)
    J21 = L2 * ((-s1) * s2 + c0 * c2 * c1) + L1 * c0 * c1
    J22 = L2 * (c1 * c2 - c0 * s2 * s1)
    J23 = L2 * ((-s0) * c2 * s1) - L1 * s0 * s1
    J31 = 0.0
    J32 = L2 * s2 * s0
    J33 = -L1 * c0 - L2 * c2 * c0
    return np.array([[J11, J12, J13], [J21, J22, J23], [J31, J32, J33]])


def random_angles(rng, n=25):
    return rng.uniform(-np.pi, np.pi, (n, 3))


@pytest.mark.parametrize("preset,L1,L2", PRESETS)
def test_jacobian_equals_thesis_printed_entries(preset, L1, L2):
    arm = load_robot("receptionist_arm", preset=preset)
    for t1, t0, t2 in random_angles(np.random.default_rng(3)):
        J = arm.jacobian([t1, t0, t2])  # model order q = [theta1, theta0, theta2]
        thesis_cols = J[:3][:, [0, 2, 1]]  # -> thesis order theta1, theta2, theta0
        np.testing.assert_allclose(thesis_cols, thesis_jacobian(t1, t0, t2, L1, L2), atol=1e-12)


@pytest.mark.parametrize("preset,L1,L2", PRESETS)
def test_thesis_jacobian_entries_are_the_derivatives_of_eq_3_13(preset, L1, L2):
    h = 1e-6
    for t1, t0, t2 in random_angles(np.random.default_rng(4)):
        fd = np.empty((3, 3))
        for col, bump in enumerate(([h, 0, 0], [0, 0, h], [0, h, 0])):  # theta1, theta2, theta0
            b1, b0, b2 = bump
            fd[:, col] = (thesis_position(t1 + b1, t0 + b0, t2 + b2, L1, L2)
                          - thesis_position(t1 - b1, t0 - b0, t2 - b2, L1, L2)) / (2 * h)
        np.testing.assert_allclose(thesis_jacobian(t1, t0, t2, L1, L2), fd, atol=1e-8)


def test_thesis_jacobian_at_a_worked_pose():
    """At theta = 0 the arm lies along x: moving theta1 or theta2 sweeps y, theta0 dips z."""
    J = thesis_jacobian(0.0, 0.0, 0.0, 0.185, 0.25)
    np.testing.assert_allclose(J, [[0, 0, 0], [0.435, 0.25, 0], [0, 0, -0.435]], atol=1e-15)


def _chains(name):
    """The serial chains of a known robot (each leg of the quadruped); skip if not written."""
    path = ROBOTS_DIR / ROBOT_FILES[name]
    if not path.exists():
        pytest.skip(f"{path.name} is not written yet "
                    f"(armlab/kinematics/robots/{path.name} missing)")
    model = load_robot(name)
    if isinstance(model, Quadruped):
        return list(model.legs.values())
    return [model]


def _angular_fd(chain, q, i, h):
    """Angular velocity of the end effector per unit rate of joint i, by central differences."""
    dq = np.zeros(chain.n)
    dq[i] = h
    R_plus, R_minus = chain.fk(q + dq)[:3, :3], chain.fk(q - dq)[:3, :3]
    W = (R_plus - R_minus) / (2 * h) @ chain.fk(q)[:3, :3].T  # skew(omega)
    return np.array([W[2, 1], W[0, 2], W[1, 0]])


@pytest.mark.parametrize("name", list(ROBOT_FILES))
def test_jacobian_matches_finite_differences_of_fk(name):
    rng = np.random.default_rng(5)
    h = 1e-6
    for chain in _chains(name):
        for _ in range(10):
            q = rng.uniform(chain.lower, chain.upper)
            J = chain.jacobian(q)
            for i in range(chain.n):
                dq = np.zeros(chain.n)
                dq[i] = h
                lin = (chain.fk(q + dq)[:3, 3] - chain.fk(q - dq)[:3, 3]) / (2 * h)
                np.testing.assert_allclose(J[:3, i], lin, atol=1e-8, err_msg=f"{chain.name} {i}")
                np.testing.assert_allclose(J[3:, i], _angular_fd(chain, q, i, h), atol=1e-8,
                                           err_msg=f"{chain.name} joint {i} angular")


@pytest.mark.parametrize("name", list(ROBOT_FILES))
def test_one_pass_fk_and_jacobian_equal_the_separate_ones(name):
    rng = np.random.default_rng(6)
    for chain in _chains(name):
        for _ in range(10):
            q = rng.uniform(chain.lower, chain.upper)
            T, J = fk_and_jacobian(chain, q)
            np.testing.assert_allclose(T, fk(chain, q), atol=1e-14)
            np.testing.assert_allclose(J, jacobian(chain, q), atol=1e-14)
            np.testing.assert_allclose(chain.link_poses(q)[-1] @ chain.tip, T, atol=1e-14)


@pytest.mark.parametrize("bad", [[0.1, 0.2], [[0.1, 0.2, 0.3]], [0.1, np.nan, 0.3],
                                 [0.1, np.inf, 0.3], "abc"])
@pytest.mark.parametrize("func", [fk, jacobian, fk_and_jacobian])
def test_bad_joint_vector_names_q(func, bad):
    arm = load_robot("receptionist_arm")
    with pytest.raises(ValueError, match=r"^q "):
        func(arm, bad)


def test_unknown_robot_lists_every_known_one():
    with pytest.raises(ValueError) as info:
        load_robot("receptionist")
    for name in ROBOT_FILES:
        assert name in str(info.value)


def test_unknown_preset_lists_the_presets():
    with pytest.raises(ValueError, match="18.5/25"):
        load_robot("receptionist_arm", preset="20/20")


GOOD_JOINT = """<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
  <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"""


def _urdf(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "broken.urdf"
    path.write_text(f'<?xml version="1.0"?>\n<robot name="broken">{body}</robot>\n')
    return path


@pytest.mark.parametrize("body,reason", [
    ('<link name="base"/><link name="arm"/>' + GOOD_JOINT + "<link", "not valid XML"),
    ('<link name="base"/><link name="arm"/>'
     '<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>'
     '<axis xyz="0 0 1"/></joint>', "needs a <limit>"),
    ('<link name="base"/><link name="arm"/>' + GOOD_JOINT.replace('link="arm"', 'link="hand"'),
     "unknown link 'hand'"),
    ('<link name="base"/><link name="arm"/>' + GOOD_JOINT.replace('"0 0 1"', '"0 0 x"'),
     "cannot read numbers"),
    ('<link name="base"/><link name="arm"/>' + GOOD_JOINT.replace('"0 0 1"', '"0 0 0"'),
     "zero axis"),
])
def test_malformed_urdf_names_file_and_reason(tmp_path, body, reason):
    path = _urdf(tmp_path, body)
    with pytest.raises(URDFError) as info:
        load_robot(path)
    assert str(path) in str(info.value)
    assert reason in str(info.value)


def test_missing_urdf_file_is_named(tmp_path):
    path = tmp_path / "nowhere.urdf"
    with pytest.raises(URDFError, match="no such file") as info:
        load_robot(path)
    assert str(path) in str(info.value)


def test_well_formed_temp_urdf_loads(tmp_path):
    """The fixture above is valid without the defect, so each failure is the defect's."""
    chain = load_robot(_urdf(tmp_path, '<link name="base"/><link name="arm"/>' + GOOD_JOINT))
    assert chain.n == 1 and chain.joint_names == ("j1",)


def test_fk_and_jacobian_of_a_slide_carried_by_a_turning_joint(tmp_path):
    """A prismatic joint (z_i; 0 column) behind a tilted revolute one: the generated
    one-pass FK equals the 4x4 product and its Jacobian the finite differences."""
    path = tmp_path / "slide.urdf"
    path.write_text("""<?xml version="1.0"?>
<robot name="slide"><link name="base"/><link name="a"/><link name="b"/><link name="tip"/>
  <joint name="turn" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0.05 0.1" rpy="0.2 0 0.4"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0.2 0 0" rpy="0 0.3 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="0" upper="0.3" effort="50" velocity="1"/></joint>
  <joint name="wrist" type="fixed"><parent link="b"/><child link="tip"/>
    <origin xyz="0.05 0.02 0" rpy="0.1 0 0"/></joint></robot>""")
    chain = chain_from_urdf(path)
    h = 1e-6
    for q in ([0.4, 0.1], [-1.2, 0.25]):
        q = np.array(q)
        T, J = fk_and_jacobian(chain, q)
        np.testing.assert_allclose(chain.link_poses(q)[-1] @ chain.tip, T, atol=1e-14)
        for i in range(2):
            dq = np.zeros(2)
            dq[i] = h
            lin = (chain.fk(q + dq)[:3, 3] - chain.fk(q - dq)[:3, 3]) / (2 * h)
            np.testing.assert_allclose(J[:3, i], lin, atol=1e-8)
            np.testing.assert_allclose(J[3:, i], _angular_fd(chain, q, i, h), atol=1e-8)
        assert np.allclose(J[3:, 1], 0.0)  # a slide does not turn the hand
