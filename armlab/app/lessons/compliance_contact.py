"""The compliance lesson's Contact tab: the hand run into a wall across the thesis line.

A wall (a plane across the thesis line, some cm ahead of the line's start, facing the
hand) is put into the simulated arm's world through its backend's
:class:`armlab.control.backend.Touchable`; "Run into the wall" plays the thesis line (the
Run tab's command) through it, so the command ends behind the surface. The 3D view draws
the wall (a translucent slab) and its force on the hand (an arrow, scaled as the lesson's
other force arrows); the figures of the run (peak and steady force, bounces, time to
settle, the steady force the law's joint stiffness predicts) are those of
``armlab experiment contact`` (:mod:`armlab.control.experiments.contact`'s functions, of
the wall's force the control loop records every period, ``f_contact`` and its peak at
every plant step between periods, ``f_contact_peak``: :mod:`armlab.control.recorder`);
one chart shows that recorded force beside the arm's sensorless estimates of the hand's
force along the wall's normal, period by period: n · F, F = (J_vᵀ)⁺(−τ) at each period's
measured pose, τ the lab's τ_ext = LPF(τ_dist) − τ_dyn (eq. 2.21–2.23, as the loop
recorded it), the disturbance observer's τ̂_dis (eq. 2.36, its change from its reading at
rest in the 0.5 s before the run began, or before the wall was placed) and the
reaction-torque observer's τ̂_reac (eq. 2.37). The loop runs no observer: they run here,
causally, on the record's rows (the servo load and the angles) as the loop appends them,
each row once (:class:`armlab.control.arm_observers.FollowedRecord`), as ``armlab
experiment contact`` runs them over its record.

The wall is dragged along the line by its gizmo (the distance slider follows), and
"Compare PD and compliance" runs ``armlab experiment contact-compare``'s two runs into the
same wall on a simulated arm of its own (the lesson's model and gains, in the lab's
process for headless runs, :mod:`armlab.app.arm.off_server`) and sets their figures side
by side: the impact, the steady press, the bounces, the settling.

A contact challenge's run (:mod:`armlab.app.lessons.compliance_challenge`) puts its own
wall in through :meth:`ContactTab.challenge_wall` (drawn as the tab's), and the tab's
setting comes back once it is over; its figures are shown here too.

Real servos touch no simulated wall: there the wall is virtual, the one the compliance law
renders (:mod:`armlab.control.virtual_wall`, put in by ``SetVirtualWall``): the loop
records the force it renders as ``f_contact``, so the tab's figures, chart and arrow are
the same; PD renders none, and a run into the wall under it is refused.
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import viser
import viser.transforms as vtf

from armlab.app.arm import off_server
from armlab.app.lessons._common import esc, guarded, set_content
from armlab.app.lessons._loop_state import check_running
from armlab.app.lessons.compliance_scene import ARROW_M_PER_N, ARROW_MIN_N
from armlab.app.lessons.compliance_teach import STALE, people
from armlab.app.page.in_order import InOrder
from armlab.app.page.inputs import guarded_slider
from armlab.app.page.plots import COLORS, LivePlot, SeriesSpec
from armlab.control.arm_observers import FollowedRecord, hand_normal_forces
from armlab.control.backend import Touchable
from armlab.control.backend import WallSetting as BackendWall
from armlab.control.commands import RunTrajectory, SetVirtualWall
from armlab.control.experiments.contact import (
    HOLD_S,
    contact_figures,
    joint_stiffness,
    predicted_force,
    wall_across_line,
)
from armlab.control.loop import VIRTUAL_WALL_SET_MAX_N
from armlab.control.params import Params
from armlab.control.trajectory import THESIS_LINE_END
from armlab.kinematics.smallarrays import all_finite

if TYPE_CHECKING:
    from armlab.app.lessons.compliance import ComplianceLesson, Rig

RUN_LABEL = "into the wall"  #: the run's label in the Files tab's Save run
#: What the tab says on real servos.
VIRTUAL_NOTE = ("On the servos the wall is **virtual**: the compliance law renders it. "
                "Inside it, it pushes the hand out (k × the penetration, plus damping), "
                "and eq. 2.7 takes that push as an external torque, so the arm backs out "
                "of the wall as from a push, and your hand pushing the arm into it feels "
                "it hold. The orange arrow and the chart show the force it renders; PD "
                "renders none (Gains tab: the compliance law).")
DISTANCE_STEP_CM = 0.5  #: the wall's distance moves in these steps (slider and drag)
DISTANCE_CM = 18.0  #: default: 2 cm before the line's end, the command ends 2 cm behind it
#: N/m, default: a wooden table top under a servo arm's hand (``armlab experiment contact``'s
#: default, so the tab's figures and the experiment's can be compared)
STIFFNESS = 2e4
DAMPING = 50.0  #: N·s/m, the experiment's default
#: N: the wall is not put where the hand already presses harder than this (it would
#: throw the arm back); Home first (the loop's own limit for a virtual wall)
PLACE_MAX_N = VIRTUAL_WALL_SET_MAX_N
WALL_RGB = (140, 100, 60)  #: wood
WALL_OPACITY = 0.35
WALL_SIZE_M = (0.22, 0.22, 0.006)  #: the slab drawn: width, height, thickness (along n)
#: m: the block the Shape choice puts in the wall's place (width, height, thickness): the
#: hand presses its face, and the forearm, reaching past the face's plane beside the
#: hand, meets its side
BLOCK_SIZE_M = (0.06, 0.04, 0.05)
#: The Shape choice: the wall's plane (the hand's tip meets it) or the block (the links too)
SHAPES = ("a wall (a plane)", "a 6×4×5 cm block")  # (short: whole in Projector mode)
CONTACT_RGB = (230, 120, 0)
CHART_WINDOW_S = 10.0
CHART_POINTS = 100  #: the loop's record thinned to about this many periods for the chart
#: The chart's lines: the wall's recorded force and the hand's force along its normal by
#: each estimate (τ_ext, the DOB's change from rest, the RTOB), each its colour and dash
CHART_SERIES = (SeriesSpec("wall (ground truth)", COLORS[3], width=2.5),
                SeriesSpec("estimate from τ_ext", COLORS[4], (6, 4)),
                SeriesSpec("DOB (eq. 2.36), change from rest", COLORS[0], (2, 3)),
                SeriesSpec("RTOB (eq. 2.37)", COLORS[5], (12, 3, 2, 3)))


@dataclass(frozen=True)
class WallSetting:
    """The wall as the controls set it: on, cm ahead of the line's start, N/m, N·s/m, and
    its Coulomb friction μ."""

    on: bool
    distance_cm: float
    stiffness: float
    damping: float
    friction: float = 0.0
    block: bool = False  #: a block (:data:`BLOCK_SIZE_M`) in the wall's place

    @property
    def size(self) -> tuple[float, float, float] | None:
        """The obstacle's box (width, height, thickness) m, or None: the plane."""
        return BLOCK_SIZE_M if self.block else None


