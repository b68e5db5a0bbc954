"""The redundancy lesson's 3D scene: one ghost arm per simulation, side by side.

Each simulation of seed 002 (modes 1-4 and the bounded method) gets a panel: a
coloured translucent copy of the planar 3R arm, the desired circle, the path the
end effector drew, stick pictures (the arm drawn every ``STICK_S`` seconds, as in
the paper's figures), the manipulability ellipse at the end effector and a dot on
each joint that turns red while the joint is outside its limits.

Panels form a grid of two columns, "no redundancy use" and "redundancy" (the
manipulability gradient), and three rows: joint limits ignored (1, 3), joint
limits by the paper's decomposition method (2, 4), limits guaranteed (bounded,
centred below). Everything but the arm meshes is drawn under a node
posed at the model's ``base_pose``, so it takes the paper's (base-frame) x-y
coordinates directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import viser
import viser.transforms as vtf

from armlab.app.page.arm_view import ArmView
from armlab.app.page.camera import View, show
from armlab.app.page.plots import COLORS
from armlab.app.page.surface import Surface
from armlab.kinematics.model import SerialChain
from armlab.kinematics.redundancy import circle_target, task_jacobian

#: Mode -> (column, row) of its panel; row 0 is the top row (no joint limits).
GRID = {"1": (0.0, 0), "3": (1.0, 0), "2": (0.0, 1), "4": (1.0, 1), "bounded": (0.5, 2)}
ROWS = 3
#: Mode -> colour (hex, as in the plots; the Okabe-Ito palette of ``armlab.app.page.plots.COLORS``).
MODE_COLORS = {"1": COLORS[0], "2": COLORS[1], "3": COLORS[5], "4": COLORS[4],
               "bounded": COLORS[3]}
#: Mode -> short label shown above its panel.
MODE_LABELS = {"1": "1 · J⁺ẋ, no limits", "2": "2 · J⁺ẋ + limits (decomposition)",
               "3": "3 · J⁺ẋ + k_a ∇w, no limits", "4": "4 · k_a ∇w + limits (paper)",
               "bounded": "bounded LSQ: ∇w + limits guaranteed"}
#: Mode -> its title in the 3D view, short enough to fit its panel (MODE_LABELS, whole,
#: name the modes in the panel's legend and table beside the same colours).
SCENE_TITLES = {"1": "1 · J⁺ẋ", "2": "2 · J⁺ẋ + limits", "3": "3 · J⁺ẋ + k_a∇w",
                "4": "4 · k_a∇w + limits", "bounded": "bounded: ∇w + limits"}
#: Metres between panel origins, world x (columns) and world z (rows).
COLUMN_M = 1.45
ROW_M = 1.35
#: The labels are sized in the scene (metres), not on the screen: at any zoom and window
#: a panel's words stay inside its own column and above its arm, never over a neighbour's
#: (screen-sized labels overprinted each other once the five panels were framed).
#: m, where a panel's labels start (left of its base), and the width they may take.
LABEL_X_M = -0.55
LABEL_WIDTH_M = COLUMN_M - 0.12
#: m, the status's two lines (bottom at LABEL_BOTTOM_M) and the title above them.
STATUS_HEIGHT_M = 0.09
TITLE_HEIGHT_M = 0.105
LABEL_BOTTOM_M = 0.97
#: a glyph's width and a line's height, per font height, that the budget assumes: a
#: status line of 26 glyphs measured 0.44 em each in Chromium (the system sans-serif),
#: taken with a margin; viser draws lines about 1.2 font heights apart
GLYPH_EM = 0.52
LINE_EM = 1.25
#: m, the title's bottom: above the status's two lines, a little apart
TITLE_BOTTOM_M = LABEL_BOTTOM_M + 2 * LINE_EM * STATUS_HEIGHT_M + 0.02
#: characters a status line may hold ("θ1, θ2, θ3 outside limits!", "w = 0.123 · error
#: 0.123 mm")
STATUS_CHARS = 27
#: Seconds between two stick pictures.
STICK_S = 0.1
#: Ellipse semi-axis (m) per unit singular value of J (m/rad).
ELLIPSE_SCALE = 0.18
ELLIPSE_POINTS = 48
OK_RGB = (60, 60, 60)
OUT_RGB = (230, 20, 20)
CIRCLE_RGB = (20, 150, 60)


def hex_rgb(color: str) -> tuple[int, int, int]:
    """"#1f5eea" -> (31, 94, 234)."""
    c = color.lstrip("#")
    return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)


def ellipse_points(J: np.ndarray, centre: np.ndarray, *, scale: float = ELLIPSE_SCALE,
                   points: int = ELLIPSE_POINTS) -> np.ndarray:
    """Manipulability (velocity) ellipse {J θ̇ : |θ̇| <= 1} at ``centre``, as a closed polyline.

    Its semi-axes are the singular values σ_i of the (2, n) Jacobian along the left
    singular vectors u_i; their product σ1 σ2 is Yoshikawa's w = sqrt(det(J Jᵀ)).

    Args:
        J: (2, n) task Jacobian, m/rad.
        centre: (2,) or (3,) end effector, m (base frame).
        scale: metres drawn per unit σ.

    Returns:
        (points, 3) points on the ellipse in the base plane (z = 0).
    """
    U, s, _ = np.linalg.svd(np.asarray(J, dtype=float)[:2], full_matrices=False)
    a = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    xy = (U @ (s[:, None] * np.vstack([np.cos(a), np.sin(a)]))).T * scale
    c = np.asarray(centre, dtype=float)[:2]
    return np.column_stack([xy + c, np.zeros(points)])


def arm_points(model: SerialChain, q: np.ndarray) -> np.ndarray:
    """(T, n + 1, 3) base-frame points of the arm (joint origins, then the end effector)
    for every row of ``q`` (T, n): what a stick picture draws."""
    out = np.empty((len(q), model.n + 1, 3))
    for i, row in enumerate(np.asarray(q, dtype=float)):
        poses = model.link_poses(row)
        out[i, :model.n] = poses[:, :3, 3]
        out[i, model.n] = (poses[-1] @ model.tip)[:3, 3]
    return out


def closed_segments(p: np.ndarray) -> np.ndarray:
    """(k, 3) polygon -> (k, 2, 3) segments joining each point to the next (closed)."""
    return np.stack([p, np.roll(p, -1, axis=0)], axis=1).astype(np.float32)


def open_segments(p: np.ndarray) -> np.ndarray:
    """(k, 3) polyline -> (k − 1, 2, 3) segments."""
    return np.stack([p[:-1], p[1:]], axis=1).astype(np.float32)


@dataclass
class ModeView:
    """The scene nodes of one simulation's panel."""

    mode: str
    root: viser.FrameHandle
    arm: ArmView
    base: str
    sticks: viser.LineSegmentsHandle
    trace: viser.LineSegmentsHandle
    ellipse: viser.LineSegmentsHandle
    joints: list[viser.IcosphereHandle]
    status: viser.LabelHandle
    sticks_shown: int = 0
    trace_shown: int = 0
    outside: tuple[bool, ...] = (False, False, False)


