"""Pointing the 3D view: each lesson's camera frames its own robot and task.

A lesson names what it shows (:class:`View`: its scene roots and a viewing direction)
with :func:`show`; the camera then stands just far enough back along that direction for
the visible nodes under those roots, shapes and all (:func:`framed_points`), to fill the
3D view (:func:`frame_points`), on new pages, on the pages already open (each for its own
field of view and aspect), and again on a page's "Frame" button or when its 3D view
changes shape (:func:`reframe`). A page may add nodes of its own scene to what its
framing of the shared view takes in (:func:`also_frame`: a presenter's ghost of a
student's arm, drawn on that page alone).

``server.initial_camera`` only sets where a *new* page starts (and where "Reset
View" returns); a page already open keeps its camera until it is moved.
"""

from __future__ import annotations

import itertools
import math
import threading
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser
import viser.transforms as vtf

from armlab.app.page.surface import Surface
from armlab.app.viser_ext.camera import send_view, shift_view
from armlab.app.viser_ext.clients import connected, server_of
from armlab.app.viser_ext.handles import scene_nodes

# -- framing: the camera that makes a lesson's robot the picture ------------------------

#: viser's vertical field of view (rad) until a page reports its own.
DEFAULT_FOV = math.radians(75.0)
#: Width / height of the 3D view until a page reports its own (a 16:9 projector).
DEFAULT_ASPECT = 16.0 / 9.0
#: How far from the view's centre towards its edge the outermost framed point may reach
#: (1 = the edge): the robot spans most of the view with a margin round it.
FILL = 0.8
#: Nearest the camera comes to a framed point, m.
NEAR = 0.05


@dataclass(frozen=True)
class View:
    """What a lesson's camera frames.

    Attributes:
        roots: scene node names; the origins of the visible nodes under them (the robot's
            link frames and meshes, the task's target, line or labels) are framed.
        direction: (3,) the direction the camera looks in, world (need not be unit).
        up: (3,) world direction shown upwards.
    """

    roots: tuple[str, ...]
    direction: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)


def frame_points(points: np.ndarray, *, direction: Sequence[float],
                 up: Sequence[float] = (0.0, 0.0, 1.0), fov: float = DEFAULT_FOV,
                 aspect: float = DEFAULT_ASPECT, fill: float = FILL
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The camera (position (3,), look_at (3,), world m) that looks along ``direction``
    at the centre of ``points`` (k, 3) from just far enough that every point lies within
    ``fill`` of the view's half-height and half-width (vertical field of view ``fov`` rad,
    width/height ``aspect``): the outermost point reaches ``fill`` of the way to an edge."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise ValueError("points: need at least one, all finite")
    forward = np.asarray(direction, dtype=float)
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(up, dtype=float))
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("direction: must not be parallel to up")
    right /= np.linalg.norm(right)
    upward = np.cross(right, forward)
    look_at = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    rel = pts - look_at
    x, y, z = rel @ right, rel @ upward, rel @ forward  # z: farther than the centre
    ty = math.tan(0.5 * fov) * fill
    tx = ty * aspect
    # a point at depth D + z shows at y / (D + z) of the focal length: within ty needs
    # D >= |y| / ty - z; likewise for x; and every point at least NEAR ahead
    distance = max(float(np.max(np.abs(y) / ty - z)), float(np.max(np.abs(x) / tx - z)),
                   float(np.max(NEAR - z)))
    return look_at - distance * forward, look_at


def node_points(scene: Any, roots: Sequence[str]) -> np.ndarray:
    """(k, 3) world positions of the origins of the visible scene nodes under ``roots``
    (``scene``: a server's or a page's ``viser`` scene; a node hidden, or under a hidden
    one, is left out, and so is one at a non-finite pose and what hangs under it: a
    lesson's marker with nothing to show yet is no place to aim a camera)."""
    out = [pose[:3, 3] for _, pose in _visible_poses(scene, roots)]
    return np.array(out, dtype=float).reshape(-1, 3)


def framed_points(scene: Any, roots: Sequence[str]) -> np.ndarray:
    """(k, 3) world points a lesson's view frames: :func:`node_points` and the corners of
    the boxes round the shapes of those nodes (meshes, spheres, boxes, cylinders), so that
    a link's mesh reaching beyond its frame's origin (the top of an arm) is framed too."""
    points = [np.zeros((0, 3))]
    for handle, pose in _visible_poses(scene, roots):
        points.append(pose[None, :3, 3])
        box = _local_box(handle)
        if box is not None:
            points.append(box @ pose[:3, :3].T + pose[:3, 3])
    return np.concatenate(points)