@dataclass
class ContactRun:
    """A run into the wall being measured (or measured)."""

    t0: float
    params: Params
    wall: WallSetting
    controller: str
    normal: np.ndarray
    depth: float  #: m of command behind the surface at the line's end
    line_end: float | None = None  #: loop time the line ended, s
    #: the loop's record of the run, once over: loop times s, the wall's force N and its
    #: peak at the plant's steps N, one a period
    t: list[float] = field(default_factory=list)
    force: list[float] = field(default_factory=list)
    peak: list[float] = field(default_factory=list)
    figures: dict[str, Any] | None = None


class ContactTab:
    """The Contact tab's controls, figures and chart, added to ``gui`` (inside the tab),
    and its wall and arrow in the lesson's scene.

    Args:
        lesson: the compliance lesson (its rig, runs, challenges and law checks).
        gui: where to add the controls.
        servos: real servos: the wall is the one the compliance law renders, and the tab
            says so.
    """

    def __init__(self, lesson: ComplianceLesson, gui: viser.GuiApi, *, servos: bool) -> None:
        self._lesson = lesson
        self._lock = threading.RLock()
        self.servos = servos
        if servos:
            gui.add_markdown(VIRTUAL_NOTE)
        else:
            gui.add_markdown("Put a **wall** across the thesis line and run the hand into "
                             "it: the orange arrow is the wall's force on the hand, the "
                             "chart sets it beside the force the arm reads without a "
                             "sensor: from τ_ext (eq. 2.23) and from the disturbance "
                             "and reaction-torque observers (DOB, RTOB). Compare PD "
                             "with the compliance law (Gains tab). At the thesis's "
                             "α 0.05 the hand bounces on the wall (the filter's lag); "
                             "at α 0.6 it rests there, pressing what the law predicts.")
        self.wall_on = gui.add_checkbox("Wall", False,
                                        hint="Put the wall across the thesis line (a "
                                             "plane facing the hand)")
        self.distance = guarded_slider(
            gui, "Wall ahead of the hand (cm)", name="wall distance", lo=5.0, hi=20.0,
            step=DISTANCE_STEP_CM, initial=DISTANCE_CM,
            apply=lambda v: self._changed(distance_cm=v),
            hint="Along the thesis line from its start; the line is 20 cm, so the command "
                 "ends (20 − this) cm behind the wall's surface")
        self.stiffness = guarded_slider(
            gui, "Wall stiffness (N/m)", name="wall stiffness", lo=1000.0, hi=100000.0,
            step=1000.0, initial=STIFFNESS, apply=lambda v: self._changed(stiffness=v),
            hint="N per m of penetration; 2·10⁴: a wooden table under a servo arm's hand")
        self.damping = guarded_slider(
            gui, "Wall damping (N·s/m)", name="wall damping", lo=0.0, hi=500.0, step=5.0,
            initial=DAMPING, apply=lambda v: self._changed(damping=v),
            hint="N per m/s of the penetration's rate while touching (it never pulls)")
        self.shape = gui.add_dropdown(
            "Shape", SHAPES, initial_value=SHAPES[0],
            hint="The wall's plane, which the hand's tip meets, or a block in its place, "
                 "which the arm's links meet too (the simulated arm only)",
            visible=not servos)
        self.friction = guarded_slider(
            gui, "Wall friction μ", name="wall friction", lo=0.0, hi=2.0, step=0.05,
            initial=0.0, apply=lambda v: self._changed(friction=v),
            hint="Coulomb friction along the wall: the hand sliding on it is held back by "
                 "up to μ × the wall's push (0: frictionless; the wall the law renders on "
                 "servos has none)")
        self.button = gui.add_button("Run into the wall", color="green",
                                     icon=viser.Icon.WALL,
                                     hint="Play the thesis line with the wall across it, "
                                          "hold 4 s behind the surface, measure the force")
        self.result = gui.add_markdown("")
        self.compare_button = gui.add_button(
            "Compare PD and compliance", icon=viser.Icon.SCALE, visible=not servos,
            hint="Run the hand into this wall twice on a simulated arm of its own, under "
                 "PD and under the compliance law (these gains), and set the figures "
                 "side by side")
        self.comparison = gui.add_markdown("")
        self.chart = LivePlot(gui, title="Contact force along the wall's normal",
                              y_label="force (N)", window_s=CHART_WINDOW_S, points=100,
                              series=CHART_SERIES,
                              y_span=5.0)
        self.wall_on.on_update(lambda e: guarded(e, self._changed))
        self.shape.on_update(lambda e: guarded(e, self._changed))
        self.button.on_click(lambda e: guarded(e, self.run))
        self.compare_button.on_click(lambda e: guarded(e, self.compare))
        self._comparing = False  #: a comparison's two runs are going on
        self._closed = False
        #: the wall's gizmo's events, in the order the page sent them
        self._lane = InOrder("armlab-contact-wall")
        self._drag: viser.TransformControlsHandle | None = None
        self._rig: Rig | None = None  #: the rig the wall and the nodes were placed on
        self._placed: tuple[np.ndarray, np.ndarray] | None = None  #: (origin, normal), base
        self._wall_node: viser.BoxHandle | None = None
        self._arrow: viser.ArrowsHandle | None = None
        self._force_now = 0.0
        self._run: ContactRun | None = None
        #: the observers kept up with the rig's record while a wall is placed, and the
        #: loop time the DOB's reference reading ends at (the wall placed, a run begun)
        self._observed: FollowedRecord | None = None
        self._dob_rest_at = 0.0
        self._dob_rest: np.ndarray | None = None
        self._shown_stale: bool | None = None
        #: a contact challenge's wall is in place (not the controls')
        self._challenge_wall = False
        #: the figures of the last run into a wall, the tab's or a challenge's (the
        #: lesson's ``run_figures``)
        self.last_figures: dict[str, Any] | None = None

    # ------------------------------------------------------------------ the wall

    def setting(self, **override: float) -> WallSetting:
        """The wall as the controls set it (``override``: a value being applied)."""
        return WallSetting(
            on=bool(self.wall_on.value),
            distance_cm=float(override.get("distance_cm", self.distance.value)),
            stiffness=float(override.get("stiffness", self.stiffness.value)),
            damping=float(override.get("damping", self.damping.value)),
            friction=float(override.get("friction", self.friction.value)),
            block=self.shape.visible and self.shape.value == SHAPES[1])

    def _changed(self, **override: float) -> None:
        """Place (or remove) the wall as the controls say; ValueError (shown) to refuse."""
        with self._lock:
            rig = self._lesson.rig
            if rig is None:
                raise ValueError("the arm is being rebuilt; try again")
            if self._challenge_wall:  # the person's wall replaces the challenge's
                self._lesson.challenges.cancel("a change of the wall")
                self._challenge_wall = False
            try:
                self._place(rig, self.setting(**override))
            except ValueError:
                if self.wall_on.value and "distance_cm" not in override and \
                        "stiffness" not in override and "damping" not in override and \
                        "friction" not in override:
                    self._wall_off()  # (its callback removes the wall)
                raise

    def _wall_off(self) -> None:
        """Untick Wall (on every page; its callback removes the wall)."""
        box: Any = self.wall_on  # (viser's stubs type an input's value as read-only)
        box.value = False

    def _place(self, rig: Rig, wall: WallSetting) -> None:
        backend = rig.backend
        self._rig = rig
        if not wall.on:
            if isinstance(backend, Touchable):
                backend.set_wall(None, stiffness=wall.stiffness, damping=wall.damping)
            else:
                rig.loop.post(SetVirtualWall(None))
            self._placed = self._observed = None  # (placed again: read from rest again)
            self._remove_nodes()
            return
        model = rig.model
        _, _, origin, normal = wall_across_line(model, rig.line.q[0], rig.line.q[-1],
                                                wall.distance_cm / 100.0)
        moved = self._placed is None or not np.allclose(self._placed[0], origin)
        snap = rig.loop.recorder.snapshot(0.05)  # (a new stiffness or damping: not checked)
        if moved and len(snap["t"]) and all_finite(snap["q"][-1]):
            hand = model.fk(snap["q"][-1])[:3, 3]
            inside = -float((hand - origin) @ normal)
            if inside * wall.stiffness > PLACE_MAX_N:
                raise ValueError(f"the hand is {people(inside * 100)} cm behind that wall's "
                                 "surface: press Home (Run tab) first, then place the wall")
        if isinstance(backend, Touchable):
            backend.set_wall(origin, normal, stiffness=wall.stiffness, damping=wall.damping,
                             friction=wall.friction, size=wall.size)
        else:  # servos: the law renders it (the loop refuses it with the hand inside)
            rig.loop.post(SetVirtualWall(BackendWall(origin, normal, wall.stiffness,
                                                     wall.damping)))
        self._placed = (origin, normal)
        self._draw_wall(rig, origin, normal, size=wall.size)

    def _draw_wall(self, rig: Rig, origin: np.ndarray, normal: np.ndarray, *,
                   size: tuple[float, float, float] | None = None) -> None:
        """The slab (or the block of ``size``) and the arrow's node under the arm's base
        frame, the face at ``origin``."""
        scene = self._lesson.server.scene
        sh = rig.scene.shoulder.name
        z = normal / np.linalg.norm(normal)
        x = np.cross([0.0, 0.0, 1.0], z)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
        R = np.column_stack([x, np.cross(z, x), z])
        wxyz = vtf.SO3.from_matrix(R).wxyz
        dims = WALL_SIZE_M if size is None else size
        centre = origin - z * dims[2] / 2  # its face on the plane, the slab behind
        if self._wall_node is not None and tuple(self._wall_node.dimensions) != dims:
            self._wall_node.remove()  # another shape: drawn anew
            self._wall_node = None
        if self._wall_node is None:
            self._wall_node = scene.add_box(f"{sh}/contact_wall", color=WALL_RGB,
                                            dimensions=dims, opacity=WALL_OPACITY,
                                            wxyz=wxyz, position=centre, cast_shadow=False)
        else:
            self._wall_node.wxyz, self._wall_node.position = wxyz, centre
        if self._drag is None:  # the wall's handle: dragged along its normal only
            self._drag = scene.add_transform_controls(
                f"{sh}/contact_wall_drag", scale=0.06, active_axes=(False, False, True),
                disable_rotations=True, disable_sliders=True, depth_test=False, wxyz=wxyz,
                position=origin)
            self._drag.on_update(self._lane(self._dragged))
        elif self._drag_phase is None:  # (not while a person holds it)
            self._drag.wxyz, self._drag.position = wxyz, origin
        if self._arrow is None:
            self._arrow = scene.add_arrows(f"{sh}/contact_force", points=np.zeros((1, 2, 3)),
                                           colors=CONTACT_RGB, shaft_radius=0.006,
                                           head_radius=0.014, head_length=0.025,
                                           visible=False)

    def _remove_nodes(self) -> None:
        for node in (self._wall_node, self._arrow, self._drag):
            if node is not None:
                node.remove()
        self._wall_node = self._arrow = self._drag = None

    _drag_phase: str | None = None  #: "start"/"update" while a person drags the wall

    def _dragged(self, event: viser.TransformControlsEvent) -> None:
        """The wall's gizmo moved by a page: the distance along the line follows (the
        slider's value, applied as the slider applies it); at the release the gizmo goes
        back onto the wall as placed (a refused place leaves the wall where it was)."""
        if event.client is None:  # a move from Python
            return
        with self._lock:
            rig, drag = self._rig, self._drag
            if rig is None or drag is None or event.target is not drag:
                return
            self._drag_phase = None if event.phase == "end" else event.phase
            x0, u, _, _ = wall_across_line(rig.model, rig.line.q[0], rig.line.q[-1], 0.0)
            along = float((np.asarray(event.target.position, dtype=float) - x0) @ u) * 100.0
            if not math.isfinite(along):  # (a page's NaN or inf: nothing moves)
                return
            step = DISTANCE_STEP_CM
            cm = min(max(round(along / step) * step, self.distance.lo), self.distance.hi)
            if cm != self.distance.value:
                self.distance.set(cm)  # (its guard applies it, or refuses and says why)
            if event.phase == "end" and self._placed is not None:
                drag.position = self._placed[0]

    def close(self) -> None:
        """The lesson is closing: the gizmo's events are dropped and a comparison going on
        writes nothing."""
        with self._lock:
            self._closed = True
        self._lane.close()

    def challenge_wall(self, rig: Rig, origin: np.ndarray, normal: np.ndarray) -> None:
        """A contact challenge's wall (``origin`` (3,) m, unit ``normal`` (3,), base frame),
        which its restarted arm meets, drawn in place of the controls' until
        :meth:`end_challenge_wall`."""
        with self._lock:
            self._rig, self._run = rig, None
            self._placed = (np.asarray(origin, dtype=float), np.asarray(normal, dtype=float))
            self._challenge_wall = True
            self._draw_wall(rig, *self._placed)
            set_content(self.result, "**Challenge run**: the hand into the challenge's "
                                     "wall…")

    def end_challenge_wall(self) -> None:
        """The contact challenge is over: the wall the controls set back (or none)."""
        with self._lock:
            rig = self._lesson.rig
            if not self._challenge_wall:
                return
            self._challenge_wall = False
            if rig is None:
                return
            try:
                self._place(rig, self.setting())
            except ValueError as exc:  # (the hand behind the controls' wall)
                self._wall_off()
                self._place(rig, replace(self.setting(), on=False))
                set_content(self.result, f"The wall is off: {esc(str(exc))}")

    def take_challenge(self, figures: dict[str, Any], *, predicted: float | None,
                       label: str) -> None:
        """A contact challenge's run, measured (``figures`` of
        :func:`~armlab.control.experiments.contact.contact_figures`): the lesson's contact
        figures and the tab's line."""
        figures = {**figures, "predicted_force_n": predicted}
        with self._lock:
            self.last_figures = figures
            text = (f"**Challenge run** ({esc(label)}): peak "
                    f"**{_newtons(figures['peak_force_n'])}**, steady "
                    f"**{_newtons(figures['steady_force_n'])}**, the law predicts "
                    f"{_newtons(predicted)}")
            if figures.get("fault"):
                text += f"; stopped: {esc(str(figures['fault']))}"
            set_content(self.result, text)
            self._lesson.last_run_text = text

    def nodes(self) -> tuple[viser.BoxHandle | None, viser.ArrowsHandle | None]:
        """The wall's and the arrow's scene nodes (None: not in the scene)."""
        return self._wall_node, self._arrow

    def _follow_rig(self, rig: Rig | None) -> None:
        """A rebuilt rig (other link lengths): the wall placed again on its backend (its
        scene is new: the nodes went with the old one)."""
        if rig is self._rig:
            return
        self._wall_node = self._arrow = None  # (removed with the old rig's scene)
        self._placed, self._rig, self._run = None, rig, None
        if rig is not None and self.wall_on.value:
            try:
                self._place(rig, self.setting())
            except ValueError as exc:
                self._wall_off()
                set_content(self.result, f"The wall is off: {esc(str(exc))}")

    # ------------------------------------------------------------------ the run

    def run(self) -> None:
        """Play the thesis line with the wall across it and measure the contact."""
        lesson = self._lesson
        rig = lesson.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        if not isinstance(rig.backend, Touchable) and \
                rig.loop.controller.effective_mode(rig.loop.params) != "compliance":
            raise ValueError("on the servos the wall is the one the compliance law renders; "
                             "PD renders none: choose the compliance law (Gains tab)")
        with self._lock:
            self._follow_rig(rig)
            if self._placed is None:
                raise ValueError("turn the wall on first (the Wall box above)")
            check_running(rig.loop.status)
            lesson._law_works("Run into the wall")
            lesson.challenges.busy()
            lesson.challenges.untag("contact")  # (not a challenge's run)
            st = rig.loop.status
            wall = self.setting()
            origin, normal = self._placed
            x0, u, _, _ = wall_across_line(rig.model, rig.line.q[0], rig.line.q[-1], 0.0)
            length = float((rig.model.fk(rig.line.q[-1])[:3, 3] - x0) @ u)
            lesson.runs.post(rig.loop, RunTrajectory(rig.line), run=RUN_LABEL)
            lesson.run_start, lesson.run_label = st.t, RUN_LABEL
            lesson.experiment = None  # (the lesson's own runs measure nothing of this)
            self._run = ContactRun(st.t, rig.loop.params, wall, st.controller, normal,
                                   depth=length - wall.distance_cm / 100.0)
            self._dob_rest_at, self._dob_rest = st.t, None  # the DOB's change from here
            self._shown_stale = None
            rig.scene.set_target(THESIS_LINE_END)
            set_content(self.result, "**Into the wall**: running…")

    def compare(self) -> None:
        """PD and the compliance law into the controls' wall, side by side, on a simulated
        arm of its own (the lesson's model and gains; the lesson's own arm runs on)."""
        lesson = self._lesson
        rig = lesson.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        if self.servos:
            raise ValueError("the comparison runs PD, which renders no wall on servos")
        with self._lock:
            if self._comparing:
                raise ValueError("a comparison is running; wait for its figures")
            self._comparing = True
        wall, model, params = self.setting(), rig.model, rig.loop.params
        x0, u, _, _ = wall_across_line(model, rig.line.q[0], rig.line.q[-1], 0.0)
        length = float((model.fk(rig.line.q[-1])[:3, 3] - x0) @ u)
        set_content(self.comparison, "**PD and compliance**: running both…")

        depth = max(0.0, length - wall.distance_cm / 100.0)  # (a wall at the line's end: 0)

        walls = {"wall": wall.distance_cm / 100.0, "depth": depth,
                 "stiffness": wall.stiffness, "damping": wall.damping,
                 "friction": wall.friction, "size": wall.size}

        def done(future: Future[dict[str, Any]]) -> None:
            try:
                text = comparison_markdown(future.result(), wall)
            except Exception as exc:  # noqa: BLE001 - said on the page, the lab goes on
                text = f"**PD and compliance**: could not run ({esc(str(exc))})"
            with self._lock:
                self._comparing = False
                if not self._closed:
                    set_content(self.comparison, text)

        try:  # (off the server's interpreter: seconds of simulation, a class pressing too)
            off_server.submit(off_server.compare_on_sim, model, params,
                              walls).add_done_callback(done)
        except ValueError:
            with self._lock:
                self._comparing = False
            raise

    def tick(self) -> None:
        """Sample the wall's force and measure a run once it is over (the publisher's every
        tick)."""
        lesson = self._lesson
        with self._lock:
            rig = lesson.rig
            self._follow_rig(rig)
            if rig is None or self._placed is None:
                self._force_now = 0.0
                if rig is not None:
                    self._mark_stale(rig)
                return
            st = rig.loop.status
            force = self._recorded_force(rig)
            self._force_now = force
            run = self._run
            if run is None or run.figures is not None:
                self._mark_stale(rig)
                return
            if lesson.runs.going_on != RUN_LABEL:  # another run began: this one is cut
                self._run = None
                set_content(self.result, "**Into the wall**: cut short by another run")
                return
            if run.line_end is None and st.t > run.t0 + 0.1 and st.trajectory is None:
                run.line_end = st.t
            if st.fault is None and (run.line_end is None or st.t < run.line_end + HOLD_S):
                return
            self._finish(rig, run, st.fault)

    @staticmethod
    def _recorded_force(rig: Rig) -> float:
        """N, the wall's force on the hand in the loop's newest record row (0: no wall)."""
        snap = rig.loop.recorder.snapshot(0.05)
        if not len(snap["t"]):
            return 0.0
        f = float(snap["f_contact"][-1])
        return f if math.isfinite(f) else 0.0


    def _finish(self, rig: Rig, run: ContactRun, fault: str | None) -> None:
        """The run's figures, of the loop's record from the run's start (every period)."""
        snap = rig.loop.recorder.snapshot(rig.loop.status.t - run.t0 + 1.0)
        rows = snap["t"] >= run.t0
        run.t = snap["t"][rows].tolist()
        run.force = np.nan_to_num(snap["f_contact"][rows]).tolist()
        run.peak = np.nan_to_num(snap["f_contact_peak"][rows]).tolist()
        figures = contact_figures(np.array(run.t), np.array(run.force), np.array(run.peak))
        k_q = joint_stiffness(run.params, run.controller)
        figures["predicted_force_n"] = None if k_q is None or run.depth <= 0 else \
            predicted_force(rig.model, rig.line.q[-1], run.normal, run.depth, k_joint=k_q,
                            k_wall=run.wall.stiffness)
        figures["fault"] = fault
        if fault is not None:
            figures["steady_force_n"] = None
        run.figures = figures
        self.last_figures = figures
        self._shown_stale = None
        self._mark_stale(rig)
        self._lesson.runs.finish_run(
            {k: figures[k] for k in ("peak_force_n", "steady_force_n", "bounces", "settle_s",
                                     "predicted_force_n")}, t=run.t[-1] if run.t else run.t0)

    def figures(self) -> dict[str, Any] | None:
        """The last run's figures (None: none measured yet)."""
        run = self._run
        return None if run is None else run.figures

    def stale(self) -> bool:
        """Whether the last run's figures were measured with other gains or another wall."""
        rig, run = self._lesson.rig, self._run
        if run is None or run.figures is None or rig is None:
            return False
        return run.params != rig.loop.params or run.wall != self.setting()

    def _mark_stale(self, rig: Rig) -> None:
        run = self._run
        if run is None or run.figures is None:
            return
        old = self.stale()
        if old != self._shown_stale:
            self._shown_stale = old
            set_content(self.result, figures_markdown(run, stale=old))

    # ------------------------------------------------------------------ frames

    def draw(self, hand: np.ndarray) -> None:
        """The contact force's arrow at ``hand`` (3,) m, base frame (the pose frames)."""
        with self._lock:
            arrow, placed = self._arrow, self._placed
            if arrow is None or placed is None:
                return
            f = self._force_now
            if not (math.isfinite(f) and f >= ARROW_MIN_N):
                if arrow.visible:
                    arrow.visible = False
                return
            tail = hand - placed[1] * f * ARROW_M_PER_N  # from inside the wall to the hand
            arrow.points = np.array([[tail, hand]], dtype=np.float32)
            arrow.visible = True

    def plot(self, force: bool) -> None:
        """The chart's newest window of the loop's record (the plot frames): the wall's
        recorded force and the estimate of it from τ_ext, while a wall is placed."""
        with self._lock:
            rig, placed = self._lesson.rig, self._placed
        if rig is None or placed is None:
            return
        observed = self._observed
        if observed is None or observed.recorder is not rig.loop.recorder:
            observed = self._observed = FollowedRecord(
                rig.model, rig.loop.recorder, window_s=CHART_WINDOW_S,
                period=rig.loop.params.period)
            self._dob_rest_at, self._dob_rest = rig.loop.status.t, None
        observed.update()  # (the periods since the last frame only)
        snap = rig.loop.recorder.snapshot(CHART_WINDOW_S, max_points=CHART_POINTS)
        if len(snap["t"]) < 2:
            return
        if self._dob_rest is None:
            self._dob_rest = observed.rest_reading(self._dob_rest_at)
        dis, reac = observed.at(snap["t"])
        dob = dis - (np.full(dis.shape[1], math.nan) if self._dob_rest is None
                     else self._dob_rest)
        wall = np.nan_to_num(snap["f_contact"])  # (NaN: rows before the wall was placed)
        est = hand_normal_forces(rig.model, snap["q"], (snap["tau_ext"], dob, reac),
                                 placed[1])
        self.chart.update(snap["t"], (wall, *est), force=force)


