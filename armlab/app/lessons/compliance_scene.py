"""The compliance lesson's 3D scene: arm, ghost, shoulder frame, path, target, trail, forces.

Everything the controller works in (target, path, forces) is drawn under the
shoulder frame node, whose pose is the model's ``base_pose``, so those nodes
take base-frame (thesis-frame) coordinates directly; the arm meshes hang from
the world as in the URDF.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import viser
import viser.transforms as vtf

from armlab.app.page import theme
from armlab.app.page.arm_view import ArmView
from armlab.app.page.camera import View, show
from armlab.app.page.in_order import InOrder
from armlab.app.page.surface import Surface
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import all_finite

#: Metres of arrow drawn per newton.
ARROW_M_PER_N = 0.03
#: Applied forces under this many newtons are not drawn.
ARROW_MIN_N = 0.05
#: Estimated forces are drawn above ESTIMATE_ON_N and hidden below ESTIMATE_OFF_N
#: (hysteresis: the estimate from quantised servo loads hovers near zero at rest).
ESTIMATE_ON_N = 0.4
ESTIMATE_OFF_N = 0.25
TRAIL_DOTS = 24
#: the nodes under the shoulder frame that the camera frames with the arm: the task
#: (the line, its ends and labels, the target), not the trail, springs or arrows
FRAMED_TASK = ("label", "path", "path_label", "path_end0", "path_end1", "target")
GHOST_RGBA = (0.35, 0.6, 1.0, 0.35)
PATH_RGB = (20, 150, 60)
FORCE_RGB = (220, 30, 30)
ESTIMATE_RGB = (150, 40, 190)


class ComplianceScene:
    """Scene nodes of the compliance lesson under ``root``.

    Args:
        server: viser server.
        model: the arm.
        path: (2, 3) start and end of the thesis line, base frame, m.
        root: scene node holding everything (removed by :meth:`remove`).
        on_target: called with a new target (3,) m, base frame, when the gizmo moves.
        on_drag_hand: called with (phase, anchor (3,) base frame or None) while the hand
            is dragged ("start"/"update" give the anchor, "end" gives None).
    """

    def __init__(self, server: Surface, model: SerialChain, *, path: np.ndarray,
                 root: str, on_target: Callable[[np.ndarray], None],
                 on_drag_hand: Callable[[str, np.ndarray | None], None]) -> None:
        self.server = server
        self.model = model
        scene = server.scene
        self.root = scene.add_frame(root, show_axes=False)
        self.arm = ArmView(server, model, root=f"{root}/arm")
        self.ghost = ArmView(server, model, root=f"{root}/ghost", color=GHOST_RGBA)
        # the thesis robot's torso stands between the camera and the arm's upper links
        self.arm.see_through("torso")
        self.ghost.see_through("torso", opacity=0.0)  # the ghost is the commanded arm only
        base = np.asarray(model.base_pose, dtype=float)
        self._base_inv = np.linalg.inv(base)
        self.shoulder = scene.add_frame(
            f"{root}/shoulder", show_axes=True, axes_length=0.08, axes_radius=0.003,
            wxyz=vtf.SO3.from_matrix(base[:3, :3]).wxyz, position=base[:3, 3])
        sh = f"{root}/shoulder"
        # the labels reach inwards from their points (the line's end is the scene's
        # rightmost point: a label hung to its right ran under the controls)
        self.shoulder_label = theme.add_label(
            scene, f"{sh}/label", "shoulder frame, x = gravity", position=(0.09, 0.0, 0.0))
        path = np.asarray(path, dtype=float).reshape(2, 3)
        self.path = scene.add_line_segments(f"{sh}/path", points=path[None, :, :],
                                            colors=PATH_RGB, thickness=0.004)
        self.path_label = theme.add_label(scene, f"{sh}/path_label", "thesis 20 cm line",
                                          position=path[1], anchor="bottom-right")
        for i, p in enumerate(path):
            scene.add_icosphere(f"{sh}/path_end{i}", radius=0.006, color=PATH_RGB, position=p)
        # Target the hand follows by RMRC (translation only).
        self.target = scene.add_transform_controls(
            f"{sh}/target", scale=0.07, disable_rotations=True, depth_test=False,
            position=path[1])
        scene.add_icosphere(f"{sh}/target/dot", radius=0.01, color=(250, 180, 0))

        # the gizmo's and the hand's events, handled in the order the page sent them
        self._lane = InOrder("armlab-compliance-drags")

        def moved(event: viser.TransformControlsEvent) -> None:
            if event.client is None:  # a page's move only: a move from Python is silent
                return
            on_target(np.array(self.target.position, dtype=float))

        self.target.on_update(self._lane(moved))

        # Hand: a grab sphere riding on the last link; drag it to pull the arm.
        tip_link = model.link_names[-1] if model.link_names else None
        tip = np.asarray(model.tip, dtype=float)
        parent = self.arm.link_frames[tip_link].name if tip_link in self.arm.link_frames else sh
        self.hand = scene.add_icosphere(f"{parent}/grab", radius=0.03, color=(255, 120, 120),
                                        opacity=0.35, position=tip[:3, 3])

        def dragged(event: viser.SceneNodeDragEvent) -> None:
            if event.phase == "end":
                on_drag_hand("end", None)
                self.spring.visible = False
                return
            anchor = self.to_base(np.asarray(event.end_position, dtype=float))
            on_drag_hand(event.phase, anchor)

        self.hand.on_drag(self._lane(dragged))

        self.spring = scene.add_line_segments(f"{sh}/spring", points=np.zeros((1, 2, 3)),
                                              colors=(90, 90, 90), thickness=0.003,
                                              visible=False)
        self.arrows = ForceArrows(scene, sh)
        self.force, self.estimate = self.arrows.force, self.arrows.estimate
        self._trail = [scene.add_icosphere(f"{sh}/trail/{i}", radius=0.004,
                                           color=(40, 40, 40), visible=False)
                       for i in range(TRAIL_DOTS)]
        self._trail_next = 0
        self._trail_last: np.ndarray | None = None
        # the arm (not the torso it stands on) and its task, from the front right; not the
        # hand's trail: a history (the move to the start leaves dots far from where the arm
        # stands), it would move the camera whenever a page is framed
        task = tuple(f"{sh}/{name}" for name in FRAMED_TASK)
        show(server, View(roots=(self.arm.moving_root, self.ghost.moving_root, *task),
                          direction=(-0.62, 0.26, -0.23)))

    # -- frames -----------------------------------------------------------------

    def to_base(self, p_world: np.ndarray) -> np.ndarray:
        """World point (3,) -> base (shoulder) frame."""
        return self._base_inv[:3, :3] @ p_world + self._base_inv[:3, 3]

    # -- per-frame updates ----------------------------------------------------------

    def set_pose(self, q: np.ndarray, q_cmd: np.ndarray) -> None:
        """Actual arm at ``q``, ghost at the commanded ``q_cmd`` (both (n,), rad)."""
        self.arm.set_q(q)
        self.ghost.set_q(q_cmd)

    def set_target(self, p: np.ndarray) -> None:
        """Move the target gizmo (base frame, m); viser reports only a page's moves, so
        this is not taken for a user's."""
        self.target.position = np.asarray(p, dtype=float)

    def add_trail(self, hand: np.ndarray, *, min_step: float = 0.003) -> None:
        """Drop a trail dot at ``hand`` (base frame) if it moved ``min_step`` m since the last."""
        if self._trail_last is not None and math.dist(hand, self._trail_last) < min_step:
            return
        dot = self._trail[self._trail_next]
        dot.position = hand
        dot.visible = True
        self._trail_next = (self._trail_next + 1) % len(self._trail)
        self._trail_last = np.array(hand, dtype=float)

    def set_spring(self, hand: np.ndarray | None, anchor: np.ndarray | None) -> None:
        """Draw the virtual spring from ``hand`` to ``anchor`` (base frame); None hides it."""
        if hand is None or anchor is None:
            self.spring.visible = False
            return
        self.spring.points = np.array([[hand, anchor]], dtype=np.float32)
        self.spring.visible = True

    def set_forces(self, hand: np.ndarray, applied: np.ndarray | None,
                   estimated: np.ndarray | None) -> None:
        """Arrows for the applied force (red) and the force estimated from τ_ext (purple), N."""
        self.arrows.set(hand, applied, estimated)

    def remove(self) -> None:
        """Remove the scene's nodes; events still queued for them are dropped."""
        self._lane.close()
        self.root.remove()


