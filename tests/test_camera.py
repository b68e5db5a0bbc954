"""The robot is the picture: each lesson's camera frames its own robot and task.

:func:`armlab.app.page.camera.frame_points` puts the camera just far enough back for every framed
point to lie within ``FILL`` of the view's edges; :func:`armlab.app.page.camera.node_points` finds
the framed points in the scene graph (world poses composed down the node names, hidden
nodes left out). Then, on the wire (a headless page reporting its view as a browser
does): every lesson frames its robot over at least 40 % of the view's height at a
projector's 16:9 and inside the view at the narrow 3D area two docked panels leave
at 1280x720; a page whose view changes shape is framed again, an orbit is left alone,
and "Frame" brings the framed view back.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest
import viser
from _helpers import client_of, project, settled
from hypothesis import given
from hypothesis import strategies as st

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons.catalog import all_lessons
from armlab.app.lessons.compliance_scene import TRAIL_DOTS, ComplianceScene
from armlab.app.page import camera
from armlab.app.page.camera import FILL, View, frame_points, node_points
from armlab.app.testing.wsclient import HeadlessClient
from armlab.app.viser_ext.handles import scene_nodes
from armlab.kinematics import load_robot

unit = st.floats(-1.0, 1.0, allow_nan=False)


@given(points=st.lists(st.tuples(unit, unit, unit), min_size=1, max_size=12),
       direction=st.tuples(unit, unit, unit).filter(
           lambda d: np.linalg.norm(d) > 0.1 and np.linalg.norm(np.cross(d, (0, 0, 1))) > 0.1),
       aspect=st.floats(0.4, 2.5), fov=st.floats(0.3, 2.0))
def test_framed_points_reach_fill_of_the_view_and_no_further(points, direction, aspect, fov):
    pts = np.array(points)
    position, look_at = frame_points(pts, direction=direction, fov=fov, aspect=aspect)
    x, y, depth = project(pts, position, look_at, (0, 0, 1), fov, aspect)
    assert np.all(depth >= camera.NEAR - 1e-9)
    reach = np.maximum(np.abs(x), np.abs(y))
    assert np.all(reach <= FILL + 1e-9)
    # just far enough: the outermost point is at FILL, unless all points sit within
    # NEAR of the camera's plane through the centre (then NEAR sets the distance)
    if float(np.max(reach)) < FILL - 1e-9:
        assert np.isclose(float(np.min(depth)), camera.NEAR)


def test_frame_points_refuses_what_cannot_be_framed():
    with pytest.raises(ValueError, match="points"):
        frame_points(np.empty((0, 3)), direction=(1, 0, 0))
    with pytest.raises(ValueError, match="points"):
        frame_points(np.array([[0.0, np.nan, 0.0]]), direction=(1, 0, 0))
    with pytest.raises(ValueError, match="direction"):
        frame_points(np.zeros((1, 3)), direction=(0, 0, -1))  # along up


def test_node_points_compose_poses_and_leave_hidden_and_non_finite_nodes_out():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        quarter = (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))  # 90° about z
        server.scene.add_frame("/a", position=(1.0, 0.0, 0.0), wxyz=quarter)
        server.scene.add_frame("/a/b", position=(0.5, 0.0, 0.0))  # a's x is world y
        server.scene.add_icosphere("/a/b/c", radius=0.01, position=(0.0, 0.0, 0.2))
        server.scene.add_frame("/a/hidden", position=(9.0, 9.0, 9.0), visible=False)
        server.scene.add_icosphere("/a/hidden/child", radius=0.01)
        server.scene.add_frame("/elsewhere", position=(5.0, 5.0, 5.0))
        server.scene.add_frame("/a/lost", position=(math.nan, 0.0, 0.0))  # nothing to show
        server.scene.add_icosphere("/a/lost/child", radius=0.01)
        pts = node_points(server.scene, ("/a",))
        expected = np.array([[1.0, 0.0, 0.0], [1.0, 0.5, 0.0], [1.0, 0.5, 0.2]])
        assert pts.shape == (3, 3)
        assert np.allclose(sorted(map(tuple, pts)), sorted(map(tuple, expected)))
        assert node_points(server.scene, ("/nothing",)).shape == (0, 3)
    finally:
        server.stop()


def test_a_gizmo_is_framed_with_the_reach_of_its_arrows():
    """A hand target's gizmo reaches ``scale`` out from its point (the URDF arm's ran off
    the top of a 1280x720 view when only its point was framed)."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        server.scene.add_transform_controls("/t", scale=0.08, position=(1.0, 0.0, 0.5))
        pts = camera.framed_points(server.scene, ("/t",))
        assert np.allclose(pts.min(axis=0), (0.92, -0.08, 0.42))
        assert np.allclose(pts.max(axis=0), (1.08, 0.08, 0.58))
    finally:
        server.stop()


