"""A URDF as it comes, drawn: every link with a <visual> reaches the page, a missing mesh
is warned about once by name and its link is drawn from collision shapes or a capsule."""

from __future__ import annotations

import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
import viser

from armlab.app.page.arm_view import ArmView
from armlab.app.testing.wsclient import HeadlessClient
from armlab.kinematics import load_robot
from armlab.kinematics.urdf_meshes import MissingMeshWarning
from tests._helpers import wait_for

DATA = Path(__file__).with_name("data")
MESH_KINDS = ("MeshMessage", "GlbMessage", "BoxMessage", "CylinderMessage", "IcosphereMessage")


def _draw(model, server, root="/arm"):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        view = ArmView(server, model, root=root)
    missing = [str(w.message) for w in caught if issubclass(w.category, MissingMeshWarning)]
    return view, missing


@pytest.fixture
def server():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield server
    server.stop()


def test_every_link_reaches_the_page_and_each_missing_mesh_is_named_once(server):
    from armlab.kinematics import urdf_meshes as urdf_module

    urdf_module._warned.clear()
    model = load_robot(DATA / "mobile_manipulator.urdf", tip_link="tcp_link")
    view, missing = _draw(model, server)
    assert view.drawn_as == {
        "base_link": "visual", "wheel_left_link": "visual", "wheel_right_link": "visual",
        "tray_link": "visual", "camera_link": "capsule", "arm_base_link": "visual",
        "shoulder_link": "collision", "upper_arm_link": "capsule", "forearm_link": "visual",
        "gripper_base_link": "visual", "finger_left_link": "visual",
        "finger_right_link": "visual"}
    assert len(missing) == 3
    for name, link in [("camera.stl", "camera_link"), ("shoulder.dae", "shoulder_link"),
                       ("upper_arm.dae", "upper_arm_link")]:
        assert sum(name in m and repr(link) in m for m in missing) == 1, missing
    # A second view of the same file (a ghost arm, another lesson) warns no more.
    _, again = _draw(model, server, root="/ghost")
    assert again == []

    # What a page receives: a mesh node directly under every drawn link's frame.
    shapes: dict[str, list[str]] = {}
    lock = threading.Lock()

    def on_message(m: dict, _t: float) -> None:
        if m.get("type") in MESH_KINDS and "name" in m:
            with lock:
                parent = m["name"].rsplit("/", 1)[0]
                shapes.setdefault(parent, []).append(m["type"])

    with HeadlessClient(f"ws://127.0.0.1:{server.get_port()}",
                        on_message=on_message).connect(10.0):
        frames = {link: view.link_frames[link].name for link in view.drawn_as}
        wait_for(lambda: all(f in shapes for f in frames.values()), 30.0,
                 "a shape under every link frame")
    view.set_q(np.array([0.3, -0.4, 1.0, 0.2]))


def test_package_path_finds_the_camera_mesh(server):
    from armlab.kinematics import urdf_meshes as urdf_module

    urdf_module._warned.clear()
    model = load_robot(DATA / "mobile_manipulator.urdf", tip_link="tcp_link",
                       package_paths=(DATA / "extra_packages",))
    view, missing = _draw(model, server)
    assert view.drawn_as["camera_link"] == "visual"
    assert not any("camera.stl" in m for m in missing)
    assert len(missing) == 2


def test_panda_without_its_meshes_is_drawn_from_collision_spheres(server):
    from armlab.kinematics import urdf_meshes as urdf_module

    urdf_module._warned.clear()
    view, missing = _draw(load_robot(DATA / "panda_style.urdf"), server)
    assert len(missing) == 11  # link0..7, hand, two fingers: one warning each
    assert set(view.drawn_as.values()) == {"collision"}


def test_a_link_drawn_see_through_hides_its_mesh_for_a_translucent_copy(server):
    view = ArmView(server, load_robot("receptionist_arm"), root="/through")
    torso = view.link_frames["torso"].name
    nodes = server.scene._handle_from_node_name
    own = [h for n, h in nodes.items() if n.rsplit("/", 1)[0] == torso and "geometry" in n]
    assert own and all(h.visible for h in own)
    assert view.see_through("torso", opacity=0.3)
    assert not any(h.visible for h in own)  # the opaque box is hidden...
    copy = nodes[f"{torso}/see_through"]
    assert copy.visible and copy.opacity == pytest.approx(0.3)  # ...and drawn translucent
    assert not view.see_through("no_such_link")
    assert not view.see_through("shoulder_pitch_link")  # a link with nothing to draw


def test_a_finger_and_the_finger_that_mimics_it_slide_together(server):
    """``set_joint`` poses the OpenManipulator-X's prismatic finger and its mimic (the other
    finger, multiplier · value + offset from the URDF), again and again from the same
    joints it found the first time."""
    model = load_robot("open_manipulator_x")
    view, _ = _draw(model, server)
    joints = view._urdf._urdf.joint_map
    left = joints["gripper_left_joint"]
    (right,) = [j for j in joints.values()
                if j.mimic is not None and j.mimic.joint == "gripper_left_joint"]
    mult, off = right.mimic.multiplier or 1.0, right.mimic.offset or 0.0
    for value in (0.0, 0.012, -0.005, 0.012):
        view.set_joint("gripper_left_joint", value)
        for j, v in ((left, value), (right, mult * value + off)):
            axis = np.asarray(j.axis, dtype=float) / np.linalg.norm(j.axis)
            want = j.origin[:3, 3] + j.origin[:3, :3] @ (axis * v)
            np.testing.assert_allclose(view.link_frames[j.child].position, want, atol=1e-12)
