"""The quadruped lesson's 3D scene: robot, floor, foot paths, support polygon, centre of mass.

- the robot from its URDF (:class:`app.arm_view.ArmView`), its root frame at the body
  pose, its legs at the angles the servos report (or the commanded ones);
- each foot's path over one gait cycle, drawn in the body frame (it travels with the
  body): the sine pattern's shape;
- each foot's recent trail on the floor (world), one colour per leg;
- the support polygon (the stance feet's convex hull) on the floor, green when the
  centre of mass projects inside it, red otherwise (a line for two feet);
- the centre of mass, its projection on the floor, and the shortest segment from
  that projection to the polygon's edge: the static stability margin.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import viser
import viser.transforms as vtf

from app import theme
from app.arm_view import ArmView
from app.camera import View, connected, show
from control.walking import GaitPlan, WalkState
from kinematics.model import Quadruped
from kinematics.quadruped import LEGS

#: One colour per leg (RF, LF, RH, LH).
LEG_RGB = {"RF": (31, 94, 234), "LF": (232, 130, 12), "RH": (194, 24, 91), "LH": (46, 125, 50)}
STABLE_RGB = (46, 160, 60)
UNSTABLE_RGB = (220, 30, 30)
COM_RGB = (20, 20, 20)
TRAIL_POINTS = 80
FLOOR_Z = 0.001


def nearest_on_polygon(p: np.ndarray, hull: np.ndarray) -> np.ndarray:
    """(2,) point of the polygon's boundary (or segment, or point) nearest to ``p`` (2,)."""
    if len(hull) == 1:
        return hull[0].copy()
    best, best_d = hull[0], math.inf
    edges = len(hull) if len(hull) > 2 else 1
    for i in range(edges):
        a, b = hull[i], hull[(i + 1) % len(hull)]
        ab = b - a
        L2 = float(ab @ ab)
        t = 0.0 if L2 == 0 else min(1.0, max(0.0, float((p - a) @ ab) / L2))
        c = a + t * ab
        d = float(np.linalg.norm(p - c))
        if d < best_d:
            best, best_d = c, d
    return np.asarray(best, dtype=float)


def _segments(points: np.ndarray, closed: bool) -> np.ndarray:
    p = np.asarray(points, dtype=np.float32)
    if closed:
        return np.stack([p, np.roll(p, -1, axis=0)], axis=1)
    return np.stack([p[:-1], p[1:]], axis=1)


class QuadrupedScene:
    """Scene nodes of the quadruped lesson under ``root``.

    Args:
        server: viser server.
        model: the quadruped.
        root: scene node holding everything (removed by :meth:`remove`).
    """

    def __init__(self, server: viser.ViserServer, model: Quadruped, *, root: str) -> None:
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
        self.trails = scene.add_line_segments(f"{root}/trails", np.zeros((4, 2, 3), np.float32),
                                              (0, 0, 0), thickness=0.004, visible=False)
        self._trail: dict[str, deque[np.ndarray]] = {leg: deque(maxlen=TRAIL_POINTS)
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
        for d in self._trail.values():
            d.clear()
        self.trails.visible = False

    def set_state(self, state: WalkState, q: np.ndarray | None = None) -> None:
        """Pose the robot (body from ``state``, legs at ``q`` (12,) rad, default the
        commanded angles) and draw trails, support polygon, centre of mass and margin."""
        x, y, z, yaw = state.body
        self.robot.root.position = (float(x), float(y), float(z))
        self.robot.root.wxyz = vtf.SO3.from_z_radians(float(yaw)).wxyz
        legs = state.q if q is None or not np.all(np.isfinite(q)) else q
        self.robot.set_q(legs)
        self._update_trails(state.feet)
        stable = state.margin > 0.0
        color = STABLE_RGB if stable else UNSTABLE_RGB
        hull = state.support
        if len(hull) >= 2:
            pts = np.column_stack([hull, np.full(len(hull), FLOOR_Z)])
            self.support.points = _segments(pts, closed=len(hull) > 2)
            self.support.visible = True
        else:
            self.support.visible = False
        com = state.com
        floor = np.array([com[0], com[1], FLOOR_Z])
        self.com.position = com
        self.com_floor.position = floor
        self.plumb.points = np.array([[com, floor]], np.float32)
        if len(hull):
            near = nearest_on_polygon(com[:2], hull)
            self.margin_line.points = np.array([[floor, [near[0], near[1], FLOOR_Z]]],
                                               np.float32)
            self.margin_line.visible = True
        else:
            self.margin_line.visible = False
        self.margin_label.position = floor + np.array([0.0, 0.0, 0.01])
        self.margin_label.text = f"margin {state.margin * 100:+.1f} cm"
        if stable != self.stable:
            rgb = np.array(color, dtype=np.uint8)
            self.support.colors = rgb
            self.com_floor.color = color
            self.margin_line.colors = rgb
            self.stable = stable

    def _update_trails(self, feet: np.ndarray, *, min_step: float = 0.002) -> None:
        changed = False
        for i, leg in enumerate(LEGS):
            d = self._trail[leg]
            if not d or np.linalg.norm(feet[i] - d[-1]) >= min_step:
                d.append(np.array(feet[i], dtype=float))
                changed = True
        if not changed or min(len(d) for d in self._trail.values()) < 2:
            return
        segs, cols = [], []
        for leg, d in self._trail.items():
            s = _segments(np.array(d), closed=False)
            segs.append(s)
            cols.append(np.broadcast_to(np.array(LEG_RGB[leg], np.uint8), s.shape).copy())
        self.trails.points = np.concatenate(segs)
        self.trails.colors = np.concatenate(cols)
        self.trails.visible = True

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
            if not connected(client):
                continue
            try:
                client.camera.position = client.camera.position + np.array([*step, 0.0])
            except (AssertionError, ValueError, RuntimeError):
                pass  # a page that has not reported its camera yet

    def remove(self) -> None:
        self.root.remove()