def _visible_poses(scene: Any, roots: Sequence[str]) -> list[tuple[Any, np.ndarray]]:
    """(handle, world pose (4, 4)) of the visible nodes under ``roots`` at finite poses
    (see :func:`node_points`)."""
    handles: dict[str, Any] = scene_nodes(scene)
    poses: dict[str, np.ndarray | None] = {"": np.eye(4)}

    def pose(name: str) -> np.ndarray | None:
        if name in poses:
            return poses[name]
        parent = pose(name.rsplit("/", 1)[0])
        handle = handles.get(name)
        if parent is None or (handle is not None and not handle.visible):
            poses[name] = None
            return None
        if handle is None:  # a path segment without a node of its own
            poses[name] = parent
            return parent
        local = np.eye(4)
        local[:3, :3] = vtf.SO3(np.asarray(handle.wxyz, dtype=float)).as_matrix()
        local[:3, 3] = handle.position
        world = parent @ local
        poses[name] = world if np.all(np.isfinite(world)) else None
        return poses[name]

    names = [n for n in list(handles) if any(n == r or n.startswith(r + "/") for r in roots)]
    return [(handles[n], p) for n, p in zip(names, map(pose, names), strict=True)
            if p is not None]


#: GLB data -> its box's corners (8, 3), node frame: a URDF's meshes are parsed once
_glb_boxes: dict[bytes, np.ndarray | None] = {}
#: models whose boxes are kept (a few robots' links)
GLB_BOXES_KEPT = 256


def _corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners (8, 3) of the box [lo, hi] (3,)."""
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])], dtype=float)


def _local_box(handle: Any) -> np.ndarray | None:
    """Corners (8, 3) of a box round a scene node's shape in its own frame (its scale
    applied; a gizmo's reach of its arrows), or None for a node without a shape (a frame,
    a label)."""
    if isinstance(handle, (viser.MeshHandle, viser.MeshSkinnedHandle)):
        v = np.asarray(handle.vertices, dtype=float).reshape(-1, 3)
        box = _corners(v.min(axis=0), v.max(axis=0)) if len(v) else None
    elif isinstance(handle, viser.GlbHandle):
        box = _glb_box(handle.glb_data)
    elif isinstance(handle, viser.IcosphereHandle):
        r = float(handle.radius)
        box = _corners(np.full(3, -r), np.full(3, r))
    elif isinstance(handle, viser.BoxHandle):
        half = 0.5 * np.asarray(handle.dimensions, dtype=float)
        box = _corners(-half, half)
    elif isinstance(handle, viser.CylinderHandle):  # a cube round it, whichever its axis
        r = max(float(handle.radius), 0.5 * float(handle.height))
        box = _corners(np.full(3, -r), np.full(3, r))
    elif isinstance(handle, viser.TransformControlsHandle):  # its arrows reach ``scale`` out
        r = float(handle.scale)
        corners = _corners(np.full(3, -r), np.full(3, r))
        return corners if np.all(np.isfinite(corners)) else None
    else:
        return None
    if box is None or not np.all(np.isfinite(box)):
        return None
    return box * np.asarray(getattr(handle, "scale", 1.0), dtype=float)


def _glb_box(data: bytes) -> np.ndarray | None:
    """Corners (8, 3) of the box round a GLB's meshes (None if it holds none)."""
    if data not in _glb_boxes:
        import io

        import trimesh

        try:
            bounds = trimesh.load(io.BytesIO(data), file_type="glb", force="scene").bounds
        except Exception:  # noqa: BLE001 - an unreadable model is framed by its origin
            bounds = None
        if len(_glb_boxes) >= GLB_BOXES_KEPT:
            _glb_boxes.clear()
        _glb_boxes[data] = None if bounds is None else _corners(*np.asarray(bounds, float))
    return _glb_boxes[data]


@dataclass(frozen=True)
class Framing:
    """One framing :func:`reframe` gave a page: the points it framed (k, 3), the camera
    it set (position, look_at (3,)), the page's view it was for (fov rad, aspect) and
    its ticket (the order in which framings read their page's view: :func:`_aim`)."""

    points: np.ndarray
    position: np.ndarray
    look_at: np.ndarray
    fov: float
    aspect: float
    ticket: int


