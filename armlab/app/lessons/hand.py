"""Lesson: the thesis's three-finger hand and a compliant grasp (thesis §2.4, §3.1.1).

Three fingers, each pulled by a 6 V DC gearmotor through a tendon against a
return spring; the only sensors are the motor currents, and tau = K_t·I
(eq. 2.29). The student closes the hand on an object of chosen size and
stiffness with a grip-force limit F and watches the currents and finger forces:
the hand stops closing when the current says it holds the object with F.

Data flow (one writer per piece of state): a :class:`armlab.control.grip_loop.GripLoop`
thread steps the simulated hand (:mod:`armlab.hardware.sim.hand_plant`) and the controller
(:mod:`armlab.control.grip`) every millisecond; buttons and sliders post commands the
loop runs at its next period; a :class:`armlab.app.page.publisher.Publisher` reads the
loop's record and updates the scene (30 Hz) and charts (10 Hz). The Files folder
(:mod:`armlab.app.lessons.run_files`) saves the grasp as a run file (finger angles, and
the voltages, currents and forces as the hand's own signals), replays one on an orange
hand beside the live one, and exports the HTML page.

Runs (what Save run saves, kept apart from the loop's 10 s record): **Close** begins the
run "grasp", over once the grasp settled (:meth:`HandLesson.run_figures`: its steady and
peak force, whether it held, its time to grasp and final current, as the page shows
them); **Open** begins the run "open", over once every finger is idle (it measures
nothing). Each keeps a settling tail; a new Close or Open lets the last run go.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from armlab.app.lessons import Lesson, LessonContext
from armlab.app.lessons._common import (
    Every,
    LessonBase,
    close_in_turn,
    guarded,
    set_content,
    status_html,
)
from armlab.app.lessons.hand_scene import HandScene
from armlab.app.lessons.replay_view import HAND_ROBOT, hand_joint_names
from armlab.app.lessons.restart_challenge import RestartRuns
from armlab.app.lessons.run_files import Recording, RunControls
from armlab.app.page.inputs import guarded_slider
from armlab.app.page.plots import COLORS, LivePlot, SeriesSpec, dash
from armlab.app.page.surface import Surface
from armlab.control.grip import GripController, GripModel, GripParams
from armlab.control.grip_loop import (
    COLUMNS,
    CloseHand,
    GripLoop,
    GripStatus,
    MotorsOff,
    OpenHand,
    SetGripParams,
    SetObject,
)
from armlab.hardware.sim.hand_plant import MAX_STIFFNESS, GraspObject, check_object, make_hand

if TYPE_CHECKING:
    from armlab.app.workers.remote_hand import RemoteHand

NAME = "hand"
TITLE = "Hand grasp"
HELP = ("The receptionist robot's three-finger hand: each finger is pulled by a 6 V DC "
        "gearmotor whose current gives its torque (τ = K_t·I, eq. 2.29). Close it on an "
        "object of chosen size and stiffness: it stops closing when the current says each "
        "finger holds the object with the force limit F, a compliant grasp. Watch the motor "
        "currents and the finger forces.")
#: The first action, shown under the status line.
TRY = ("Press **Close (grasp)**: each finger stops when its current says it holds the "
       "object with F.")
ROBOTS = ("receptionist_arm",)
ORDER = 30
#: a student's page can hold a private copy: their own hand in the class
#: (``ctx.arms.hand_for``: :mod:`armlab.app.workers.class_hands` in the class's worker process)
PRIVATE = True
#: The figures of its last settled grasp: its steady and peak fingertip force (N), and
#: 1.0 when every finger held at 90 % of its limit, else 0.
FIGURES = ("grasp_force_n", "grasp_peak_n", "grasp_held")
#: What a class overview shows of them, and its columns' heads.
OVERVIEW = {"grasp_force_n": "grip N", "grasp_peak_n": "peak N", "grasp_held": "held"}

STIFFNESS_PRESETS = {"soft": 200.0, "medium": 1000.0, "hard": 5000.0}
DEFAULT_FORCE = 0.8  #: N
CURRENT_SPAN_A = 0.2  #: smallest span of the current chart, A
FORCE_SPAN_N = 1.0  #: smallest span of the force chart, N
DEFAULT_SIZE_CM = 6.0
DEFAULT_STIFFNESS = 1000.0
WINDOW_S = 6.0  #: seconds shown on the charts
FINGER_COLORS = (COLORS[0], COLORS[1], COLORS[4])
ZERO_RGB = "#bbbbbb"
FIGURES_S = 0.5  #: s between two workings-out of the last grasp's figures
#: The record's columns a run file keeps as the hand's own signals (name -> unit): the
#: finger angle ("angle") is the run's "q"
RUN_SIGNALS = {name: unit for name, unit in COLUMNS.items() if name != "angle"}
SETTLED_S = 0.5  #: s a grasp holds past its time to grasp before its figures are final
#: The labels of the hand's runs (Save run): a close, an open.
GRASP_RUN, OPEN_RUN = "grasp", "open"

EXPLAIN = """\
**How the hand knows its grip.** No force sensor: the current *I* of each motor
gives its torque τ = K_t·I (eq. 2.29, K_t = 8.83 mN·m/A from the datasheet:
2 oz·in at 1.6 A stall). The tendon tension is τ / r_spool; at the finger's
hinge it balances the return spring and the fingertip force:
F = (T·r_tendon − τ_spring) / (L cos φ). The finger angle φ comes from the
motor's back-EMF, ω = (V − R·I)/K_e.