class RedundancyScene:
    """Ghost arms, circles, sticks, traces and ellipses of every mode under ``root``.

    Args:
        server: viser server.
        model: the redundant planar arm.
        modes: the modes to draw (keys of :data:`GRID`).
        root: scene node holding everything (removed by :meth:`remove`).
    """

    def __init__(self, server: Surface, model: SerialChain, *,
                 modes: tuple[str, ...], root: str) -> None:
        self.server = server
        self.model = model
        self.root = server.scene.add_frame(root, show_axes=False)
        self.views: dict[str, ModeView] = {}
        base = np.asarray(model.base_pose, dtype=float)
        base_wxyz = vtf.SO3.from_matrix(base[:3, :3]).wxyz
        circle = np.array([np.append(circle_target(t)[0], 0.0)
                           for t in np.linspace(0.0, 2.0, 97)[:-1]])
        scene = server.scene
        for mode in modes:
            col, row = GRID[mode]
            name = f"{root}/mode_{mode}"
            frame = scene.add_frame(name, show_axes=False,
                                    position=(col * COLUMN_M, 0.0, (ROWS - 1 - row) * ROW_M))
            rgb = hex_rgb(MODE_COLORS[mode])
            arm = ArmView(server, model, root=f"{name}/arm",
                          color=(rgb[0] / 255, rgb[1] / 255, rgb[2] / 255, 0.55))
            b = f"{name}/base"
            scene.add_frame(b, show_axes=False, wxyz=base_wxyz, position=base[:3, 3])
            scene.add_line_segments(f"{b}/circle", closed_segments(circle), CIRCLE_RGB,
                                    thickness=0.006)
            scene.add_label(f"{b}/title", SCENE_TITLES[mode], font_size_mode="scene",
                            font_scene_height=TITLE_HEIGHT_M,
                            position=(LABEL_X_M, TITLE_BOTTOM_M, 0.0), anchor="bottom-left")
            status = scene.add_label(f"{b}/status", "", font_size_mode="scene",
                                     font_scene_height=STATUS_HEIGHT_M,
                                     position=(LABEL_X_M, LABEL_BOTTOM_M, 0.0),
                                     anchor="bottom-left")
            light = tuple(int(0.45 * c + 0.55 * 255) for c in rgb)
            sticks = scene.add_line_segments(f"{b}/sticks", np.zeros((1, 2, 3), np.float32),
                                             light, thickness=0.004, visible=False)  # type: ignore[arg-type]  # three ints: rgb's, lightened
            trace = scene.add_line_segments(f"{b}/trace", np.zeros((1, 2, 3), np.float32),
                                            rgb, thickness=0.008, visible=False)
            ellipse = scene.add_line_segments(f"{b}/ellipse",
                                              np.zeros((ELLIPSE_POINTS, 2, 3), np.float32),
                                              (20, 20, 20), thickness=0.006)
            joints = [scene.add_icosphere(f"{b}/joint{i}", radius=0.035, color=OK_RGB)
                      for i in range(model.n)]
            self.views[mode] = ModeView(mode, frame, arm, b, sticks, trace, ellipse, joints,
                                        status)
        # in front of the grid of panels (world y < 0), square on it
        show(server, View(roots=(root,), direction=(0.0, 1.0, 0.0)))

    def show_mode(self, mode: str, visible: bool) -> None:
        """Show or hide one panel."""
        self.views[mode].root.visible = bool(visible)

    def clear(self) -> None:
        """Forget the sticks and the trace (before a new run)."""
        for v in self.views.values():
            v.sticks.visible = False
            v.trace.visible = False
            v.sticks_shown = 0
            v.trace_shown = 0

    def set_pose(self, mode: str, q: np.ndarray, *, status: str | None = None) -> None:
        """Pose one ghost at ``q`` (n,) rad: arm, joint dots (red outside the limits), ellipse."""
        v = self.views[mode]
        m = self.model
        v.arm.set_q(q)
        poses = m.link_poses(q)
        outside = tuple(bool(x) for x in (q < m.lower - 1e-9) | (q > m.upper + 1e-9))
        for i, dot in enumerate(v.joints):
            dot.position = poses[i][:3, 3]
            if outside[i] != v.outside[i]:
                dot.color = OUT_RGB if outside[i] else OK_RGB
        v.outside = outside
        tip = m.fk(q)[:3, 3]
        v.ellipse.points = closed_segments(ellipse_points(task_jacobian(m, q), tip))
        if status is not None:
            v.status.text = status

    def set_history(self, mode: str, points: np.ndarray, k: int, dt: float) -> None:
        """Stick pictures every ``STICK_S`` s and the end-effector path up to sample ``k``.

        Args:
            points: (T, n + 1, 3) base, joints 2..n and end effector of every sample of
                the run (:func:`arm_points`), base frame, m.
            k: samples played so far (0..T).
            dt: sample period, s.
        """
        v = self.views[mode]
        every = max(1, round(STICK_S / dt))
        n_sticks = (k - 1) // every + 1 if k > 0 else 0
        if n_sticks != v.sticks_shown and n_sticks > 0:
            chosen = points[:k:every][:n_sticks]
            v.sticks.points = np.concatenate([open_segments(p) for p in chosen])
            v.sticks.visible = True
            v.sticks_shown = n_sticks
        step = max(1, every // 5)
        n_trace = (k - 1) // step + 1 if k > 0 else 0
        if n_trace != v.trace_shown and n_trace >= 2:
            v.trace.points = open_segments(points[:k:step, -1][:n_trace])
            v.trace.visible = True
            v.trace_shown = n_trace

    def remove(self) -> None:
        self.root.remove()