class ForceArrows:
    """Two arrows ending at the hand: the force applied there (red: a push, a drag's
    spring) and the force the controller estimates from τ_ext (purple).

    Args:
        scene: the server's scene API.
        parent: the scene node of the arm's base frame (the arrows take its coordinates).
    """

    def __init__(self, scene: viser.SceneApi, parent: str) -> None:
        self.force = scene.add_arrows(f"{parent}/force", points=np.zeros((1, 2, 3)),
                                      colors=FORCE_RGB, shaft_radius=0.007, head_radius=0.016,
                                      head_length=0.03, visible=False)
        self.estimate = scene.add_arrows(f"{parent}/estimate", points=np.zeros((1, 2, 3)),
                                         colors=ESTIMATE_RGB, shaft_radius=0.004,
                                         head_radius=0.01, head_length=0.02, visible=False)

    @staticmethod
    def _arrow(handle: viser.ArrowsHandle, at: np.ndarray, force: np.ndarray | None, *,
               on: float = ARROW_MIN_N, off: float = ARROW_MIN_N) -> None:
        size = math.hypot(*force.tolist()) if force is not None else 0.0
        if not math.isfinite(size) or size < (off if handle.visible else on):
            handle.visible = False
            return
        # The arrow ends at the hand: it shows the push arriving there.
        assert force is not None  # None: size 0, refused above
        tail = at - force * ARROW_M_PER_N
        handle.points = np.array([[tail, at]], dtype=np.float32)
        handle.visible = True

    def set(self, hand: np.ndarray, applied: np.ndarray | None,
            estimated: np.ndarray | None) -> None:
        """Show ``applied`` and ``estimated`` (3,) N (None: hidden) at ``hand`` (3,) m,
        base frame; the estimate only above :data:`ESTIMATE_ON_N` until it falls below
        :data:`ESTIMATE_OFF_N`."""
        self._arrow(self.force, hand, applied)
        self._arrow(self.estimate, hand, estimated, on=ESTIMATE_ON_N, off=ESTIMATE_OFF_N)

    def remove(self) -> None:
        """Remove both arrows from the scene."""
        self.force.remove()
        self.estimate.remove()


