"""Real URDFs as they come: tip links, joints off the chain, limits, mimic, package://.

The three files in tests/data are written in three publishers' styles (a ROS mobile
manipulator, Franka's Panda, a hobby 2-joint arm). Forward kinematics is checked
against a computation written here from the file's numbers with plain homogeneous
transforms, independent of armlab.kinematics.transforms and armlab.kinematics.fk.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from armlab.kinematics import URDFError, load_robot
from armlab.kinematics.urdf_meshes import resolve_resource
from armlab.kinematics.urdf_read import CONTINUOUS_LIMIT

DATA = Path(__file__).with_name("data")
MOBILE = DATA / "mobile_manipulator.urdf"
PANDA = DATA / "panda_style.urdf"
TWO = DATA / "two_joint_arm.urdf"


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation, written out."""
    x, y, z = axis / np.linalg.norm(axis)
    c, s, v = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return np.array([[c + x * x * v, x * y * v - z * s, x * z * v + y * s],
                     [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
                     [z * x * v - y * s, z * y * v + x * s, c + z * z * v]])


def _origin(el: ET.Element | None) -> np.ndarray:
    T = np.eye(4)
    if el is None:
        return T
    x, y, z = (float(v) for v in el.get("xyz", "0 0 0").split())
    r, p, w = (float(v) for v in el.get("rpy", "0 0 0").split())
    ex, ey, ez = np.eye(3)
    T[:3, :3] = _rot(ez, w) @ _rot(ey, p) @ _rot(ex, r)  # URDF: fixed-axis roll, pitch, yaw
    T[:3, 3] = (x, y, z)
    return T


def _world_pose(path: Path, tip: str, q: dict[str, float]) -> np.ndarray:
    """root <- tip from the file: joint origins times rotations about the axes."""
    joints = {j.find("child").get("link"): j for j in ET.parse(path).getroot().iter("joint")}
    T = np.eye(4)
    link = tip
    while link in joints:
        j = joints[link]
        step = _origin(j.find("origin"))
        if j.get("type") in ("revolute", "continuous"):
            axis = np.array([float(v) for v in j.find("axis").get("xyz").split()])
            R = np.eye(4)
            R[:3, :3] = _rot(axis, q[j.get("name")])
            step = step @ R
        T = step @ T
        link = j.find("parent").get("link")
    return T


@pytest.mark.parametrize("path,tip,n", [(MOBILE, "tcp_link", 4), (PANDA, "panda_hand_tcp", 7),
                                        (TWO, "tool_link", 2)])
def test_fk_matches_plain_transforms_of_the_file(path, tip, n):
    chain = load_robot(path, tip_link=tip)
    assert chain.n == n
    rng = np.random.default_rng(14)
    for _ in range(25):
        q = rng.uniform(chain.lower, chain.upper)
        angles = dict(zip(chain.joint_names, q, strict=True))
        expected = _world_pose(path, tip, angles)
        np.testing.assert_allclose(chain.base_pose @ chain.fk(q), expected, atol=1e-9)
        # Every moving link too (the viewer's frames).
        for i, name in enumerate(chain.link_names):
            np.testing.assert_allclose(chain.base_pose @ chain.link_poses(q)[i],
                                       _world_pose(path, name, angles),
                                       atol=1e-9)


def test_default_tip_skips_camera_wheels_and_gripper_fingers():
    """Without tip_link: the leaf below the most revolute joints, not a finger or camera."""
    assert load_robot(MOBILE).link_names[-1] == "gripper_base_link"
    assert load_robot(MOBILE).joint_names == load_robot(MOBILE, tip_link="tcp_link").joint_names
    np.testing.assert_allclose(load_robot(MOBILE).tip[:3, 3], [0.1, 0, 0], atol=1e-15)
    assert load_robot(PANDA).joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    np.testing.assert_allclose(load_robot(PANDA).tip[:3, 3], [0, 0, 0.107 + 0.1034], atol=1e-12)
    omx = load_robot("open_manipulator_x")
    assert omx.joint_names == ("joint1", "joint2", "joint3", "joint4")
    np.testing.assert_allclose(omx.fk(np.zeros(4))[:3, 3], [0.286, 0, 0.2045], atol=1e-12)


def test_limits_come_from_the_file_and_continuous_ones_default():
    mobile = load_robot(MOBILE, tip_link="tcp_link")
    np.testing.assert_array_equal(mobile.lower, [-2.5, -1.9, -CONTINUOUS_LIMIT, -3.0])
    np.testing.assert_array_equal(mobile.upper, [2.5, 1.9, CONTINUOUS_LIMIT, 3.0])
    assert [j.limit_default for j in mobile.joints] == [False, False, True, False]
    assert [j.effort for j in mobile.joints] == [10.0, 10.0, 8.0, 3.0]
    two = load_robot(TWO)  # a continuous joint whose <limit> states a range keeps it
    np.testing.assert_array_equal(two.lower, [-2.6, -1.8])
    assert not any(j.limit_default for j in two.joints)
    panda = load_robot(PANDA, tip_link="panda_hand_tcp")
    assert panda.lower[3] == -3.0718 and panda.upper[3] == -0.0698


def test_base_pose_takes_the_floating_base_at_zero_and_the_mount():
    mobile = load_robot(MOBILE, tip_link="tcp_link")
    np.testing.assert_allclose(mobile.base_pose[:3, 3], [0.1, 0, 0.08 + 0.06], atol=1e-15)
    np.testing.assert_allclose(mobile.gravity, [0, 0, -9.81], atol=1e-12)


@pytest.mark.parametrize("tip,joint,words", [
    ("finger_right_link", "finger_right_joint", "mimics joint 'finger_left_joint'"),
])
def test_an_undrivable_joint_on_the_chain_is_named(tip, joint, words):
    with pytest.raises(URDFError) as info:
        load_robot(MOBILE, tip_link=tip)
    assert f"joint {joint!r}" in str(info.value) and words in str(info.value)
    assert str(MOBILE) in str(info.value)


def test_a_floating_joint_after_the_first_moving_one_is_named(tmp_path):
    text = TWO.read_text().replace('name="elbow" type="continuous"', 'name="elbow" type="floating"')
    path = tmp_path / "floating_elbow.urdf"
    path.write_text(text)
    with pytest.raises(URDFError, match="joint 'elbow' on the chain to 'tool_link' is floating"):
        load_robot(path)
    # Off the chain the same joint is ignored.
    assert load_robot(path, tip_link="arm_link").joint_names == ("yaw",)


def test_unknown_tip_link_lists_the_links():
    with pytest.raises(URDFError, match="no link named 'hand'.*panda_hand_tcp"):
        load_robot(PANDA, tip_link="hand")


def test_package_names_resolve_against_parents_and_package_paths():
    found = resolve_resource("package://mm_description/meshes/arm_base.stl", urdf_path=MOBILE)
    assert found == (DATA / "mm_description/meshes/arm_base.stl").resolve()
    camera = "package://mm_sensors/meshes/camera.stl"
    assert resolve_resource(camera, urdf_path=MOBILE) is None
    assert resolve_resource(camera, urdf_path=MOBILE,
                            package_paths=(DATA / "extra_packages",)) == \
        (DATA / "extra_packages/mm_sensors/meshes/camera.stl").resolve()
    # A package path naming the package folder itself works too.
    assert resolve_resource(camera, urdf_path=MOBILE,
                            package_paths=(DATA / "extra_packages/mm_sensors",)) is not None
    assert resolve_resource("package://mm_description/meshes/upper_arm.dae",
                            urdf_path=MOBILE) is None
    assert resolve_resource("meshes/visual/panda_link0.dae", urdf_path=PANDA) is None
