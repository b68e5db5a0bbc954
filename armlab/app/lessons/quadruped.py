"""Lesson: the seed 003 quadruped walking, its 12 AX-12A servos and its static stability.

The quadruped walks in 3D, in place or across the floor with its body carried by
its stance feet, by the paper's sine pattern and trot (Table 1.1, leg IK eq.
3.1-3.9) or by a crawl that keeps it statically stable (one leg at a time, the
body shifted over the supporting triangle first). Sliders set A (step length),
B (outward foot offset), C (step height), D (body height), α (heading) and the
gait speed; buttons walk forward, back, or turn. The scene shows every foot's path
over a cycle, trails on the floor, the support polygon, the centre of mass and the
static stability margin.

Behind it a :class:`armlab.control.gait_loop.GaitLoop` drives 12 AX-12A servos: simulated
(:class:`armlab.hardware.families.dynamixel1.quadruped.QuadrupedSimBackend`, the legs loaded by the
body's
weight while they stand) or on a serial port (``DynamixelBackend``: real servos, or
``armlab emulate --robot quadruped``). The servo tab reports the paper's eq. 4.1,
the commanded-vs-servo angle error in percent, from the servos' own feedback.

Data flow as in the compliance lesson: UI callbacks validate input, plan the gait
(``armlab.control.walking.plan_gait``) and post it to the loop; a :class:`Publisher` draws
the loop's latest state at 30 Hz and the charts at 10 Hz. The Files tab
(:mod:`armlab.app.lessons.run_files`) saves a walk as a run file (the goals sent and the
angles the servos read), replays one on a see-through quadruped and exports the HTML page.

Runs (what Save run saves, kept apart from the loop's 20 s record, at most 120 s): a
direction button begins a walk, labelled by its gait and direction ("trot forward"),
over once the robot stands again (Stop, or Reset) with its eq. 4.1 error
(:meth:`QuadrupedLesson.run_figures`, the figure the page shows for the last walk); a
direction, gait or sine-input change while it walks is a command inside the same walk.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from armlab.app.arm.backends import make_backend
from armlab.app.lessons import Lesson, LessonContext
from armlab.app.lessons._common import (
    Every,
    LessonBase,
    close_in_turn,
    guarded,
    set_content,
    status_html,
    warning_html,
)
from armlab.app.lessons.quadruped_scene import QuadrupedScene
from armlab.app.lessons.restart_challenge import RestartRuns
from armlab.app.lessons.run_files import Recording, RunControls
from armlab.app.page.inputs import GuardedNumber, guarded_slider
from armlab.app.page.plots import (
    ANGLE_SPAN_DEG,
    COLORS,
    LivePlot,
    SeriesSpec,
    dash,
    decimation,
    rebuild_plots,
)
from armlab.app.page.surface import Surface
from armlab.control.backend import Backend, BackendError
from armlab.control.commands import Reset
from armlab.control.experiments.seed003 import joint_names as gait_joint_names
from armlab.control.gait_loop import GaitLoop, GaitStatus, SetInPlace, SetSpeed, StopWalking
from armlab.control.restart import RestartableArm
from armlab.control.walking import (
    COMMANDS,
    GAITS,
    GaitPlan,
    GaitSpec,
    Walker,
    angle_error_pct,
    plan_gait,
    walking_tilts_deg,
)
from armlab.hardware.families.dynamixel1.quadruped import SIM_DT, QuadrupedSimBackend
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.gait import SineParams
from armlab.kinematics.model import Quadruped, SerialChain
from armlab.kinematics.quadruped import LEGS, QuadrupedGeometry
from armlab.kinematics.units import deg

if TYPE_CHECKING:
    from armlab.app.workers.remote_gait import RemoteGait

NAME = "quadruped"
TITLE = "Quadruped gait"
HELP = ("The seed 003 quadruped walks by the sine pattern (A step length, B foot offset, "
        "C step height, D body height, α heading) and its leg IK, driving 12 AX-12A servos. "
        "The trot is not statically stable: while two legs swing it stands on two diagonal "
        "feet, a line, so its stability margin is never positive (it does not tip only "
        "because each half-step is quick). The crawl "
        "lifts one leg at a time after shifting the body over the other three: its margin "
        "stays positive. The servo tab gives the paper's eq. 4.1 error (paper: 1.201 %).")
#: The first action, shown under the status line.
TRY = ("Press **Forward** and watch the stability margin while two legs swing.")
ROBOTS = ("quadruped",)
ORDER = 30
#: a student's page can hold a private copy: their own robot in the class
#: (``ctx.arms.quadruped_for``: :mod:`armlab.app.workers.class_quadrupeds` in the class's worker
#: process)
PRIVATE = True
#: The figure of its last walk: seed 003's eq. 4.1 error, % (from the servos' feedback).
FIGURES = ("eq41_error_pct",)
#: What a class overview shows of it, and its column's head.
OVERVIEW = {"eq41_error_pct": "eq. 4.1 err %"}

#: The paper's mean commanded-vs-servo angle error (seed 003 §4.1.2), %.
PAPER_ERROR_PCT = 1.201
#: Slider specs: name -> (label, lo, hi, step, SineParams field, display scale).
GAIT_SLIDERS: dict[str, tuple[str, float, float, float, str, float]] = {
    "A": ("A step length (cm)", 0.0, 8.0, 0.5, "A", 100.0),
    "B": ("B foot offset (cm)", 5.0, 13.0, 0.5, "B", 100.0),
    "C": ("C step height (cm)", 0.0, 5.0, 0.5, "C", 100.0),
    "D": ("D body height (cm)", 5.0, 13.0, 0.5, "D", 100.0),
    "alpha": ("α heading (°)", 45.0, 135.0, 5.0, "alpha_deg", 1.0),
}
SPEED_RANGE = (0.05, 1.5)
#: s of record every chart shows, and the points it is decimated to (one grid: a frame
#: finds the record's bins once for the five charts)
CHART_WINDOW_S = 8.0
CHART_POINTS = 128
COMMAND_LABELS = {"forward": "Forward", "back": "Back", "left": "Turn left",
                  "right": "Turn right"}
#: s between two workings-out of the Servos tab's table (10 s of record each)
TABLE_S = 1.0
#: s, at most the gait loop's period (20 ms simulated, 30 ms on a bus): a walk's run
#: takes its lead from that many rows, cut to its time
RUN_PERIOD_S = 0.02


def leg_joint_labels(model: Quadruped, leg: str) -> tuple[str, ...]:
    """What ``leg``'s joints are called on the page, from the model's joint names:
    "RF_hip_yaw" -> "hip yaw"."""
    return tuple(name.removeprefix(f"{leg}_").replace("_", " ")
                 for name in model.legs[leg].joint_names)


@functools.cache
def _robot(name: str) -> SerialChain | Quadruped:
    """``load_robot(name)``, once per process: every page's copy of the lesson (a classroom)
    shares the model and the dynamics compiled for it on first use (the Servos tab's tilts)."""
    return load_robot(name)


def build(server: Surface, ctx: LessonContext) -> QuadrupedLesson:
    """Open the lesson on ``server`` (see :mod:`armlab.app.lessons`)."""
    return QuadrupedLesson(server, ctx)


def open_servos(model: Quadruped, ctx: LessonContext, q0: np.ndarray
                ) -> tuple[Backend | None, str]:
    """The 12 servos for ``ctx.backend``: (backend, "") or (None, why not).

    A serial bus without all 12 AX-12A (IDs 1..12 by default) gives one message saying
    what is missing and what to do; the lesson then shows the gait without servos.
    """
    if ctx.backend == "sim":  # a challenge's walk starts it again standing at the start
        return RestartableArm(lambda q: QuadrupedSimBackend(model, q0=q, dt=SIM_DT), q0,
                              period=0.02, sync_first=False), ""
    try:
        # the reply timeout is the bus's own (armlab.hardware.wire.bus: a wire's or an emulator's)
        backend = make_backend(ctx.backend, model, port=ctx.port, baud=ctx.baud)
    except (BackendError, ValueError, OSError) as exc:
        return None, (f"The quadruped needs 12 AX-12A servos (IDs 1–12: legs "
                      f"{', '.join(LEGS)}, each {', '.join(leg_joint_labels(model, LEGS[0]))})"
                      f" on {ctx.port}: {exc}. Connect them (or "
                      "run `armlab emulate --robot quadruped`) and reopen the lesson; the gait "
                      "is shown without servos.")
    if backend.n != 12:
        backend.close()
        return None, f"the serial backend has {backend.n} joints; the quadruped needs 12"
    return backend, ""


class QuadrupedLesson(LessonBase):
    """The quadruped lesson on ``server`` (a :class:`armlab.app.lessons.LessonHandle`).

    Args:
        server: the viser server.
        ctx: robot and backend choice ("sim": simulated AX-12A; "serial": a port).
        pose_hz, plot_hz: scene and chart update rates.
    """

    def __init__(self, server: Surface, ctx: LessonContext, *,
                 pose_hz: float = 30.0, plot_hz: float = 10.0) -> None:
        super().__init__(server, ctx)
        self._table = Every(TABLE_S)  #: when the Servos tab is worked out again
        self._walk_from: float | None = None  #: loop time the present walk began
        self._walk_error: float | None = None  #: eq. 4.1 of the last walk, % (run_figures)
        #: the walk challenge's runs, from the start at rest (restart_challenge)
        self.challenge_runs = RestartRuns(self, "walk")
        model = _robot(ctx.robot)
        if not isinstance(model, Quadruped):
            raise ValueError(f"robot: {ctx.robot} is not a quadruped")
        self.model = model
        self.geom = QuadrupedGeometry()
        self.spec = GaitSpec()
        self.plan = plan_gait(self.spec, self.geom)
        self.loop: GaitLoop | RemoteGait
        #: the worker the shared robot walks in (a simulated classroom), or None
        self._worker = ctx.arm_process if ctx.arms is None and ctx.backend == "sim" else None
        if ctx.arms is None and self._worker is None:
            walker = Walker(self.plan)
            self.backend, self.servo_message = open_servos(model, ctx, walker.state().q)
            to_servo = getattr(getattr(self.backend, "map", None), "to_servo", None)
            self.loop = GaitLoop(
                walker, self.backend, period=0.02 if ctx.backend == "sim" else 0.03,
                realtime=ctx.realtime, speed=0.5, to_servo=to_servo)
        elif ctx.arms is None:  # a simulated classroom: the shared robot off the server's GIL
            assert self._worker is not None  # the branch above took the case without one
            self.backend, self.servo_message = None, ""
            self.loop = self._worker.add_quadruped(self.spec, speed=0.5, history_s=20.0)
        else:  # a student's own robot, kept by their seat (as it was left, on a reload)
            self.backend, self.servo_message = None, ""
            self.loop = ctx.arms.quadruped_for(self.spec, speed=0.5, history_s=20.0)
            self.spec = self.loop.spec
            self.plan = plan_gait(self.spec, self.geom)
        #: whether simulated or real servos walk (False: the gait alone)
        self.has_servos = self.backend is not None or not isinstance(self.loop, GaitLoop)
        with self.opening(self.backend.close if self.backend is not None else None):
            self._build_gui()
            self.scene = QuadrupedScene(server, model, root="/quadruped")
            self.scene.set_foot_paths(self.plan)
            self.scene.set_state(self.loop.state)
        self.loop.start()
        self.publish(pose=self._pose_frame, plots=self._plot_frame, pose_hz=pose_hz,
                     plot_hz=plot_hz, every=self._measure)

    # ================================================================== GUI

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.status = self._gui.add_status(try_this=TRY)
        warning = (warning_html("Servos not available", self.servo_message)
                   if self.servo_message else "")
        self.warning = self._gui.add(gui.add_html(warning, order=-79.0,
                                                  visible=bool(self.servo_message)))
        tabs = self._gui.add(gui.add_tab_group(order=-70.0))
        with tabs.add_tab("Walk", viser.Icon.WALK):
            self._build_walk_tab(gui)
        with tabs.add_tab("Gait", viser.Icon.ADJUSTMENTS):
            self._build_gait_tab(gui)
        with tabs.add_tab("Servos", viser.Icon.CPU):
            self.servo_table = gui.add_markdown("")
        with tabs.add_tab("Teach", viser.Icon.SCHOOL):
            gui.add_markdown(TEACH)
        with tabs.add_tab("Files", viser.Icon.FILE):  # Save run, Open run (replay), Export page
            self.runs = RunControls(self.server, gui, lesson=NAME, record=self.recording,
                                    rows=lambda: (self.loop, RUN_PERIOD_S),
                                    model=lambda: self.model, figures=self.run_figures,
                                    ghost_root="/quadruped_replay")
        with self._gui.chart_panel("Charts") as tab:
            self._build_plots(gui, tab)

    def _build_walk_tab(self, gui: viser.GuiApi) -> None:
        icons = {"forward": viser.Icon.ARROW_UP, "back": viser.Icon.ARROW_DOWN,
                 "left": viser.Icon.ARROW_BACK_UP, "right": viser.Icon.ARROW_FORWARD_UP}
        self.direction_buttons = {}
        for command in COMMANDS:
            b = gui.add_button(COMMAND_LABELS[command], icon=icons[command],
                               color="blue" if command == "forward" else None,
                               hint=_command_hint(command))
            b.on_click(lambda e, c=command: guarded(e, lambda: self.walk(c)))  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
            self.direction_buttons[command] = b
        self.stop_button = gui.add_button("Stop", icon=viser.Icon.PLAYER_STOP,
                                          hint="Walk on to the next moment all four feet "
                                               "stand, then stop there")
        self.stop_button.on_click(lambda e: guarded(e, self.stop))
        self.reset_button = gui.add_button("Reset", icon=viser.Icon.REFRESH,
                                           hint="Back to the start, standing; after an "
                                                "E-STOP: torque on again")
        self.reset_button.on_click(lambda e: guarded(e, self.reset))
        self.gait_dropdown = gui.add_dropdown(
            "Gait", GAITS, initial_value=self.spec.gait,
            hint="trot: diagonal legs together (the paper); crawl: one leg at a time, "
                 "statically stable")
        self.gait_dropdown.on_update(lambda e: guarded(
            e, lambda: self.set_gait(str(self.gait_dropdown.value)),
            undo=lambda: setattr(self.gait_dropdown, "value", self.spec.gait)))
        self.across = gui.add_checkbox("Walk across the floor", True,
                                       hint="Off: walk in place (the feet slide under a "
                                            "body held still)")
        self.across.on_update(lambda _e: self.set_in_place(not bool(self.across.value)))
        self.follow = gui.add_checkbox("Camera follows the robot", True,
                                       hint="Carry the view along as the robot walks")
        self.speed = guarded_slider(gui, "Gait speed (cycles/s)", name="gait speed",
                                    lo=SPEED_RANGE[0], hi=SPEED_RANGE[1], step=0.05,
                                    initial=self.loop.status.speed,
                                    apply=self.set_speed,
                                    hint="Gait cycles per second")

    def _build_gait_tab(self, gui: viser.GuiApi) -> None:
        gui.add_markdown("Sine pattern inputs (seed 003 Table 1.1). A change is taken at the "
                         "start of the next cycle.")
        self.gait_sliders: dict[str, GuardedNumber] = {}
        self._gait_lock = threading.RLock()
        p = self.spec.params
        for key, (label, lo, hi, step, field, k) in GAIT_SLIDERS.items():
            self.gait_sliders[key] = guarded_slider(
                gui, label, name=key, lo=lo, hi=hi, step=step,
                initial=float(getattr(p, field)) * k, lock=self._gait_lock,
                apply=lambda v, field=field, k=k: self.set_params(**{field: v / k}))  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
        self.reachable_md = gui.add_markdown(_plan_md(self.plan))

    def _build_plots(self, gui: viser.GuiApi, container: Any) -> None:
        self.charts = container
        self._leg = "RF"
        self._leg_stale = False
        self._plot_lock = threading.Lock()
        kw: dict[str, Any] = {"window_s": CHART_WINDOW_S, "points": CHART_POINTS, "height": 130}
        with container:
            self.leg_picker = gui.add_button_group("Leg", LEGS, order=1.0,
                                                   hint="The leg the joint charts show")
            self.margin_plot = LivePlot(gui, title="Static stability margin",
                                        y_label="cm", order=20.0, series=(
                                            SeriesSpec("margin", COLORS[4]),
                                            SeriesSpec("0", "#999999", (4, 4))),
                                        y_span=2.0, **kw)
            self.error_plot = LivePlot(gui, title="Eq. 4.1 |servo − commanded| / commanded",
                                       y_label="%", order=21.0, series=tuple(
                                           SeriesSpec(f"servo {j + 1}", COLORS[j + 3], dash(j))
                                           for j in range(3)), y_span=5.0, **kw)
        self._build_joint_charts()

        @self.leg_picker.on_click
        def _(_: viser.GuiEvent) -> None:
            leg = str(self.leg_picker.value)
            if leg in LEGS and leg != self._leg:
                self._leg = leg
                self._leg_stale = True  # rebuilt by the next chart frame

    def _build_joint_charts(self) -> None:
        """The three joint charts of the chosen leg (rebuilt, not retitled, on a change:
        see ``armlab.app.page.plots.LivePlot``)."""
        gui = self.server.gui
        names = leg_joint_labels(self.model, self._leg)  # θ1..θ3: the seed's eq. 3.1–3.9
        with self.charts:
            self.joint_plots = [
                LivePlot(gui, title=f"Leg {self._leg}: servo {j + 1} ({names[j]} θ{j + 1})",
                         y_label="angle (°)", order=10.0 + j, height=130, window_s=CHART_WINDOW_S,
                         points=CHART_POINTS, series=(
                             SeriesSpec("commanded", COLORS[0], (6, 4)),
                             SeriesSpec("servo", COLORS[2])), y_span=ANGLE_SPAN_DEG)
                for j in range(3)]

    # ================================================================== actions

    def _replan(self, spec: GaitSpec) -> GaitPlan:
        """Plan ``spec`` (ValueError if it cannot be walked) and make it the lesson's."""
        with self._lock:
            plan = plan_gait(spec, self.geom)
            self.spec, self.plan = spec, plan
        self.scene.set_foot_paths(plan)
        self.reachable_md.content = _plan_md(plan)
        return plan

    def walk(self, command: str) -> None:
        """Walk ``command`` ("forward", "back", "left", "right") with the current gait.

        Raises:
            ValueError: e.g. turning with the crawl.
        """
        self.challenge_runs.busy()
        plan = self._replan(replace(self.spec, command=command))
        t = self.loop.status.t
        self.loop.go(plan)
        if self.runs.going_on is None or not self.loop.status.walking:
            self.runs.begin_run(f"{self.spec.gait} {command}", t=t)  # (else: the same walk)
        self._note_plan("Walk")

    def stop(self) -> None:
        self.challenge_runs.cancel("Stop")
        self.runs.post(self.loop, StopWalking())

    def reset(self) -> None:
        self.challenge_runs.cancel("Reset")
        self.runs.post(self.loop, Reset())
        self.scene.clear_trails()

    def set_speed(self, speed: float) -> None:
        """Gait speed, cycles/s (ValueError outside 0.05..3)."""
        self.challenge_runs.busy()
        self.runs.post(self.loop, SetSpeed(speed))

    def _note_plan(self, kind: str) -> None:
        """Keep a walk or a new plan for the run file: its direction, gait and sine inputs
        (the plan itself is worked out from them)."""
        self.runs.note({"kind": kind, "command": self.spec.command, "gait": self.spec.gait,
                        **self.spec.params.named()}, t=self.loop.status.t)

    def set_gait(self, gait: str) -> None:
        """Trot or crawl (a turn becomes "forward" for the crawl, which walks straight)."""
        self.challenge_runs.busy()
        command = self.spec.command
        if gait == "crawl" and command in ("left", "right"):
            command = "forward"
        plan = self._replan(replace(self.spec, gait=gait, command=command))
        self.loop.set_plan(plan)
        self._note_plan("SetPlan")

    def set_params(self, **changes: float) -> None:
        """New sine-pattern inputs (SI); raises ValueError (refused) when unwalkable."""
        self.challenge_runs.busy()
        params = replace(self.spec.params, **changes)
        plan = self._replan(replace(self.spec, params=params))
        self.loop.set_plan(plan)
        self._note_plan("SetPlan")

    def set_in_place(self, in_place: bool) -> None:
        self.challenge_runs.busy()
        self.runs.post(self.loop, SetInPlace(bool(in_place)))
        self.scene.clear_trails()

    def estop(self) -> None:
        """Torque off now; never raises."""
        self.challenge_runs.cancel("E-STOP")
        self.loop.estop()

    # ================================================================== reading

    @property
    def params(self) -> SineParams:
        return self.spec.params

    def servo_error(self, window_s: float | None = 10.0) -> dict[str, object] | None:
        """Eq. 4.1 from the servos' feedback over the last ``window_s`` s of walking."""
        return self.loop.angle_error(window_s)

    # ================================================================== publishing

    def _pose_frame(self) -> None:
        state = self.loop.state
        snap = self.loop.snapshot(0.1)
        q = snap["q"][-1] if len(snap["t"]) else None
        self.scene.set_state(state, q)
        if self.follow.value:
            self.scene.follow(state.body[:2])

    def _plot_frame(self, force: bool) -> None:
        snap = self.loop.snapshot(self.margin_plot.window_s + 0.5)
        t = snap["t"]
        with self._plot_lock:
            if self._leg_stale:
                self._leg_stale = False
                rebuild_plots(self.joint_plots, self._build_joint_charts)
                force = True
            leg = self._leg
        if len(t) >= 2:
            i = LEGS.index(leg)
            # the five charts share a window and a grid: the record's bins found once
            index = decimation(t, window_s=CHART_WINDOW_S, points=CHART_POINTS)
            for j, plot in enumerate(self.joint_plots):
                plot.update(t, (deg(snap["q_cmd"][:, 3 * i + j]), deg(snap["q"][:, 3 * i + j])),
                            force=force, index=index)
            self.margin_plot.update(t, (snap["margin"] * 100.0, np.zeros(len(t))), force=force,
                                    index=index)
            self.error_plot.update(t, tuple(self._error_series(snap)), force=force,
                                   index=index)
        self._update_status(self.loop.status)
        if self._table.due(force=force):  # 10 s of eq. 4.1 and tilts
            self._update_servo_table()

    def _error_series(self, snap: dict[str, np.ndarray]) -> list[np.ndarray]:
        """Per sample, |eq. 4.1| averaged over the four legs for servo 1, 2, 3 (NaN when not
        walking or without servos)."""
        ok, c, a = self.loop.servo_angles_deg(snap)
        out = np.full((len(ok), 3), np.nan)
        if ok.any():
            out[ok] = np.abs(angle_error_pct(c, a)).reshape(-1, 4, 3).mean(axis=1)
        return [out[:, j] for j in range(3)]

    def recording(self, rows: dict[str, np.ndarray] | None = None) -> Recording:
        """The robot's record for a run file: the goals sent as "q_cmd", the angles the
        servos read one period later as "q" (gait order, legs RF, LF, RH, LH); the gait,
        its sine inputs (m, °) and speed as parameters. After a servo fault the run is the
        last stretch the servos were read. Without servos nothing was read: "q" is then the
        goals (``extra["q_is"]`` says so). ``rows``: a run's rows (the loop's snapshot
        layout) instead of the whole record."""
        snap = self.loop.snapshot() if rows is None else rows
        extra: dict[str, object] = {}
        read = np.isfinite(snap["q"]).all(axis=1)
        if read.any():
            last = int(np.flatnonzero(read)[-1])
            unread = np.flatnonzero(~read[:last])
            first = int(unread[-1]) + 1 if len(unread) else 0
            snap = {k: v[first:last + 1] for k, v in snap.items()}
        else:
            snap = {**snap, "q": snap["q_cmd"]}
            extra["q_is"] = "the goals sent (no servos: no angle was read)"
        st = self.loop.status
        params = {"gait": self.spec.gait, "command": self.spec.command,
                  **self.spec.params.named(), "speed": st.speed,
                  "walk_in_place": not bool(self.across.value)}
        return Recording(model=self.model, robot=self.model.name,
                         joint_names=gait_joint_names(self.model), snapshot=snap,
                         params=params, extra=extra)

    def page_only_buttons(self) -> tuple[viser.GuiButtonHandle, ...]:
        """Save run and Export page: each answers the pressing page."""
        return self.runs.page_only_buttons()

    def run_challenge(self, challenge: Any) -> str:
        """Start the walk challenge's run: standing at rest at the start again, a walk
        forward stopped after ``walk_s`` of loop time, eq. 4.1 over a fixed window
        (:mod:`armlab.app.lessons.restart_challenge`)."""
        return self.challenge_runs.start(challenge)

    def run_tags(self) -> dict[str, str | None]:
        """The key of the challenge whose run measured eq. 4.1 (None: a walk of the
        student's own)."""
        return self.challenge_runs.tags()

    def challenge_results(self) -> list:
        """The challenge runs measured: (number, figures, tags), newest last."""
        return list(self.challenge_runs.results)

    def run_figures(self) -> dict[str, float | None]:
        """Eq. 4.1 of the last walk (once it stopped), from the servos' feedback
        (:data:`FIGURES`)."""
        return LESSON.figures_of(eq41_error_pct=self._walk_error)

    def _watch_walk(self, st: GaitStatus) -> None:
        """When a walk ends, work out its eq. 4.1 error (its last ``history_s`` at most)."""
        if st.walking:
            if self._walk_from is None:
                self._walk_from = st.t
            return
        if self._walk_from is None:
            return
        began, self._walk_from = self._walk_from, None
        err = self.loop.angle_error(st.t - began + 0.5)
        self._walk_error = None if err is None else float(err["mean_pct"])
        self.challenge_runs.untag()  # (a walk of the student's own)
        if self.runs.going_on is not None:  # the walk's run is over, with its own figure
            self.runs.finish_run({"eq41_error_pct": self._walk_error}, t=st.t)

    def _measure(self) -> None:
        """At each publisher tick, a page open or not: keep the walk's rows, and measure a
        walk once it is over (its run's figure)."""
        self.runs.tick()
        if not self.challenge_runs.measure():
            self._watch_walk(self.loop.status)

    def _update_status(self, st: GaitStatus) -> None:
        state = self.loop.state
        if st.fault:
            head, color = f"servos stopped: {st.fault} (press Reset)", "#b00020"
        elif self.has_servos and not st.torque_on:
            head, color = "E-STOPPED: torque off (press Reset)", "#b00020"
        elif st.standing_up:
            head, color = "standing up", "#555"
        elif st.walking:
            what = "stopping" if st.stopping else f"walking {st.command}"
            head, color = f"{what}: {st.gait} at {st.speed:g} cycles/s", "#1f5eea"
        else:
            head, color = "standing: press a direction", "#2e7d32"
        if not self.has_servos:
            servos = "no servos (gait only)"
        elif self.ctx.arms is not None:
            servos = "12 simulated AX-12A (your own robot)"
        elif self._worker is not None:
            servos = "12 simulated AX-12A (in the class's simulation process)"
        elif self.ctx.backend == "sim":
            servos = "12 simulated AX-12A"
        else:
            servos = f"12 AX-12A on {self.ctx.port}"
        x, y, _, yaw = state.body
        m = state.margin * 100.0
        legs_down = int(state.stance.sum())
        verdict = ("statically stable" if m > 0 else
                   "on a line: not statically stable" if legs_down == 2 else "would tip")
        mcolor = "#2e7d32" if m > 0 else "#b00020"
        set_content(self.status, status_html(
            head, color, f"{servos} · t = {st.t:.1f} s · body ({x * 100:.1f}, {y * 100:.1f}) "
            f"cm, yaw {deg(yaw):.0f}° · {legs_down} feet down",
            extra=f"<div style='font-size:0.85em'>margin <b style='color:{mcolor}'>{m:+.1f} cm"
                  f"</b> ({verdict})</div>"))

    def _update_servo_table(self) -> None:
        tilts = walking_tilts_deg(self.model, self.loop.snapshot(10.0))
        set_content(self.servo_table, servo_markdown(
            self.servo_error(10.0), has_servos=self.has_servos, where=self.ctx.backend,
            tilts=tilts))

    # ================================================================== lifetime

    def close(self) -> None:
        """Stop the publisher and the loop (torque off), close the servos, remove everything."""
        if self.mark_closed():
            free = None if self._worker is None else partial(self._worker.free_member, self.loop)  # type: ignore[arg-type]  # with a worker, the loop is the worker's RemoteGait
            close_in_turn(self.publisher.close, partial(self.loop.shutdown, torque_off=True),
                          free, self.runs.remove,
                          self.backend.close if self.backend is not None else None,
                          self.scene.remove, self._gui.remove_all)


def servo_markdown(err: dict[str, Any] | None, *, has_servos: bool, where: str,
                   tilts: np.ndarray | None = None) -> str:
    """The eq. 4.1 table (servo tab), and the body tilt the servos' angles imply."""
    head = ("**Commanded vs servo angle, seed 003 eq. 4.1**: %Error = (servo angle − "
            "computed angle) / computed angle × 100, angles as the servo counts them (IK "
            "angle + its 150° set point); the servo's feedback is read one period after the "
            f"goal is sent. Paper: **{PAPER_ERROR_PCT} %** (mean), largest on servo 2.")
    if not has_servos:
        return head + "\n\n*No servos: nothing to measure.*"
    if err is None:
        return head + "\n\n*Walk to measure (last 10 s of walking).*"
    per_servo = err["per_servo_pct"]
    per_joint = np.asarray(err["per_joint_pct"]).reshape(4, 3)
    rows = ["| leg | servo 1 | servo 2 | servo 3 |", "|---|---|---|---|"]
    for i, leg in enumerate(LEGS):
        rows.append(f"| {leg} | " + " | ".join(f"{v:.2f} %" for v in per_joint[i]) + " |")
    rows.append("| **mean** | " + " | ".join(f"**{v:.2f} %**" for v in per_servo) + " |")
    src = "simulated AX-12A (legs loaded by the body's weight)" if where == "sim" else "serial"
    tilt = ""
    if tilts is not None and len(tilts):
        tilt = (f"\n\n**Body tilt** the servos' angles imply on flat ground: mean "
                f"**{float(np.mean(tilts)):.1f}°**, max {float(np.max(tilts)):.1f}° (paper: "
                "3.6–5.7°): the body leans onto a swing foot, less as the loaded legs give way.")
    return "\n".join([head, "",
                      f"Lab, last 10 s ({err['samples']} samples, {src}): "
                      f"mean **{err['mean_pct']:.3f} %**", "", *rows]) + tilt


TEACH = """\
**Sine pattern** (seed 003 Table 1.1): each foot moves ±A/2 along the heading α while it
stands (z = −D), and swings forward lifted by C sin(ω − 90°). Joint angles come from the leg
IK θ1 = atan2(x, y), θ3 = atan2(√(1 − A²), A), θ2 = atan2(C, D) (eq. 3.1-3.9).

**Trot**: the diagonal legs RF+LH and LF+RH share a phase. Only two feet stand at a time:
the support "polygon" is the diagonal line between them, and the centre of mass is at best
*on* it. The static margin is never positive: a trot does not fall only because each
half-step is short (dynamic balance).

**Crawl** (the paper's suggested next step, centre-of-gravity control): one leg swings at
a time; before each swing the body shifts so that the centre of mass lies at least 2 cm
inside the triangle of the three feet that stay down. The margin stays positive over the
whole cycle, at the price of half the speed (A per cycle against 2A).

**Turning**: direction index 1 on both right legs reverses their step and the robot turns
right (the seed); on both left legs it turns left. The stance feet slip a little while
turning (watch the trails).

**Servos**: the chart and the table compare the angle sent with the angle the servo
reports (eq. 4.1). Servo 2 carries the body: its error is the largest, as the paper found.
A fast crawl asks the knees for more than an AX-12A's 6 rad/s: lower the gait speed.
"""


def _plan_md(plan: GaitPlan) -> str:
    adv = plan.advance
    m = plan.margins
    return (f"Per cycle: advance {math.hypot(adv[0], adv[1]) * 100:.1f} cm, turn "
            f"{deg(adv[2]):+.0f}°; stability margin {m.min() * 100:+.1f} … "
            f"{m.max() * 100:+.1f} cm; stance feet slip {plan.slip * 1000:.1f} mm.")


def _command_hint(command: str) -> str:
    return {"forward": "Walk forward (direction index 0 on every leg)",
            "back": "Walk backward (every step reversed)",
            "left": "Turn left on the spot (direction index 1 on both left legs; trot only)",
            "right": "Turn right on the spot (direction index 1 on both right legs, as in the "
                     "seed; trot only)"}[command]


#: This lesson, as the lab lists it (:data:`armlab.app.lessons.catalog.LESSONS`).
LESSON = Lesson(name=NAME, title=TITLE, help=HELP, first_step=TRY, robots=ROBOTS, build=build,
                order=ORDER, private=PRIVATE, figures=FIGURES, overview=OVERVIEW)

__all__ = ["QuadrupedLesson", "build", "open_servos", "servo_markdown", "NAME", "TITLE",
           "HELP", "ROBOTS", "LESSON"]