def estimated_hand_force(J: np.ndarray, tau_ext: np.ndarray) -> np.ndarray | None:
    """The force the world applies at the hand, (3,) N, from the estimated external joint
    torques (eq. 2.23): F = (J_vᵀ)⁺ (−τ_ext), the statics τ = J_vᵀ F solved by least
    squares (τ_ext is what the motors spend against the world, so the world applies
    −τ_ext). ``J`` (6, n) geometric Jacobian, ``tau_ext`` (n,) N·m; None while τ_ext is
    not finite (compliance off).

    Every page draws this every frame, so a J_v of full rank takes the normal equations'
    3×3 solve, F = (J_v J_vᵀ)⁻¹ J_v (−τ_ext), in plain floats (the pseudo-inverse's F to
    about 1e-16·cond(J_v)²); one near a singular pose (a stretched arm) takes the SVD."""
    tau_ext = np.asarray(tau_ext, dtype=float)
    if not all_finite(tau_ext):
        return None
    Jv = np.asarray(J, dtype=float)[:3]
    if Jv.shape[1] >= 3:
        F = _solve3(*(Jv @ Jv.T).tolist(), (Jv @ -tau_ext).tolist())  # type: ignore[call-arg]  # (3, 3) rows, then the right side
        if F is not None:
            return np.array(F)
    return np.linalg.pinv(Jv.T) @ (-tau_ext)


#: ``_solve3`` leaves a system to the SVD when det(A) < this · (trace(A)/3)³ (A's
#: condition number beyond about 1e8: J_v's beyond 1e4)
SINGULAR_DET = 1e-8


def _solve3(a: list[float], b: list[float], c: list[float],
            r: list[float]) -> list[float] | None:
    """x of [a; b; c] x = r for a symmetric positive semi-definite 3×3 by its adjugate, or
    None when it is nearly singular (:data:`SINGULAR_DET`)."""
    c00 = b[1] * c[2] - b[2] * c[1]
    c01 = b[2] * c[0] - b[0] * c[2]
    c02 = b[0] * c[1] - b[1] * c[0]
    det = a[0] * c00 + a[1] * c01 + a[2] * c02
    scale = (a[0] + b[1] + c[2]) / 3.0
    if not det > SINGULAR_DET * scale ** 3:
        return None
    c11 = a[0] * c[2] - a[2] * c[0]
    c12 = a[2] * b[0] - a[0] * b[2]
    c22 = a[0] * b[1] - a[1] * b[0]
    inv = 1.0 / det
    return [(c00 * r[0] + c01 * r[1] + c02 * r[2]) * inv,
            (c01 * r[0] + c11 * r[1] + c12 * r[2]) * inv,
            (c02 * r[0] + c12 * r[1] + c22 * r[2]) * inv]


def unit(v: np.ndarray) -> np.ndarray:
    """``v`` / |v| (zeros stay zeros)."""
    n = float(np.linalg.norm(v))
    return v / n if n > 0 and math.isfinite(n) else np.zeros_like(v)