def figures_markdown(run: ContactRun, *, stale: bool = False) -> str:
    """The figures of ``run`` in the page's number style, one short paragraph."""
    fig = run.figures or {}
    w = run.wall
    law = "compliance law" if joint_stiffness(run.params, run.controller) else "PD"
    head = (f"**Into the wall** ({law}, wall {people(w.distance_cm)} cm ahead, "
            f"{people(w.stiffness)} N/m, {people(w.damping)} N·s/m"
            + (f", μ {people(w.friction)}" if w.friction else "") + ")")
    if not fig.get("touched"):
        text = f"{head}: the hand never touched the wall"
    else:
        def n(x: float | None) -> str:
            return "—" if x is None else f"{people(x)} N"
        settle = fig.get("settle_s")
        lines = [f"peak **{n(fig['peak_force_n'])}**",
                 f"steady **{n(fig['steady_force_n'])}**",
                 f"the law predicts {n(fig.get('predicted_force_n'))}"
                 + ("" if fig.get("predicted_force_n") is not None
                    else " (PD: no finite stiffness)"),
                 f"{fig['bounces']} bounce{'s' if fig['bounces'] != 1 else ''}",
                 "settles in " + ("— (never within 10 %)" if settle is None
                                  else f"{people(settle)} s")]
        text = f"{head}: " + ", ".join(lines)
    if fig.get("fault"):
        text += f"; stopped: {esc(str(fig['fault']))}"
    if stale:
        text += f"\n\n{STALE} measured with other gains or another wall: run again"
    return text


def comparison_markdown(result: dict[str, Any], wall: WallSetting) -> str:
    """``contact-compare``'s figures (:func:`~armlab.control.experiments.contact.
    compare_contact`) as the tab's table: a row a figure, PD's beside the compliance
    law's."""
    def cell(value: Any, unit: str) -> str:
        if value is None:
            return "—"
        if isinstance(value, str):
            return value
        return f"{people(float(value))} {unit}".rstrip()

    what = "the block" if wall.block else "the wall"
    lines = [f"**PD and compliance** into {what} {people(wall.distance_cm)} cm ahead "
             f"({people(wall.stiffness)} N/m):", "", "| | PD | compli\u00adance |",
             "| --- | --- | --- |"]
    lines += [f"| {row['figure']} | {cell(row['pd'], row['unit'])} | "
              f"{cell(row['compliance'], row['unit'])} |" for row in result["rows"]]
    return "\n".join(lines)


def _newtons(x: float | None) -> str:
    """A force as the tab shows it ("2.14 N"; "—": none)."""
    return "—" if x is None else f"{people(x)} N"