**The grasp.** Approach at a set fingertip speed with the current capped at a
light touch; once a finger stops, the force cap rises smoothly to F and the
current is held there. The hand never squeezes harder than F, whatever the
object. Try a hard object and a fast approach: the first touch is an impact.
"""


def build(server: Surface, ctx: LessonContext) -> HandLesson:
    """Open the lesson on ``server`` (see :mod:`armlab.app.lessons`)."""
    return HandLesson(server, ctx)


class HandLesson(LessonBase):
    """The hand lesson on ``server`` (a :class:`armlab.app.lessons.LessonHandle`).

    Args:
        server: the viser server.
        ctx: lesson context (only ``realtime`` matters: the hand is always simulated).
        pose_hz, plot_hz: scene and chart update rates.

    Attributes:
        loop: the control loop (read its ``status``, ``params``, ``snapshot()``,
            ``last_grasp()``): the lesson's own, or a student's hand in the class
            (:class:`armlab.app.workers.remote_hand.RemoteHand`, with ``ctx.arms``).
    """

    def __init__(self, server: Surface, ctx: LessonContext, *,
                 pose_hz: float = 30.0, plot_hz: float = 10.0) -> None:
        super().__init__(server, ctx)
        self._grasp: tuple[float | None, dict] | None = None  #: (closed_at, figures)
        #: the last grasp once it settled (every finger holding or closed on nothing):
        #: (closed_at, its figures, held); what run_figures reports
        self._settled: tuple[float | None, dict, bool] | None = None
        #: the grasp's figures read the whole record since the close: not every chart frame
        self._figures = Every(FIGURES_S)
        #: a grasp that goes on is measured at this pace with no page open too (its run)
        self._measuring = Every(FIGURES_S)
        #: the grasp challenge's runs, from the hand open at rest (restart_challenge)
        self.challenge_runs = RestartRuns(self, "grasp")
        self.obj = GraspObject(size=DEFAULT_SIZE_CM / 100.0, stiffness=DEFAULT_STIFFNESS)
        params = GripParams(force_limit=DEFAULT_FORCE)
        history_s = WINDOW_S + 4.0
        self.loop: GripLoop | RemoteHand
        if ctx.arms is None:
            plant = make_hand(size=self.obj.size, stiffness=self.obj.stiffness)
            self.loop = GripLoop(plant, GripController(GripModel.of(plant), params),
                                 realtime=ctx.realtime, history_s=history_s)
        else:  # a student's own hand, kept by their seat (as it was, on a reload)
            self.loop = ctx.arms.hand_for(self.obj, params, history_s=history_s)
            self.obj = self.loop.obj or self.obj
        self.model = self.loop.model
        self.scene = HandScene(server, self.model.finger, root="/hand")
        with self.opening(self.scene.remove):
            self.scene.set_object(self.obj.size, self.obj.stiffness)
            self._build_gui()
        self.loop.start()
        self.publish(pose=self._pose_frame, plots=self._plot_frame, pose_hz=pose_hz,
                     plot_hz=plot_hz, every=self._measure)

    # ================================================================== GUI

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.status = self._gui.add_status(try_this=TRY)
        folder = self._gui.add(gui.add_folder("Hand", order=-70.0))
        with folder:
            self.close_button = gui.add_button(
                "Close (grasp)", color="green", icon=viser.Icon.HAND_GRAB,
                hint="Close the fingers until each holds the object with F")
            self.open_button = gui.add_button(
                "Open", icon=viser.Icon.HAND_STOP,
                hint="Unwind the tendons; the springs open the fingers")
            self.close_button.on_click(lambda e: guarded(e, self.close_hand))
            self.open_button.on_click(lambda e: guarded(e, self.open_hand))
            fmax = math.floor(self.model.max_force() * 20.0) / 20.0
            self.force = guarded_slider(
                gui, "Force limit F (N)", name="force limit", lo=0.05, hi=fmax, step=0.05,
                initial=self.loop.params.force_limit, apply=self.set_force_limit,
                hint="Grip force per finger; the controller reads it from the motor current")
            self.speed = guarded_slider(
                gui, "Approach speed (cm/s)", name="approach speed", lo=0.5, hi=10.0,
                step=0.5, initial=self.loop.params.approach_speed * 100.0,
                apply=self.set_approach_speed,
                hint="Fingertip speed while closing: faster means a harder first touch")
            self.force_slider = self.force.handle
        objf = self._gui.add(gui.add_folder("Object", order=-60.0))
        with objf:
            g = self.model.finger
            lo = math.ceil(g.min_size * 200.0) / 2.0  # cm, half-centimetre steps
            hi = math.floor(g.max_size * 200.0 - 1.0) / 2.0
            self.size = guarded_slider(
                gui, "Size (cm)", name="size", lo=1.0, hi=hi, step=0.5,
                initial=self.obj.size * 100.0, apply=lambda v: self.set_object(size_cm=v),
                hint=f"Diameter of the cylinder; under {lo:g} cm the fingers close on nothing")
            self.stiffness = guarded_slider(
                gui, "Stiffness (N/m)", name="stiffness", lo=100.0,
                hi=min(20000.0, MAX_STIFFNESS), step=100.0, initial=self.obj.stiffness,
                apply=lambda v: self.set_object(stiffness=v),
                hint="Contact stiffness of object and pad")
            self.size_slider = self.size.handle
            self.presets = gui.add_button_group("Preset", tuple(STIFFNESS_PRESETS))
            self.presets.on_click(lambda e: self.stiffness.set(
                STIFFNESS_PRESETS[str(self.presets.value)]))
        self.figures = self._gui.add(gui.add_markdown("", order=-50.0))
        explain = self._gui.add(gui.add_folder("How it works", order=-40.0,
                                               expand_by_default=False))
        with explain:
            gui.add_markdown(EXPLAIN)
        files = self._gui.add(gui.add_folder("Files", order=-30.0, expand_by_default=False))
        with files:  # Save run, Open run (a ghost hand replays it), Export page
            self.runs = RunControls(self.server, gui, lesson=NAME, record=self.recording,
                                    rows=lambda: (self.loop, self.loop.dt),
                                    model=lambda: self.model.finger,
                                    figures=self.run_figures, ghost_root="/hand_replay")
        with self._gui.chart_panel("Current and force") as tab, tab:
            kw: dict[str, Any] = {"window_s": WINDOW_S, "points": 200}
            # each chart has a zero line: it keeps 0 in view, so a held force is a flat
            # line at F rather than an auto-zoomed band around it; its axis spans at least
            # CURRENT_SPAN_A / FORCE_SPAN_N (armlab.app.page.plots.fit_range)
            self.current_plot = LivePlot(gui, title="Motor current (measured)", y_label="A",
                                         series=(*(SeriesSpec(f"finger {i + 1}", c, dash(i))
                                                   for i, c in enumerate(FINGER_COLORS)),
                                                 SeriesSpec("0", ZERO_RGB, width=1.0)),
                                         y_span=CURRENT_SPAN_A, **kw)
            self.force_plot = LivePlot(
                gui, title="Fingertip force", y_label="N", y_span=FORCE_SPAN_N, series=(
                    *(SeriesSpec(f"finger {i + 1}", c, dash(i))
                      for i, c in enumerate(FINGER_COLORS)),
                    SeriesSpec("limit F", COLORS[3], (6, 4)),
                    SeriesSpec("from current (finger 1)", COLORS[2], (2, 3), width=3.5),
                    SeriesSpec("0", ZERO_RGB, width=1.0)), **kw)

    # ================================================================== actions

    def close_hand(self) -> None:
        """Grasp: close with the force limit (the run "grasp")."""
        self.challenge_runs.busy()
        self.runs.post(self.loop, CloseHand(), run=GRASP_RUN)

    def open_hand(self) -> None:
        """Release the object (the run "open")."""
        self.challenge_runs.busy()
        self.runs.post(self.loop, OpenHand(), run=OPEN_RUN)

    def estop(self) -> None:
        """Motors off (the springs open the hand); never raises."""
        self.challenge_runs.cancel("E-STOP")
        self.loop.post(MotorsOff())
        self.runs.note(MotorsOff(), t=self.loop.status.t)

    def set_force_limit(self, force: float) -> None:
        """New grip-force limit F, N (applied at the loop's next period). ValueError to refuse."""
        self.challenge_runs.busy()
        replace(self.loop.params, force_limit=force)  # validates
        if force > self.model.max_force():
            raise ValueError(f"force limit must be <= {self.model.max_force():.2f} N")
        self.runs.post(self.loop, SetGripParams(force_limit=force))

    def set_approach_speed(self, cm_per_s: float) -> None:
        """Fingertip approach speed, cm/s."""
        self.challenge_runs.busy()
        v = cm_per_s / 100.0
        replace(self.loop.params, approach_speed=v)  # validates
        self.runs.post(self.loop, SetGripParams(approach_speed=v))

    def set_object(self, *, size_cm: float | None = None,
                   stiffness: float | None = None) -> None:
        """Change the object (ValueError to refuse).

        The size only changes with the hand open: a bigger object appearing
        inside closed fingers would be an impossible collision.
        """
        self.challenge_runs.busy()
        with self._lock:
            size = self.obj.size if size_cm is None else size_cm / 100.0
            k = self.obj.stiffness if stiffness is None else stiffness
            obj = check_object(replace(self.obj, size=size, stiffness=k), self.model.finger)
            if size != self.obj.size and any(m != "idle" for m in self.loop.status.modes):
                raise ValueError("open the hand before changing the object's size")
            self.obj = obj
            self.runs.post(self.loop, SetObject(obj))
            self.scene.set_object(obj.size, obj.stiffness)

    # ================================================================== publishing

    def _pose_frame(self) -> None:
        snap = self.loop.snapshot(0.05)
        if len(snap["t"]) == 0:
            return
        self.scene.set_state(snap["angle"][-1], snap["force"][-1],
                             self.loop.params.force_limit)

    def _plot_frame(self, force: bool) -> None:
        snap = self.loop.snapshot(WINDOW_S + 0.5)
        t = snap["t"]
        if len(t) < 2:
            return
        limit = self.loop.params.force_limit
        zero = np.zeros(len(t))
        self.current_plot.update(t, (*(snap["current"][:, i] for i in range(3)), zero),
                                 force=force)
        self.force_plot.update(t, (*(snap["force"][:, i] for i in range(3)),
                                   np.full(len(t), limit), snap["estimate"][:, 0], zero),
                               force=force)
        self._update_status(snap, limit, figures=self._figures.due(force=force))

    def _update_status(self, snap: dict[str, np.ndarray], limit: float, *,
                       figures: bool = True) -> None:
        st = self.loop.status
        modes = st.modes
        word = modes[0] if len(set(modes)) == 1 else ", ".join(modes)
        f, cur = snap["force"][-1], snap["current"][-1]
        color = {"holding": "#2e7d32", "empty": "#a15c00"}.get(modes[0], "#1f5eea")
        if st.fault:
            word, color = st.fault, "#b00020"
        set_content(self.status, status_html(
            word, color, f"simulated hand · t = {st.t:.1f} s · force "
            f"{', '.join(f'{x:.2f}' for x in f)} N · current "
            f"{', '.join(f'{x:.2f}' for x in cur)} A"))
        self.scene.set_label("closed on nothing" if modes[0] == "empty" else " ")
        if not figures:
            return
        fig = self._measure_grasp(st, limit)
        text = ""
        if fig is not None:
            grasped = fig["time_to_grasp_s"]
            done = self._settled is not None and self._settled[0] == st.closed_at
            # a steady force only once the grasp has settled (the figures then kept); before,
            # the force now, as the status line and the chart show it
            force = (f"steady {fig['steady_force_N']:.3f} N" if done else
                     f"closing: force now {float(np.mean(f)):.3f} N (steady once settled)")
            text = (f"**Last grasp** (F = {limit:g} N): {force} · "
                    f"peak {fig['peak_force_N']:.3f} N · "
                    + (f"held after {grasped:.2f} s" if grasped is not None else "not held yet")
                    + f" · current {fig['final_current_A']:.3f} A")
        set_content(self.figures, text)

    def _measure_grasp(self, st: GripStatus, limit: float) -> dict | None:
        """The last grasp's figures now (None: no close yet), kept once it settled."""
        if self.challenge_runs.pending is not None:  # measured over the run's own window
            return None
        if self._settled is not None and self._settled[0] == st.closed_at:
            return self._settled[1]  # (the figures kept: the page shows what is judged)
        fig = self.loop.last_grasp(limit)
        if fig is not None:
            self._grasp = (st.closed_at, fig)
        elif self._grasp is not None and self._grasp[0] == st.closed_at:
            fig = self._grasp[1]  # the close has left the record: keep its figures
        self._settle(st, fig)
        return fig

    def _measure(self) -> None:
        """At each publisher tick, a page open or not: keep the run's rows; measure a
        grasp that goes on (its run is over, with its figures, once it settled); an open
        is over once every finger is idle."""
        self.runs.tick()
        if self.challenge_runs.measure():
            return
        going = self.runs.going_on
        if going == GRASP_RUN and self._measuring.due():
            self._measure_grasp(self.loop.status, self.loop.params.force_limit)
        elif going == OPEN_RUN:
            st = self.loop.status
            if set(st.modes) == {"idle"}:
                self.runs.finish_run({}, t=st.t)

    def _settle(self, st: GripStatus, fig: dict | None) -> None:
        """Keep the grasp's figures once it has settled: every finger holding for
        :data:`SETTLED_S` past the time to grasp, or none closing any more (some closed
        on nothing: not held)."""
        if fig is None or st.closed_at is None:
            return
        if self._settled is not None and self._settled[0] == st.closed_at:
            return  # this grasp's figures are kept already
        modes = set(st.modes)
        held = modes == {"holding"}
        grasped = fig["time_to_grasp_s"]
        if held and grasped is not None and st.t - st.closed_at >= grasped + SETTLED_S:
            self._settled = (st.closed_at, fig, True)
        elif not held and modes <= {"holding", "empty"}:
            self._settled = (st.closed_at, fig, False)
        else:
            return
        self.challenge_runs.untag()  # (a grasp of the student's own)
        if self.runs.going_on == GRASP_RUN:  # the grasp's run is over: its own figures
            self.runs.finish_run(self.grasp_figures(), t=st.t)

    def grasp_figures(self) -> dict[str, float | None]:
        """The last settled grasp's figures as its run file keeps them (those the page
        shows: steady and peak force, held, time to grasp, final current); {} before."""
        settled = self._settled
        if settled is None:
            return {}
        _, fig, held = settled
        return {"grasp_force_n": fig["steady_force_N"], "grasp_peak_n": fig["peak_force_N"],
                "grasp_held": 1.0 if held else 0.0,
                "time_to_grasp_s": fig["time_to_grasp_s"],
                "final_current_a": fig["final_current_A"]}

    def page_only_buttons(self) -> tuple[viser.GuiButtonHandle, ...]:
        """Save run and Export page: each answers the pressing page."""
        return self.runs.page_only_buttons()

    def run_challenge(self, challenge: Any) -> str:
        """Start the grasp challenge's run: the hand open at rest again, then a close, its
        figures over a fixed window (:mod:`armlab.app.lessons.restart_challenge`)."""
        return self.challenge_runs.start(challenge)

    def run_tags(self) -> dict[str, str | None]:
        """Per grasp figure, the key of the challenge whose run measured it (None: a
        grasp of the student's own)."""
        return self.challenge_runs.tags()

    def challenge_results(self) -> list:
        """The challenge runs measured: (number, figures, tags), newest last."""
        return list(self.challenge_runs.results)

    def run_figures(self) -> dict[str, float | None]:
        """The last settled grasp's steady and peak force, and whether it held
        (:data:`FIGURES`)."""
        settled = self._settled
        if settled is None:
            return LESSON.figures_of()
        _, fig, held = settled
        return LESSON.figures_of(grasp_force_n=fig["steady_force_N"],
                       grasp_peak_n=fig["peak_force_N"], grasp_held=1.0 if held else 0.0)

    def recording(self, rows: dict[str, np.ndarray] | None = None) -> Recording:
        """The hand's record for a run file: the finger angles as "q", the motor voltages,
        currents, true and estimated fingertip forces and the force cap as the hand's own
        signals (:data:`RUN_SIGNALS`); the grasp's settings and the object as parameters.
        ``rows``: a run's rows (the loop's snapshot layout) instead of the whole record."""
        snap = self.loop.snapshot() if rows is None else rows
        obj = self.obj
        params = {**dataclasses.asdict(self.loop.params), "object_size_m": obj.size,
                  "object_stiffness_n_per_m": obj.stiffness, "period": self.loop.dt}
        params = {k: v for k, v in params.items()  # (no object: its size is not kept)
                  if isinstance(v, str) or (isinstance(v, int | float) and math.isfinite(v))}
        return Recording(model=self.model.finger, robot=HAND_ROBOT,
                         joint_names=hand_joint_names(self.model.finger),
                         snapshot={**snap, "q": snap["angle"]}, params=params,
                         lesson_signals=RUN_SIGNALS)

    # ================================================================== lifetime

    def close(self) -> None:
        """Stop the publisher and the loop, remove scene and GUI."""
        if self.mark_closed():
            close_in_turn(self.publisher.close, self.loop.shutdown, self.runs.remove,
                          self.scene.remove, self._gui.remove_all)


#: This lesson, as the lab lists it (:data:`armlab.app.lessons.catalog.LESSONS`).
LESSON = Lesson(name=NAME, title=TITLE, help=HELP, first_step=TRY, robots=ROBOTS, build=build,
                order=ORDER, private=PRIVATE, figures=FIGURES, overview=OVERVIEW)

__all__ = ["HandLesson", "build", "NAME", "TITLE", "HELP", "ROBOTS", "LESSON"]
