"""The quadruped lesson's 3D scene: robot, floor, foot paths, support polygon, centre of mass.

- the robot from its URDF (:class:`armlab.app.page.arm_view.ArmView`), its root frame at the body
  pose, its legs at the angles the servos report (or the commanded ones);
- each foot's path over one gait cycle, drawn in the body frame (it travels with the
  body): the sine pattern's shape;
- each foot's recent trail on the floor (world), one colour per leg, in pieces of
  :data:`TRAIL_CHUNK` segments (:class:`FootTrail`: a frame sends only the piece that grew);
- the support polygon (the stance feet's convex hull) on the floor, green when the
  centre of mass projects inside it, red otherwise (a line for two feet);
- the centre of mass, its projection on the floor, and the shortest segment from
  that projection to the polygon's edge: the static stability margin.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import viser

from armlab.app.page import theme
from armlab.app.page.arm_view import ArmView
from armlab.app.page.camera import View, carry, show
from armlab.app.page.surface import Surface
from armlab.control.walking import GaitPlan, WalkState
from armlab.kinematics.model import Quadruped
from armlab.kinematics.quadruped import LEGS
from armlab.kinematics.stability import nearest_on_polygon

#: One colour per leg (RF, LF, RH, LH).
LEG_RGB = {"RF": (31, 94, 234), "LF": (232, 130, 12), "RH": (194, 24, 91), "LH": (46, 125, 50)}
STABLE_RGB = (46, 160, 60)
UNSTABLE_RGB = (220, 30, 30)
COM_RGB = (20, 20, 20)
#: points of a foot's trail shown at least (2 mm apart)
TRAIL_POINTS = 80
#: segments in a piece of a trail: while a foot moves, each frame sends its newest piece
#: (8 segments, 0.2 kB) rather than the whole trail (80 points a foot, 7.6 kB for four)
TRAIL_CHUNK = 8
FLOOR_Z = 0.001


def _segments(points: np.ndarray, closed: bool) -> np.ndarray:
    p = np.asarray(points, dtype=np.float32)
    if closed:
        return np.stack([p, np.roll(p, -1, axis=0)], axis=1)
    return np.stack([p[:-1], p[1:]], axis=1)


class FootTrail:
    """One foot's recent trail as a ring of line-segment nodes of :data:`TRAIL_CHUNK`
    segments each: a new point re-sends the newest piece only; a full piece stays as it is
    until the ring comes round to it again (then the oldest piece goes at once).

    Args:
        scene: the server's scene API.
        name: the node holding the pieces (``name/0``, ``name/1``, ...).
        rgb: the line's colour.
        points: points shown at least.
        chunk: segments per piece.
    """

    def __init__(self, scene: viser.SceneApi, name: str, rgb: tuple[int, int, int], *,
                 points: int = TRAIL_POINTS, chunk: int = TRAIL_CHUNK) -> None:
        self.chunk = chunk
        # enough pieces that the full ones alone hold points - 1 segments
        pieces = -(-(points - 1) // chunk) + 1
        self.pieces = [scene.add_line_segments(f"{name}/{i}",
                                               np.zeros((chunk, 2, 3), np.float32), rgb,
                                               thickness=0.004, visible=False)
                       for i in range(pieces)]
        self._k = 0  # the piece growing now
        self._points: list[np.ndarray] = []  # its points (the first: the last one's end)
        # the page's frame thread adds, a button's callback clears
        self._lock = threading.Lock()

    @property
    def last(self) -> np.ndarray | None:
        """(3,) the newest point, m (None: the trail is empty)."""
        points = self._points
        return points[-1] if points else None

    def add(self, p: np.ndarray) -> None:
        """Extend the trail to ``p`` (3,) m, world frame."""
        with self._lock:
            points = self._points
            points.append(np.asarray(p, dtype=np.float32))
            if len(points) < 2:
                return
            piece = self.pieces[self._k]
            pad = [points[-1]] * (self.chunk + 1 - len(points))  # unused ends: zero length
            piece.points = _segments(np.array(points + pad), closed=False)
            piece.visible = True
            if len(points) == self.chunk + 1:  # full: the next piece starts at its end
                self._k = (self._k + 1) % len(self.pieces)
                self.pieces[self._k].visible = False  # the oldest piece, to be written over
                self._points = [points[-1]]

    def clear(self) -> None:
        """Hide the trail and start it again."""
        with self._lock:
            for piece in self.pieces:
                piece.visible = False
            self._k, self._points = 0, []

    def segments(self) -> np.ndarray:
        """(S, 2, 3) the segments shown, oldest first (zero-length ones left out), m."""
        with self._lock:
            order = self.pieces[self._k + 1:] + self.pieces[:self._k + 1]
            segs = [np.asarray(p.points) for p in order if p.visible]
        out = np.concatenate(segs) if segs else np.zeros((0, 2, 3), np.float32)
        return out[np.any(out[:, 0] != out[:, 1], axis=1)]


class QuadrupedScene:
    """Scene nodes of the quadruped lesson under ``root``.

    Args:
        server: viser server.
        model: the quadruped.
        root: scene node holding everything (removed by :meth:`remove`).
    """

    def __init__(self, server: Surface, model: Quadruped, *, root: str) -> None:
        self.server = server
        self.model = model
        scene = server.scene
        self.root = scene.add_frame(root, show_axes=False)
        scene.add_grid(f"{root}/floor", width=4.0, height=4.0, plane="xy", cell_size=0.1,
                       section_size=0.5, cell_color=(215, 215, 215),
                       section_color=(160, 160, 160))
        self.robot = ArmView(server, model, root=f"{root}/robot")
        self.paths = scene.add_line_segments(f"{root}/robot/foot_paths",
                                             np.zeros((4, 2, 3), np.float32), (0, 0, 0),
                                             thickness=0.003)
        self.trails = {leg: FootTrail(scene, f"{root}/trails/{leg}", LEG_RGB[leg])
                       for leg in LEGS}
        self.support = scene.add_line_segments(f"{root}/support",
                                               np.zeros((1, 2, 3), np.float32), STABLE_RGB,
                                               thickness=0.006)
        self.com = scene.add_icosphere(f"{root}/com", radius=0.012, color=COM_RGB)
        self.com_floor = scene.add_icosphere(f"{root}/com_floor", radius=0.008,
                                             color=STABLE_RGB)
        self.plumb = scene.add_line_segments(f"{root}/plumb", np.zeros((1, 2, 3), np.float32),
                                             (90, 90, 90), thickness=0.002)
        self.margin_line = scene.add_line_segments(f"{root}/margin",
                                                   np.zeros((1, 2, 3), np.float32),
                                                   STABLE_RGB, thickness=0.004)
        self.margin_label = theme.add_label(scene, f"{root}/margin_label", "",
                                            anchor="bottom-left")
        self.stable: bool | None = None
        self._followed: np.ndarray | None = None
        # what the page was last sent: body pose, support polygon, centre of mass, margin
        self._body: tuple[float, ...] | None = None
        self._hull: bytes | None = None
        self._com: tuple[float, ...] | None = None
        self._margin: tuple[float, ...] | None = None
        show(server, View(roots=(root,), direction=(-0.2, 0.6, -0.5)))  # front left, above

    def set_foot_paths(self, plan: GaitPlan) -> None:
        """Draw every foot's closed path over one cycle of ``plan`` (body frame)."""
        segs, cols = [], []
        for i, leg in enumerate(LEGS):
            s = _segments(plan.feet_body[:, i], closed=True)
            segs.append(s)
            cols.append(np.broadcast_to(np.array(LEG_RGB[leg], np.uint8), s.shape).copy())
        self.paths.points = np.concatenate(segs)
        self.paths.colors = np.concatenate(cols)

    def clear_trails(self) -> None:
        for trail in self.trails.values():
            trail.clear()

    def set_state(self, state: WalkState, q: np.ndarray | None = None) -> None:
        """Pose the robot (body from ``state``, legs at ``q`` (12,) rad, default the
        commanded angles) and draw trails, support polygon, centre of mass and margin.
        A node is sent only when it changed (a page's frame, 30 times a second)."""
        body = tuple(state.body.tolist())
        if body != self._body:
            x, y, z, yaw = body
            self.robot.root.position = (x, y, z)
            self.robot.root.wxyz = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))  # about z
            self._body = body
        legs = state.q if q is None or not np.all(np.isfinite(q)) else q
        self.robot.set_q(legs)
        self._update_trails(state.feet)
        stable = state.margin > 0.0
        color = STABLE_RGB if stable else UNSTABLE_RGB
        hull = state.support
        key = hull.tobytes()
        if key != self._hull:
            if len(hull) >= 2:
                pts = np.column_stack([hull, np.full(len(hull), FLOOR_Z)])
                self.support.points = _segments(pts, closed=len(hull) > 2)
                self.support.visible = True
            else:
                self.support.visible = False
            self._hull = key
        cx, cy, cz = state.com.tolist()
        if (cx, cy, cz) != self._com:
            self.com.position = (cx, cy, cz)
            self.com_floor.position = (cx, cy, FLOOR_Z)
            self.plumb.points = np.array([[[cx, cy, cz], [cx, cy, FLOOR_Z]]], np.float32)
            self.margin_label.position = (cx, cy, FLOOR_Z + 0.01)
            self._com = (cx, cy, cz)
        if len(hull):
            nx, ny = nearest_on_polygon((cx, cy), hull)
            if (cx, cy, nx, ny) != self._margin:
                self.margin_line.points = np.array([[[cx, cy, FLOOR_Z], [nx, ny, FLOOR_Z]]],
                                                   np.float32)
                self._margin = (cx, cy, nx, ny)
            self.margin_line.visible = True
        else:
            self.margin_line.visible = False
        self.margin_label.text = f"margin {state.margin * 100:+.1f} cm"
        if stable != self.stable:
            rgb = np.array(color, dtype=np.uint8)
            self.support.colors = rgb
            self.com_floor.color = color
            self.margin_line.colors = rgb
            self.stable = stable

    def _update_trails(self, feet: np.ndarray, *, min_step: float = 0.002) -> None:
        """Extend each foot's trail to where it is, when it moved ``min_step`` m since."""
        for i, leg in enumerate(LEGS):
            trail = self.trails[leg]
            last = trail.last
            if last is None or math.dist(feet[i], last.tolist()) >= min_step:
                trail.add(feet[i])

    def follow(self, body_xy: np.ndarray) -> None:
        """Carry every page's camera along with the body (keeping its view direction)."""
        xy = np.asarray(body_xy, dtype=float)[:2]
        if self._followed is None or not np.all(np.isfinite(xy)):
            self._followed = xy
            return
        step = xy - self._followed
        if float(np.hypot(*step)) < 1e-4:
            return
        self._followed = xy
        for client in self.server.get_clients().values():
            carry(client, (*step.tolist(), 0.0))  # nothing for a page without a camera yet

    def remove(self) -> None:
        self.root.remove()