def test_the_compliance_camera_frames_the_arm_and_its_task_not_the_hands_trail():
    """The trail is the hand's history: the arm's move to its start leaves dots far from
    where it then stands, and later dots replace them. Framed, they would move the camera
    (and leave the resting arm small, or out of the view framed a moment before)."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        rig = ComplianceScene(server, load_robot("receptionist_arm"),
                              path=np.array([[0.15, 0.0, 0.0], [0.15, 0.2, 0.0]]), root="/c",
                              on_target=lambda _p: None, on_drag_hand=lambda *_a: None)
        view = camera._views[server.scene]
        before = node_points(server.scene, view.roots)
        far = np.array([1.5, -1.0, 0.5])  # base frame, m
        for i in range(TRAIL_DOTS):
            rig.add_trail(far + 0.01 * i)
        after = node_points(server.scene, view.roots)
        assert np.array_equal(before, after)
        # what is framed: the arm, its ghost and the line's ends (world = base pose @ p)
        base = np.asarray(rig.model.base_pose, dtype=float)
        for end in ((0.15, 0.0, 0.0), (0.15, 0.2, 0.0)):
            world = base[:3, :3] @ end + base[:3, 3]
            assert np.min(np.linalg.norm(before - world, axis=1)) < 1e-9
    finally:
        server.stop()


def _framed(lab: Lab) -> tuple[View, np.ndarray]:
    view = camera._views[lab.server.scene]
    return view, node_points(lab.server.scene, view.roots)


#: m: a resting arm still moves by a count or so of its servos (0.29° is 1.5 mm at the
#: thesis arm's hand); the framings compared differ by decimetres
STILL_M = 2e-3
SAME_M = 1e-2


def _at_rest(lab: Lab, page: HeadlessClient) -> None:
    """Until the framed points stand still (a lesson's arm moves to its start first)."""
    last: list[np.ndarray] = []

    def still() -> bool:
        now = _framed(lab)[1]
        same = bool(last) and last[0].shape == now.shape and np.allclose(last[0], now,
                                                                          atol=STILL_M)
        last[:] = [now]
        return same

    page.wait_for(still, what="the lesson's robot to stand still")


def _shows_framing(page: HeadlessClient, lab: Lab, *, fov: float, aspect: float
                   ) -> camera.Framing:
    """Until the server has framed the page for the view it reported (``fov``, ``aspect``)
    and the page's camera shows that framing; returns it. Its points are the robot as it
    stood when the page was framed (under load a starved loop can still be bringing the
    arm to its start after it looked still: the framing does not chase it)."""

    def framing() -> camera.Framing | None:
        for client in list(lab.server.get_clients().values()):
            f = camera.last_framing.get(client)
            if f is not None and math.isclose(f.fov, fov, rel_tol=1e-6) \
                    and math.isclose(f.aspect, aspect, rel_tol=1e-6):
                return f
        return None

    def there() -> bool:
        f, cam = framing(), page.camera
        return (f is not None and "look_at" in cam
                and np.allclose(cam["position"], f.position, atol=SAME_M)
                and np.allclose(cam["look_at"], f.look_at, atol=SAME_M))

    try:
        page.wait_for(there, what=f"the framing for a {aspect:.2f} view")
    except TimeoutError as exc:
        for client in list(lab.server.get_clients().values()):
            if (f := camera.last_framing.get(client)) is not None:
                exc.add_note(f"the page's last framing was for fov {f.fov:.3f} rad, "
                             f"aspect {f.aspect:.3f}; its camera is at {page.camera}")
        raise
    shown = framing()
    assert shown is not None
    return shown


#: (width, height) of a page's 3D view: a 1920x1080 projector's and the narrow area two
#: docked panels leave at 1280x720, and a 390x844 phone's (above its controls)
VIEWS = ((1600, 1000), (458, 640), (390, 345))
FOV = 1.2  # rad, the page's vertical field of view


@pytest.mark.parametrize("lesson", sorted(all_lessons()))
@pytest.mark.slow
def test_every_lesson_frames_its_robot_in_the_page_view(lesson):
    with Lab(ServeOptions(http_port=0, lesson=lesson, realtime=False)) as lab, \
            client_of(lab.server, token=lab.token) as page:
        _at_rest(lab, page)
        view = camera._views[lab.server.scene]
        for width, height in VIEWS:
            page.report_view(width=width, height=height, fov=FOV)
            aspect = width / height
            points = _shows_framing(page, lab, fov=FOV, aspect=aspect).points
            assert len(points) >= 3
            x, y, depth = project(points, page.camera["position"], page.camera["look_at"],
                                   view.up, FOV, aspect)
            assert np.all(depth > 0) and np.all(np.abs(x) <= 1) and np.all(np.abs(y) <= 1)
            if aspect > 1.0:  # a projector's view: the robot is the picture
                span = (y.max() - y.min()) / 2.0
                assert span >= 0.4, (lesson, width, height, span)
            boxes = _label_boxes(lab.server.scene, page, view.up, width, height)
            for name, box in boxes:
                assert box[0] >= 0 and box[1] >= 0 and box[2] <= width and \
                    box[3] <= height, (lesson, name, (width, height), box)
            for i, (a, box_a) in enumerate(boxes):  # and no two over each other
                for b, box_b in boxes[i + 1:]:
                    apart = (box_a[2] <= box_b[0] or box_b[2] <= box_a[0]
                             or box_a[3] <= box_b[1] or box_b[3] <= box_a[1])
                    assert apart, (lesson, a, b, (width, height), box_a, box_b)


#: px tall a screen-sized label's text is per unit of ``font_screen_scale`` (viser draws
#: scale 1 about 12 px tall) and px wide per character per px of height (measured in
#: Chromium: "thesis 20 cm line" is 156 px wide at 20 px tall, 0.46; 0.5 leaves room)
LABEL_PX_PER_SCALE = 12.0
LABEL_CHAR_EM = 0.5


def _label_boxes(scene, page, up, width: int, height: int):  # noqa: ANN001, ANN202
    """(name, (left, top, right, bottom) px) of every screen-sized label with words that
    the scene shows, where the page's camera puts it in a ``width`` x ``height`` view: its
    anchor's place and its text's estimated size, laid out by its anchor (a label that runs
    out of the view, or under a docked panel beside it, is cut)."""
    out = []
    for name, handle in scene_nodes(scene).items():
        if not isinstance(handle, viser.LabelHandle) or not handle.text \
                or handle.font_size_mode != "screen" or not len(node_points(scene, (name,))):
            continue
        point = node_points(scene, (name,))[0]
        x, y, depth = project(point[None, :], page.camera["position"],
                              page.camera["look_at"], up, FOV, width / height)
        assert depth[0] > 0, name
        px, py = (x[0] + 1.0) / 2.0 * width, (1.0 - y[0]) / 2.0 * height
        tall = LABEL_PX_PER_SCALE * float(handle.font_screen_scale)
        lines = str(handle.text).split("\n")
        w, h = LABEL_CHAR_EM * tall * max(map(len, lines)), tall * len(lines)
        vertical, horizontal = str(handle.anchor).split("-")
        left = {"left": px, "center": px - w / 2.0, "right": px - w}[horizontal]
        top = {"top": py, "center": py - h / 2.0, "bottom": py - h}[vertical]
        out.append((name, (left, top, left + w, top + h)))
    return out


def test_an_orbit_is_left_alone_and_frame_brings_the_view_back():
    with Lab(ServeOptions(http_port=0, lesson="compliance", realtime=False)) as lab, \
            client_of(lab.server, token=lab.token) as page:
        _at_rest(lab, page)
        page.report_view(width=1000, height=700, fov=FOV)
        _shows_framing(page, lab, fov=FOV, aspect=1000 / 700)
        (client,) = lab.server.get_clients().values()
        # the page orbits: the same view shape, another camera
        page.report_view(width=1000, height=700, fov=FOV, position=(2.0, 2.0, 2.0),
                         look_at=(0.0, 0.0, 0.0))
        page.wait_for(lambda: np.allclose(client.camera.position, (2.0, 2.0, 2.0)),
                      what="the server to hear the orbit")
        sets = page.camera_sets
        settled(client, page)  # (the page's own stream, which carries its camera)
        assert page.camera_sets == sets  # the server left the orbit alone
        page.wait_for(lambda: page.shows("Frame"), what="the Frame button")
        page.click("Frame")
        page.wait_for(lambda: page.camera_sets > sets, what="the camera to move")
        _shows_framing(page, lab, fov=FOV, aspect=1000 / 700)


def test_a_page_that_reshapes_before_taking_a_framing_is_framed_for_its_last_shape():
    """The race behind a reloaded page left framed for a narrower view than it has: the
    page narrows and is framed for that, but widens again before the framing arrives,
    reporting the camera it had, which is already the framing for its new shape. viser
    sends nothing for a camera value equal to the page's last report, so the framing is
    sent by hand: else the older one would land last and stay. (A lesson whose robot
    stands still, so the framing for the wide view is the same to the last bit.)"""
    with Lab(ServeOptions(http_port=0, lesson="ik_accuracy", realtime=False)) as lab, \
            client_of(lab.server, token=lab.token) as page:
        page.report_view(width=852, height=720, fov=FOV)
        wide = _shows_framing(page, lab, fov=FOV, aspect=852 / 720)
        had = {"position": tuple(map(float, wide.position)),
               "look_at": tuple(map(float, wide.look_at))}
        page.report_view(width=458, height=720, fov=FOV, **had)
        narrow = _shows_framing(page, lab, fov=FOV, aspect=458 / 720)
        assert not np.allclose(narrow.position, wide.position, atol=SAME_M)
        # the page widens before it took the narrow framing: its camera is the wide one
        page.report_view(width=852, height=720, fov=FOV, **had)
        again = _shows_framing(page, lab, fov=FOV, aspect=852 / 720)
        assert np.array_equal(again.position, wide.position)  # what the page reported


def test_a_framing_for_a_shape_the_page_has_left_never_lands_after_its_new_one(monkeypatch):
    """Framings of one page are made in several threads (viser runs each camera report's
    callbacks in a pool, the Frame button another): one for the page's old shape, slow to
    be worked out, must not land after the one for the shape it reported since. (Under
    two CPU burners a page's first framing once lost this way to its connect-time one,
    and stayed framed for a view it no longer had.)"""
    with Lab(ServeOptions(http_port=0, lesson="ik_accuracy", realtime=False)) as lab, \
            client_of(lab.server, token=lab.token) as page:
        page.report_view(width=852, height=720, fov=FOV)
        _shows_framing(page, lab, fov=FOV, aspect=852 / 720)
        (client,) = lab.server.get_clients().values()
        working, go_on = threading.Event(), threading.Event()
        frame_points_now = camera.frame_points

        def slow_first(*args, **kwargs):  # the first framing from here on waits for go_on
            if not working.is_set():
                working.set()
                go_on.wait(120.0)
            return frame_points_now(*args, **kwargs)

        monkeypatch.setattr(camera, "frame_points", slow_first)
        late = threading.Thread(target=camera.reframe, args=(client,), daemon=True)
        late.start()  # "Frame", for the 852x720 view the page has now
        assert working.wait(120.0), "the first framing never started"
        page.report_view(width=458, height=720, fov=FOV)  # a side panel opened meanwhile
        narrow = _shows_framing(page, lab, fov=FOV, aspect=458 / 720)
        go_on.set()
        late.join(120.0)
        assert not late.is_alive()
        settled(client, page)
        assert camera.last_framing[client] is narrow
        assert _shows_framing(page, lab, fov=FOV, aspect=458 / 720) is narrow


def test_carry_moves_a_pages_camera_and_its_look_at_without_turning_it():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with client_of(server) as page:
            (client,) = server.get_clients().values()
            page.wait_for(lambda: client.camera._state.update_timestamp != 0.0,
                          what="the page's camera report")
            before = (client.camera.position.copy(), client.camera.look_at.copy(),
                      client.camera.wxyz.copy())
            assert camera.carry(client, (0.05, -0.02, 0.0))
            np.testing.assert_allclose(client.camera.position, before[0] + (0.05, -0.02, 0.0))
            np.testing.assert_allclose(client.camera.look_at, before[1] + (0.05, -0.02, 0.0))
            np.testing.assert_array_equal(client.camera.wxyz, before[2])  # not turned
            want = tuple((before[0] + (0.05, -0.02, 0.0)).tolist())
            want_at = tuple((before[1] + (0.05, -0.02, 0.0)).tolist())
            # position and look-at go out as two messages: wait for both
            page.wait_for(lambda: page.camera.get("position") == pytest.approx(want)
                          and page.camera.get("look_at") == pytest.approx(want_at),
                          what="the carried camera and its look-at on the page")
            # a non-finite offset moves nothing
            assert not camera.carry(client, (math.nan, 0.0, 0.0))
            np.testing.assert_allclose(client.camera.position, want)
    finally:
        server.stop()