#: page -> its last framing (for a person, or a test, checking what the page was shown)
last_framing: weakref.WeakKeyDictionary[viser.ClientHandle, Framing] = \
    weakref.WeakKeyDictionary()
#: scene -> the View its lesson asked for (a server's scene, or a page's own for a
#: student's private lesson)
_views: weakref.WeakKeyDictionary[Any, View] = weakref.WeakKeyDictionary()
#: page -> roots in its own scene that its framing of the shared view takes in too
#: (:func:`also_frame`)
_also: weakref.WeakKeyDictionary[viser.ClientHandle, tuple[str, ...]] = \
    weakref.WeakKeyDictionary()
#: Framings of a page are made in several threads at once (its view's reshapes, its
#: "Frame" button, a lesson's :func:`show`); each takes a ticket as it reads the page's
#: view, and one whose ticket is older than the page's :data:`last_framing` is dropped,
#: not sent: a framing for a shape the page has left never lands after one for its new.
_order = threading.Lock()
_tickets = itertools.count()


def _camera_of(client: viser.ClientHandle) -> tuple[float, float]:
    """(fov, aspect) the page reported, or the defaults before it has."""
    try:
        fov, aspect = float(client.camera.fov), float(client.camera.aspect)
    except (AssertionError, AttributeError, ValueError, ZeroDivisionError):
        return DEFAULT_FOV, DEFAULT_ASPECT
    if not (0.0 < fov < math.pi and math.isfinite(aspect) and aspect > 0.0):
        return DEFAULT_FOV, DEFAULT_ASPECT
    return fov, aspect


def show(server: Surface, view: View) -> None:
    """Frame ``view`` on ``server`` (the lab's :class:`viser.ViserServer`, or one page: an
    :class:`armlab.app.classroom.private_page.Page`): new pages start there (at the default
    aspect), open pages move there (each at its own), and :func:`reframe` returns to it."""
    _views[server.scene] = view
    points = framed_points(server.scene, view.roots)
    if len(points) == 0:
        return
    position, look_at = frame_points(points, direction=view.direction, up=view.up)
    if isinstance(server, viser.ViserServer):
        server.initial_camera.position = tuple(position)
        server.initial_camera.look_at = tuple(look_at)
        server.initial_camera.up = view.up
    for client in list(server.get_clients().values()):
        own = _framed_scene(client.scene) if client.scene is not server.scene else None
        if own is not None:  # a page showing its own lesson keeps that lesson's view
            _aim(client, *own)
        elif client.scene is not server.scene:  # and what the page draws alone (a ghost)
            _aim(client, view, _with_also(client, points))
        else:
            _aim(client, view, points)


def reframe(client: viser.ClientHandle) -> bool:
    """Move ``client``'s camera to its lesson's framed view, for the page's own field of
    view and aspect (the "Frame" button; a page whose 3D view changed shape). The page's
    own lesson (a private arm), while it is open, wins over the server's. False if there
    is nothing to frame or the page has gone."""
    framed = page_framing(client)
    return framed is not None and _aim(client, *framed)


def also_frame(client: viser.ClientHandle, roots: Sequence[str]) -> None:
    """Have ``client``'s framing of the shared lesson's view take in, as well, the visible
    nodes under ``roots`` of the page's own scene (``client.scene``: drawn on that page
    alone, such as a presenter's ghost of a student's arm); ``()``: no longer."""
    with _order:
        if roots:
            _also[client] = tuple(roots)
        else:
            _also.pop(client, None)


def also_framed(client: viser.ClientHandle) -> tuple[str, ...]:
    """The roots of ``client``'s own scene that :func:`also_frame` asked it to frame."""
    with _order:
        return _also.get(client, ())


def page_framing(client: viser.ClientHandle) -> tuple[View, np.ndarray] | None:
    """(the View, the points (k, 3)) that :func:`reframe` frames on ``client`` now: the
    page's own lesson's while one is open, else the shared lesson's with the page's own
    nodes of :func:`also_frame`; None: nothing to frame."""
    # the page's own lesson first; once it has closed its nodes are gone: the shared view
    own = _framed_scene(client.scene)
    if own is not None:
        return own
    shared = _framed_scene(server_of(client).scene)
    return None if shared is None else (shared[0], _with_also(client, shared[1]))


def _with_also(client: viser.ClientHandle, points: np.ndarray) -> np.ndarray:
    """``points`` and those of ``client``'s own nodes it was asked to frame too."""
    with _order:
        roots = _also.get(client, ())
    extra = framed_points(client.scene, roots) if roots else np.zeros((0, 3))
    return np.concatenate([points, extra]) if len(extra) else points


def _framed_scene(scene: Any) -> tuple[View, np.ndarray] | None:
    """(the View a lesson asked for on ``scene``, the points it frames now), or None
    (no lesson's view there, or none of its nodes left)."""
    view = _views.get(scene)
    if view is None:
        return None
    points = framed_points(scene, view.roots)
    return (view, points) if len(points) else None


def _aim(client: viser.ClientHandle, view: View, points: np.ndarray) -> bool:
    """Frame ``points`` along ``view`` on ``client``'s camera, for its own field of view
    and aspect; False if the page has gone or has not reported its camera yet. A framing
    overtaken by one made from a newer report of the page's view is dropped (True: the
    page is framed for its view)."""
    if not connected(client):
        return False
    with _order:
        ticket = next(_tickets)
        fov, aspect = _camera_of(client)
    position, look_at = frame_points(points, direction=view.direction, up=view.up,
                                     fov=fov, aspect=aspect)
    with _order:
        last = last_framing.get(client)
        if last is not None and last.ticket > ticket:
            return True  # a framing made from a newer view of the page has gone
        try:
            client.camera.up_direction = view.up
            client.camera.position = tuple(position)
            client.camera.look_at = tuple(look_at)  # after position: it drags look_at
        except (AssertionError, ValueError, RuntimeError):
            return False  # not reported its camera yet: it starts at initial_camera
        # viser sends no camera value equal to the page's last report; but a framing
        # sent before that report may still be on its way (the page reshaped before it
        # took it), and would then land last: so the framing is always sent (the newer
        # of two waiting camera messages replaces the older)
        send_view(client, position, look_at)
        last_framing[client] = Framing(points, position, look_at, fov, aspect, ticket)
    return True


def carry(client: viser.ClientHandle, offset: Sequence[float]) -> bool:
    """Move ``client``'s camera and the point it looks at by ``offset`` (3,) m, world: the
    view travels without turning (a walking robot's page follows it).

    viser's ``camera.position`` does the same and then works the camera's orientation
    out again from its look-at point (an SO3 from a matrix, every frame of every page); a
    translation keeps the orientation, so this moves the page's two points in viser's
    record of its camera and sends them. False if the page has gone or has not reported
    its camera yet."""
    return shift_view(client, offset)


#: A page's view is framed again when its width/height changes by more than this
#: fraction (a side panel collapsed or opened, the window resized, a phone turned).
RESHAPE = 0.03

#: Of the camera's distance to what it looks at: a page's camera this close to its last
#: framing shows it (an orbit moves it by far more)
SAME = 0.02


def shown(client: viser.ClientHandle, since: Framing | None = None) -> Framing | None:
    """The page's last framing (a newer one than ``since``) once the page shows it: its
    camera is there and its view still has the shape the framing was made for (a view
    reshaped since is framed again); else None (for a test, or a script taking pictures)."""
    framing = last_framing.get(client)
    if framing is None or framing is since:
        return None
    try:
        cam = client.camera
        tol = SAME * float(np.linalg.norm(framing.position - framing.look_at))
        there = (float(np.linalg.norm(cam.position - framing.position)) <= tol
                 and float(np.linalg.norm(cam.look_at - framing.look_at)) <= tol)
        same_view = abs(cam.aspect / framing.aspect - 1.0) <= RESHAPE
    except (AssertionError, ZeroDivisionError):  # no camera report yet
        return None
    return framing if there and same_view else None


def reframe_on_reshape(server: viser.ViserServer) -> None:
    """Frame every page for its own 3D view: once when it first reports its shape (new
    pages start framed for :data:`DEFAULT_ASPECT`), and again whenever that shape changes;
    an orbit or a zoom (the same shape) is left alone."""

    @server.on_client_connect
    def _(client: viser.ClientHandle) -> None:
        last: list[float] = []
        lock = threading.Lock()

        def heard(camera: viser.CameraHandle) -> None:
            try:
                aspect = float(camera.aspect)
            except (AssertionError, ZeroDivisionError):
                return  # no report yet
            with lock:
                if last and abs(aspect / last[0] - 1.0) <= RESHAPE:
                    return
                last[:] = [aspect]
            reframe(client)

        client.camera.on_update(heard)
        heard(client.camera)  # a first report that came before the callback was there
