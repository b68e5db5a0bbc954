"""Lesson: tune the thesis's compliance controller on a live 3D arm (thesis 000, ch. 2–4).

What a teacher opens in front of a class: the receptionist robot's arm, its
gains and virtual environment on sliders, live charts, a hand that pushes the
arm. Behind it a :class:`armlab.control.loop.ControlLoop` runs the controller on the
simulated arm (default) or on Dynamixel servos (``--backend serial``).

Data flow (one writer per piece of state): sliders build a validated
:class:`Params` that the loop swaps in at its next period; buttons post
commands the loop applies at its next period; a :class:`Publisher` thread reads
``loop.recorder`` and ``loop.status`` and updates the scene at 30 Hz and the
charts at 10 Hz inside ``server.atomic()``. UI callbacks never touch the servos.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import partial

import numpy as np
import viser

from armlab.app.lessons import Lesson, LessonContext
from armlab.app.lessons._common import (
    LessonBase,
    close_in_turn,
    esc,
    guarded,
    joint_label,
    send_download,
    set_content,
    status_html,
)
from armlab.app.lessons._loop_state import (
    STOPPED_COLOR,
    check_running,
    link_note,
    post_reset,
    stopped_state,
)
from armlab.app.lessons._servo_arm import open_arm, shut_arm
from armlab.app.lessons.compliance_challenge import ChallengeRuns
from armlab.app.lessons.compliance_contact import ContactTab
from armlab.app.lessons.compliance_controls import GainControls, apply_gains, show_gain_warning
from armlab.app.lessons.compliance_plots import JointPlots
from armlab.app.lessons.compliance_push import PushControls
from armlab.app.lessons.compliance_scene import ComplianceScene, estimated_hand_force
from armlab.app.lessons.compliance_servos import LinkMonitor, safe_health_html
from armlab.app.lessons.compliance_teach import (
    Chapter4,
    chapter4_markdown,
    design_table,
    equations_markdown,
    latest_values,
    measured_line,
    thesis_preset_note,
)
from armlab.app.lessons.law_view import ERROR_COLOR, LawView, law_loop_of, reference_angle
from armlab.app.lessons.run_files import RunControls
from armlab.app.page.inputs import guarded_slider
from armlab.app.page.surface import Surface
from armlab.control.backend import Backend, Pushable
from armlab.control.challenges import Challenge
from armlab.control.commands import (
    EStop,
    Push,
    Reconnect,
    RunTrajectory,
    SetTarget,
    Spring,
    Stop,
)
from armlab.control.loop import ControlLoop, LoopStatus
from armlab.control.params import DEFAULT, Params
from armlab.control.response import (
    Measured,
    last_finite,
    line_errors,
    line_part,
    line_yield,
    measure_push,
    measure_step,
    plan_step,
)
from armlab.control.trajectory import (
    THESIS_LINE_END,
    THESIS_LINE_START,
    JointTrajectory,
    hold,
    thesis_line,
)
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics.catalog import RECEPTIONIST_PRESETS, load_robot
from armlab.kinematics.fk import fk_and_jacobian
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import all_finite

NAME = "compliance"
TITLE = "Compliance"
HELP = ("The receptionist robot's arm under the thesis's PD loop and compliance controller: "
        "tune Kp, Kv and the virtual environment (M_env, D_env, K_env, K_f), run the 20 cm "
        "line, push or drag the hand and watch the arm yield.")
#: The first action, shown under the status line.
TRY = ("Press **Run thesis line**, then **Push the hand** while it runs (by hand on real "
       "servos): the arm gives way and comes back.")
ROBOTS = ("receptionist_arm",)
ORDER = 0

DEG = 180.0 / math.pi
#: The joint the charts show and the step test steps first: θ2, the elbow, the thesis's
#: servo 3 (chapter 4's metric).
SERVO_3 = 2

#: Push directions offered, in the shoulder (thesis) frame: x = gravity, y = along the line.
PUSH_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "against the line (−y)": (0.0, -1.0, 0.0),
    "along the line (+y)": (0.0, 1.0, 0.0),
    "down (+x, with gravity)": (1.0, 0.0, 0.0),
    "up (−x)": (-1.0, 0.0, 0.0),
    "towards the body (−z)": (0.0, 0.0, -1.0),
    "away from the body (+z)": (0.0, 0.0, 1.0),
}
#: ° of the RX-24F's position step (300° / 1023), the thesis arm's servos, simulated or not
SERVO_STEP_DEG = math.degrees(RX24F.position_unit)
HISTORY_S = 30.0  #: seconds the recorder keeps (a run is kept apart from it: run_track)


#: a student's page can hold a private copy of this lesson (``ctx.arms``)
PRIVATE = True
#: The figures of its last runs (:meth:`ComplianceLesson.run_figures`):
#: - max_error_deg: max |θ_cmd − θ| of the last free thesis-line run, ° (any joint);
#: - yield_deg: how far the last pushed line run moved from the free one, °;
#: - overshoot_pct, settling_s: of the last step test (%, s);
#: - step_joint: the joint (index in the model's order) the last step test stepped;
#: - pushed_error_deg: max |θ_cmd − θ| of the last thesis-line run with a push, °;
#: - line_push_n: the largest push (N) during that pushed line run (a drag alone: None,
#:   its force is the person's);
#: - push_n, stiffness_nm_per_rad: the force (N) of the last push test and the stiffness
#:   1/C_f it measured (Δτ_ext/Δθ_env, N·m/rad);
#: - contact_peak_n, contact_steady_n: the last run into a wall (the Contact tab's or the
#:   contact challenge's): the largest wall force at any plant step and the mean of its
#:   last second, N, from the loop's record (``f_contact``).
FIGURES = ("max_error_deg", "yield_deg", "overshoot_pct", "settling_s", "step_joint",
           "pushed_error_deg", "line_push_n", "push_n", "stiffness_nm_per_rad",
           "contact_peak_n", "contact_steady_n")
#: What a class overview shows of them, and its columns' heads.
OVERVIEW = {"max_error_deg": "max err °", "overshoot_pct": "%OS", "settling_s": "Ts s",
            "yield_deg": "yield °"}


def build(server: Surface, ctx: LessonContext) -> ComplianceLesson:
    """Open the lesson on ``server`` (see :mod:`armlab.app.lessons`)."""
    return ComplianceLesson(server, ctx)


@dataclass
class Experiment:
    """The last thing the student ran, measured once it is over.

    Attributes:
        kind: "line", "step" or "push".
        t0: loop time when it was posted, s.
        ready_at: loop time after which it can be measured, s.
        joint: joint index it concerns (step), or -1.
        q0, q1: step from/to, rad (step only).
        label: what the teaching panel calls it.
    """

    kind: str
    t0: float
    ready_at: float
    joint: int = -1
    q0: float = 0.0
    q1: float = 0.0
    label: str = ""
    over: bool = False  #: its run is over: it is being measured
    done: bool = False  #: measured: its figures are in (the page's and the run file's)
    pushed: bool = False  #: line only: a push or drag happened while it ran
    push_n: float | None = None  #: the largest push during it, N (a drag alone: None)


@dataclass
class Rig:
    """What a link-length preset needs: model, servos, loop, scene."""

    preset: str
    model: SerialChain
    backend: Backend
    loop: ControlLoop
    scene: ComplianceScene
    line: JointTrajectory


@dataclass(frozen=True)
class Kept:
    """What the lesson hands its next opening in the lab (:meth:`ComplianceLesson.keep`):
    the link lengths, the gains and every measurement, so that a switch to another lesson
    and back loses none of them (for the same robot)."""

    robot: str
    preset: str
    params: Params
    measured_pd: Measured | None
    measured_env: Measured | None
    chapter4: Chapter4
    free_q: np.ndarray | None
    last_run_text: str
    step_joint: int | None
    line_push_n: float | None
    push_n: float | None


class ComplianceLesson(LessonBase):
    """The compliance lesson on ``server`` (a :class:`armlab.app.lessons.LessonHandle`).

    Args:
        server: the viser server.
        ctx: robot and backend choice.
        link_preset: key of ``RECEPTIONIST_PRESETS`` (link lengths, cm).
        pose_hz, plot_hz: scene and chart update rates.
    """

    def __init__(self, server: Surface, ctx: LessonContext, *,
                 link_preset: str = "18.5/25", pose_hz: float = 30.0,
                 plot_hz: float = 11.0) -> None:
        super().__init__(server, ctx)
        self.hardware = ctx.backend != "sim"
        self._last_teach = 0.0
        self._last_servos = 0.0
        self._link = LinkMonitor()
        self.experiment: Experiment | None = None
        #: the challenges' runs: from the challenge's own start, tagged with its key
        self.challenges = ChallengeRuns(self)
        self._measured: Experiment | None = None  #: the last experiment measured whole
        self.run_start: float | None = None  #: loop time the last run started (CSV)
        self.run_label = "recording"
        self.measured_pd: Measured | None = None
        self.measured_env: Measured | None = None
        self.last_run_text = ""
        self.chapter4 = Chapter4()
        #: what the challenges judge besides chapter 4's figures (run_figures): the last
        #: step's joint, the last pushed line's push, the last push test's force (N)
        self._step_joint: int | None = None
        self._line_push_n: float | None = None
        self._push_n: float | None = None
        self._free_q: np.ndarray | None = None  #: θ of the last free line run, from its start
        self._drag_anchor: np.ndarray | None = None
        self._hand: np.ndarray | None = None  #: hand position of the last pose frame, m
        self._push: tuple[np.ndarray, float] | None = None  # (force N, end loop time)
        self.rig: Rig | None = None
        params = DEFAULT
        kept = None if ctx.arms is None else ctx.arms.kept()
        if kept is not None and kept[0] in RECEPTIONIST_PRESETS:
            link_preset, params = kept  # a reload: the student's arm as they left it
        own = ctx.kept if isinstance(ctx.kept, Kept) and ctx.kept.robot == ctx.robot and \
            ctx.kept.preset in RECEPTIONIST_PRESETS else None
        if own is not None:  # back from another lesson: as it was left
            link_preset, params = own.preset, own.params
        with self.opening():
            model = self._load_model(link_preset)
            self._build_gui(params, link_preset, model.joint_names)
            self.rig = self._make_rig(model, link_preset, params)
            show_gain_warning(self.warning, self.rig.loop.gains)
        if own is not None:
            self._take_kept(own)
        # an experiment is measured once it is over, whether a page is open to see it or
        # not (or its page is behind: a private page skips frames then)
        self.publish(pose=self._pose_frame, plots=self._plot_frame, pose_hz=pose_hz,
                     plot_hz=plot_hz, every=self._measure)

    def keep(self) -> Kept | None:
        """The link lengths, gains and measurements, for the lesson's next opening."""
        rig = self.rig
        if rig is None:
            return None
        return Kept(robot=self.ctx.robot, preset=rig.preset, params=self.gains.params,
                    measured_pd=self.measured_pd, measured_env=self.measured_env,
                    chapter4=self.chapter4, free_q=self._free_q,
                    last_run_text=self.last_run_text, step_joint=self._step_joint,
                    line_push_n=self._line_push_n, push_n=self._push_n)

    def _take_kept(self, kept: Kept) -> None:
        """The measurements of the lesson's last opening, shown again (:meth:`keep`)."""
        self.measured_pd, self.measured_env = kept.measured_pd, kept.measured_env
        self.chapter4, self._free_q = kept.chapter4, kept.free_q
        self.last_run_text, self._step_joint = kept.last_run_text, kept.step_joint
        self._line_push_n, self._push_n = kept.line_push_n, kept.push_n
        if kept.measured_pd is not None:
            set_content(self.step_result, measured_line(kept.measured_pd))
        if kept.measured_env is not None:
            for beside in (self.pushes.result, self.push_result_run):
                set_content(beside, measured_line(kept.measured_env))

    # ================================================================== rig

    def _load_model(self, preset: str) -> SerialChain:
        """The lesson's arm with the link lengths of ``preset``."""
        model = load_robot(self.ctx.robot, preset=preset)
        if not isinstance(model, SerialChain):
            raise ValueError(f"robot: {self.ctx.robot} is not a serial arm")
        return model

    def _make_rig(self, model: SerialChain, preset: str, params: Params) -> Rig:
        line = thesis_line(model)
        start = {"q0": line.q[0]} if self.ctx.backend == "sim" else {}  # on the line
        backend, loop = open_arm(self.ctx, model, params, preset=preset, q0=line.q[0],
                                 history_s=HISTORY_S, backend_kw=start, restartable=True)
        try:
            scene = ComplianceScene(
                self.server, model, path=np.vstack([THESIS_LINE_START, THESIS_LINE_END]),
                root="/compliance", on_target=self._on_target, on_drag_hand=self._on_drag)
        except BaseException:
            if self.ctx.arms is None:  # (a student's arm stays with their seat)
                shut_arm(backend, loop)
            raise
        scene.hand.visible = not self.hardware  # real servos are pushed by a real hand
        loop.start()  # (one already running goes on)
        return Rig(preset, model, backend, loop, scene, line)

    def _close_rig(self, rig: Rig) -> None:
        if self.ctx.arms is not None:  # the student's arm lives on for a reload; the page
            # leaves (maybe mid-drag: let go of the arm) or another preset replaces it
            rig.loop.post(Spring(None, stiffness=0.0, link=rig.model.n - 1,
                                 point=rig.model.tip[:3, 3]))
            rig.scene.remove()
            return
        try:
            shut_arm(rig.backend, rig.loop)
        finally:
            rig.scene.remove()

    def set_link_preset(self, preset: str) -> None:
        """Rebuild model, servos and loop for other link lengths (keeps the gains)."""
        if preset not in RECEPTIONIST_PRESETS:
            raise ValueError(f"link lengths: unknown preset {preset!r}; known: "
                             f"{', '.join(RECEPTIONIST_PRESETS)}")
        with self._lock:
            old = self.rig
            if old is None or old.preset == preset or self._closed:
                return
            self.challenges.cancel("new link lengths")
            self.rig = None
            self._close_rig(old)
            self.rig = self._make_rig(self._load_model(preset), preset, self.gains.params)
            self.experiment = None
            self.run_start = None
            self.chapter4, self._free_q = Chapter4(), None
            self._step_joint = self._line_push_n = self._push_n = None

    # ================================================================== GUI

    def _build_gui(self, params: Params, link_preset: str,
                   joint_names: tuple[str, ...]) -> None:
        gui = self.server.gui
        self.status = self._gui.add_status(try_this=TRY)
        self.warning = self._gui.add(gui.add_html("", order=-79.0, visible=False))
        tabs = self._gui.add(gui.add_tab_group(order=-70.0))
        with tabs.add_tab("Run", viser.Icon.PLAYER_PLAY):
            self._build_run_tab(gui, link_preset, joint_names)
        with tabs.add_tab("Gains", viser.Icon.ADJUSTMENTS):
            #: the student's own law (``armlab serve --exercise``): its note, error, ghost
            self.law_view = (None if self.ctx.law is None else LawView(
                self.server, gui, self.ctx.law, root="/compliance_reference"))
            self.gains = GainControls(gui, params, apply=self._apply_params)
        with tabs.add_tab("Push", viser.Icon.HAND_FINGER):
            self._build_push_tab(gui)
        with tabs.add_tab("Contact", viser.Icon.WALL):  # the hand run into a wall
            self.contact = ContactTab(self, gui, servos=self.hardware)
        with tabs.add_tab("Teach", viser.Icon.SCHOOL):
            self.equations = gui.add_markdown("")
            self.design = gui.add_markdown(design_table(params, None, None))
            self.last_run_md = gui.add_markdown("")
        with tabs.add_tab("Servos", viser.Icon.CPU):
            self.servo_html = gui.add_html("reading the servos…")
        with tabs.add_tab("Files", viser.Icon.FILE):  # Save run, Open run (replay), Export page
            self.runs = RunControls(self.server, gui, lesson=NAME, arm=self._arm_now,
                                    figures=self.run_figures, start=lambda: self.run_start,
                                    extra=self._run_extra, ghost_root="/compliance_replay",
                                    ctx=self.ctx, backend=self._backend_now,
                                    live_figures=False)
        with self._gui.chart_panel("Live charts") as charts:
            self.plots = JointPlots(gui, charts, joint_names, default_joint=SERVO_3,
                                    reference=self.ctx.law is not None)

    def _build_run_tab(self, gui: viser.GuiApi, link_preset: str,
                       joint_names: tuple[str, ...]) -> None:
        run = gui.add_button("Run thesis line", color="green", icon=viser.Icon.PLAYER_PLAY,
                             hint="The hand moves 20 cm along y in 1.28 s (thesis ch. 4), "
                                  "after a smooth approach to the start")
        stop = gui.add_button("Stop", icon=viser.Icon.PLAYER_STOP,
                              hint="Stop the motion and hold where the command is")
        reset = gui.add_button("Reset", icon=viser.Icon.REFRESH,
                               hint="After an E-STOP or a fault: torque on, hold where the arm is")
        home = gui.add_button("Home", icon=viser.Icon.HOME,
                              hint="Move the arm back to the thesis line's start at the lab's "
                                   "calm approach speed (after Reset, if it stopped far away)")
        home.on_click(lambda e: guarded(e, self.home))
        self.reconnect_button = gui.add_button(
            "Reconnect", color="orange", icon=viser.Icon.PLUG, visible=False,
            hint="The link to the servos is down: open the port again now (the lab also "
                 "tries once a second); torque stays off until Reset")
        run.on_click(lambda e: guarded(e, self.run_line))
        stop.on_click(lambda e: guarded(e, self.stop))
        reset.on_click(lambda e: guarded(e, self.reset))
        self.reconnect_button.on_click(lambda e: guarded(e, self.reconnect))
        # a short title: it stays on one line at projector sizes (what it measures: the hint)
        with gui.add_folder("Step test", expand_by_default=True):
            self.joint_labels = tuple(joint_label(n) for n in joint_names)
            self.step_joint = gui.add_dropdown("Joint", self.joint_labels,
                                               initial_value=self.joint_labels[SERVO_3])
            self._step_size = guarded_slider(
                gui, "Step (°)", name="step", lo=-30.0, hi=30.0, step=1.0, initial=-20.0,
                apply=lambda v: None, hint="Size and sign of the step; it goes the other way "
                "when a joint limit is too near")
            step = gui.add_button("Step", icon=viser.Icon.STAIRS_UP,
                                  hint="Step one joint's command and measure Tp, %OS, Ts "
                                       "and Tr; the Teach tab compares the "
                                       "response with eq. 2.16–2.19")
            step.on_click(lambda e: guarded(e, self.run_step))
            self.step_result = gui.add_markdown("")  # the figures of the last step, here
        # the push test one click from here too (the Push tab sets its force and length)
        push = gui.add_button("Push the hand", icon=viser.Icon.HAND_FINGER,
                              visible=not self.hardware,
                              hint="Push the hand as the Push tab sets it (4 N along −y for "
                                   "2 s unless changed): the arm gives way and comes back")
        push.on_click(lambda e: guarded(e, self.push))
        self.push_result_run = gui.add_markdown("")  # the figures of the last push, here
        self.download = gui.add_button("Download the last run (CSV)", icon=viser.Icon.DOWNLOAD,
                                       hint="Time, every plotted signal (SI) and the "
                                            "parameters in the header")
        self.download.on_click(lambda e: send_download(e, self.csv_bytes))
        with gui.add_folder("Arm and display", expand_by_default=False):
            self.links = gui.add_dropdown("Link lengths (cm)", tuple(RECEPTIONIST_PRESETS),
                                          initial_value=link_preset,
                                          hint="L1/L2: the appendix code (18.5/25), the "
                                               "specification list (18.5/18.5) or the FK "
                                               "text of eq. 3.13 (17/25)")
            self.links.on_update(lambda e: guarded(
                e, lambda: self.set_link_preset(str(self.links.value))))
            self.show_ghost = gui.add_checkbox("Show command (ghost)", True)
            self.show_trail = gui.add_checkbox("Show hand trail", True)

    def _build_push_tab(self, gui: viser.GuiApi) -> None:
        if self.hardware:
            gui.add_markdown("Push the **real arm by hand**: the purple arrow and the τ_ext "
                             "chart show the external torque the controller estimates "
                             "(eq. 2.23).")
        else:
            gui.add_markdown("**Drag the pink sphere at the hand** to pull the arm with a "
                             "spring, or push it with the button below.")
        self._spring_k = guarded_slider(gui, "Drag spring (N/m)", name="drag spring", lo=10.0,
                                        hi=1000.0, step=10.0, initial=200.0,
                                        apply=lambda v: None, visible=not self.hardware)
        self.pushes = PushControls(gui, tuple(PUSH_DIRECTIONS), servos=self.hardware,
                                   on_push=self.push)

    # ================================================================== actions

    def _loop(self) -> ControlLoop:
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        return rig.loop

    def _arm_now(self) -> tuple[SerialChain, ControlLoop]:
        """The model and loop of the arm now (a run file's robot and record)."""
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        return rig.model, rig.loop

    def _run_extra(self) -> dict[str, object]:
        """What a run file keeps besides the contract's fields: the link lengths (the run,
        law and backend: :class:`RunControls`)."""
        rig = self.rig
        return {"link_lengths_cm": None if rig is None else rig.preset}

    def _backend_now(self) -> Backend | None:
        """The arm's backend now (a run file names its servos)."""
        rig = self.rig
        return None if rig is None else rig.backend

    def _apply_params(self, params: Params) -> None:
        """Swap ``params`` into the loop (next period). Raises ValueError to refuse."""
        self.challenges.cancel("new gains")
        apply_gains(self._loop(), params, warning=self.warning)

    def _now(self) -> float:
        return self._loop().status.t

    def run_line(self) -> None:
        """Play the thesis's 20 cm line (after a smooth approach to its start)."""
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        check_running(rig.loop.status)
        self._law_works("Run thesis line")
        self.challenges.busy()
        self.challenges.untag("line_push")
        t0 = self._now()
        self.runs.post(rig.loop, RunTrajectory(rig.line), run="thesis line")
        self.run_start, self.run_label = t0, "thesis line"
        self.experiment = Experiment("line", t0, ready_at=math.inf, label="thesis line")
        rig.scene.set_target(THESIS_LINE_END)

    def run_step(self, *, joint: int | None = None, step_deg: float | None = None) -> None:
        """Step one joint's command by the chosen angle (measures the PD loop); ``joint``
        (index) and ``step_deg`` in place of the controls' (a challenge's run)."""
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        check_running(rig.loop.status)
        self._law_works("Step")
        self.challenges.busy()
        loop = rig.loop
        if joint is not None and not 0 <= joint < len(self.joint_labels):
            raise ValueError(f"step: no joint {joint} (the arm has {len(self.joint_labels)})")
        label = str(self.step_joint.value) if joint is None else self.joint_labels[joint]
        size = self._step_size.value if step_deg is None else step_deg
        plan = plan_step(_recorded_commands(loop), joint=self.joint_labels.index(label),
                         step=math.radians(size), lower=loop.lower,
                         upper=loop.upper, params=loop.params, label=label)
        t0 = self._now()
        self.challenges.untag("step")
        self.runs.post(loop, RunTrajectory(plan.trajectory, approach=False),
                       run=f"step {label}")
        self.run_start, self.run_label = t0, f"step {label}"
        self.experiment = Experiment(
            "step", t0, ready_at=t0 + plan.wait_s, joint=plan.joint, q0=plan.q0, q1=plan.q1,
            label=f"step of {label} by {math.degrees(plan.q1 - plan.q0):+.0f}°")

    def push(self, *, force_n: float | None = None, duration: float | None = None) -> None:
        """Push the hand with the chosen force, direction and duration (simulated arm);
        ``force_n`` and ``duration`` (s) in place of the controls' (a challenge's run)."""
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        if not isinstance(rig.backend, Pushable):
            raise ValueError("real servos: push the arm by hand")
        self._law_works("Push")
        self.challenges.busy()
        pushes = self.pushes
        size = pushes.force if force_n is None else force_n
        if not (math.isfinite(size) and size > 0):
            raise ValueError(f"push: {size!r} N is not a force")
        force = size * np.array(PUSH_DIRECTIONS[pushes.direction])
        duration = pushes.duration if duration is None else duration
        t0 = self._now()
        pushed_line = self._mark_line_pushed(push_n=size)
        self.challenges.untag("line_push" if pushed_line else "push")
        self.runs.post(rig.loop, Push(force, link=rig.model.n - 1, point=rig.model.tip[:3, 3],
                                      duration=duration), run=None if pushed_line else "push")
        self._push = (force, t0 + duration)
        if pushed_line:
            return
        self.run_start, self.run_label = t0, "push"
        self.experiment = Experiment("push", t0, ready_at=t0 + duration, push_n=size, label=(
            f"push of {size:g} N {pushes.direction} for {duration:g} s"))

    def stop(self) -> None:
        self.challenges.cancel("Stop")
        self.runs.post(self._loop(), Stop())

    def home(self) -> None:
        """Move the arm to the lesson's home pose, the thesis line's start, at the lab's
        approach speed: the way back after gains or a run left it far away (Reset only
        holds it where it is, as on a real arm). ValueError (shown) while the loop is
        stopped or the student's law fails."""
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        check_running(rig.loop.status)
        self._law_works("Home")
        self.challenges.cancel("Home")
        self.runs.post(rig.loop, RunTrajectory(hold(rig.line.q[0], 0.2, name="home")))

    def reset(self) -> None:
        """Clear a fault or E-STOP: torque on, hold. ValueError (shown to the person) while
        the link to the servos is down: nothing can be reset then."""
        self.challenges.cancel("Reset")
        post_reset(self._loop())
        self._push = None

    def reconnect(self) -> None:
        """Open the servos' port again now (after a lost link); torque stays off."""
        loop = self._loop()
        if not loop.status.link_down:
            raise ValueError("nothing to do: the link to the servos is up")
        loop.post(Reconnect())

    def estop(self) -> None:
        """Torque off now (the loop applies it at its next period); never raises."""
        rig = self.rig
        if rig is None:
            return
        self.challenges.cancel("E-STOP")
        try:
            rig.loop.post(EStop())
            if not rig.loop.status.running:  # no loop to apply it: do it here
                rig.backend.estop()
        except (ValueError, RuntimeError, OSError):
            rig.backend.estop()

    def gain_controls(self) -> GainControls:
        """The gain sliders: the gains the arm runs, set as a person sets them."""
        return self.gains

    def page_only_buttons(self) -> tuple[viser.GuiButtonHandle, ...]:
        """Save run, Export page and the CSV download: each answers the pressing page."""
        return (*self.runs.page_only_buttons(), self.download)

    def run_figures(self) -> dict[str, float | None]:
        """Chapter 4's figures of the last line runs, the last step test's, and the last
        run into a wall's (:data:`FIGURES`)."""
        ch4, step, env = self.chapter4, self.measured_pd, self.measured_env
        gain = None if env is None else env.static_gain
        return LESSON.figures_of(max_error_deg=_largest(ch4.free),
                       yield_deg=_largest(ch4.yield_deg),
                       overshoot_pct=None if step is None else step.overshoot_pct,
                       settling_s=None if step is None else step.settling_time_s,
                       step_joint=None if step is None else _index(self._step_joint),
                       pushed_error_deg=_largest(ch4.pushed),
                       line_push_n=None if ch4.pushed is None else self._line_push_n,
                       push_n=None if env is None else self._push_n,
                       stiffness_nm_per_rad=(None if gain is None or not gain > 0
                                             else 1.0 / gain),
                       **self._contact_figures())

    def _contact_figures(self) -> dict[str, float | None]:
        """The last run into a wall's peak and steady force, N (the Contact tab's or the
        contact challenge's; None before one)."""
        fig = self.contact.last_figures or {}
        return {"contact_peak_n": fig.get("peak_force_n") if fig.get("touched") else None,
                "contact_steady_n": fig.get("steady_force_n")}

    # ------------------------------------------------------------------ challenges

    def run_challenge(self, challenge: Challenge) -> str:
        """Start ``challenge``'s run from its own start (:mod:`.compliance_challenge`);
        what was started, for a person. ValueError when it cannot be."""
        self._law_works("The challenge's run")
        return self.challenges.start(challenge)

    def _law_works(self, what: str) -> None:
        """Refuse ``what`` (ValueError, shown) while the student's law fails."""
        if self.law_view is not None:
            self.law_view.refuse_commands(what)

    def run_tags(self) -> dict[str, str | None]:
        """Per figure of :meth:`run_figures`, the key of the challenge whose run measured
        it (None: a run made otherwise)."""
        return self.challenges.tags()

    def challenge_results(self) -> list[tuple[int, dict[str, float | None],
                                              dict[str, str | None]]]:
        """The challenge runs measured (number, figures, tags), newest last."""
        return list(self.challenges.results)

    def pushable(self) -> bool:
        """Whether the lab can push this arm (a simulated one)."""
        rig = self.rig
        return rig is not None and isinstance(rig.backend, Pushable)

    def take_step(self, measured: Measured, joint: int) -> None:
        """A challenge's step, measured: the lesson's step figures and the page's line."""
        self.measured_pd, self._step_joint = measured, joint
        set_content(self.step_result, measured_line(measured))

    def take_push(self, measured: Measured, force_n: float) -> None:
        """A challenge's push, measured: the lesson's push figures and the page's lines."""
        self.measured_env, self._push_n = measured, force_n
        for beside in (self.pushes.result, self.push_result_run):
            set_content(beside, measured_line(measured))

    def take_pushed_line(self, err_deg: np.ndarray, q: np.ndarray, force_n: float) -> None:
        """A challenge's line under a push, measured: chapter 4's pushed figures (its
        largest error per joint, °; the yield from the last free line run, if any)."""
        free_q, yld = self._free_q, None
        if free_q is not None and free_q.shape[1] == q.shape[1]:
            yld = line_yield(q, free_q) * DEG
        self.chapter4 = Chapter4(self.chapter4.free, err_deg, yld)
        self._line_push_n = force_n
        self.last_run_text = chapter4_markdown(self.chapter4, self.joint_labels)

    def _on_target(self, xyz: np.ndarray) -> None:
        rig = self.rig
        if rig is not None and np.all(np.isfinite(xyz)):  # a page cannot send NaN on
            self.challenges.cancel("a new target")
            self.runs.post(rig.loop, SetTarget(xyz))

    def _on_drag(self, phase: str, anchor: np.ndarray | None) -> None:
        rig = self.rig
        if rig is None or not isinstance(rig.backend, Pushable):
            return
        if anchor is not None and not np.all(np.isfinite(anchor)):
            return  # a malformed drag event: ignore it
        k = self._spring_k.value
        if anchor is not None:
            self.challenges.cancel("a drag of the hand")
        self._drag_anchor = anchor
        drag = phase == "start" and not self._mark_line_pushed()
        self.runs.post(rig.loop, Spring(anchor, stiffness=k, link=rig.model.n - 1,
                                        point=rig.model.tip[:3, 3]),
                       run="hand drag" if drag else None)
        if drag:
            self.run_start, self.run_label = self._now(), "hand drag"
        elif phase == "end" and self.runs.run_label == "hand drag":
            self.runs.finish_run({}, t=self._now())  # a drag measures nothing

    def _mark_line_pushed(self, *, push_n: float | None = None) -> bool:
        """A push (of ``push_n`` N) or drag during a line run makes it a pushed run
        (chapter 4); True if so."""
        exp = self.experiment
        if exp is None or exp.kind != "line" or exp.over:
            return False
        exp.pushed = True
        if push_n is not None:
            exp.push_n = max(push_n, exp.push_n or 0.0)
        return True

    def csv_bytes(self) -> tuple[str, bytes]:
        """(file name, CSV) of the run Save run saves (:meth:`RunControls.run_csv`: the
        last run whole, or up to now marked unfinished; with no run the live window,
        labelled so), its label, state and loop times in a header line."""
        rig = self.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        about, text = self.runs.run_csv()
        if text.count("\n") <= 3:
            raise ValueError("no samples recorded yet")
        label = str(about["label"])
        head = (f"# run: {label} ({about['state']}); robot {rig.model.name}, link lengths "
                f"{rig.preset} cm, backend {self.ctx.backend}; loop time "
                f"{about['t0_s']:.3f} s to {about['t_end_s']:.3f} s\n")
        first, rest = text.split("\n", 1)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        return (f"armlab-{label.replace(' ', '-')}-{stamp}.csv",
                (first + "\n" + head + rest).encode())

    # ================================================================== publishing

    def _pose_frame(self) -> None:
        rig = self.rig
        if rig is None:
            return
        snap = rig.loop.recorder.snapshot(0.05)
        if len(snap["t"]) == 0:
            return
        q = snap["q"][-1]
        if not all_finite(q):
            return
        q_cmd = snap["q_cmd"][-1]
        ghost = self.show_ghost.value and all_finite(q_cmd)
        rig.scene.ghost.root.visible = bool(ghost)
        rig.scene.set_pose(q, q_cmd if ghost else q)
        law_loop = law_loop_of(rig.loop)
        if law_loop is not None and self.law_view is not None:
            self.law_view.draw(law_loop, rig.model)
        T, J = fk_and_jacobian(rig.model, q)  # one pass for the hand and the force estimate
        hand = self._hand = T[:3, 3]
        if self.show_trail.value:
            rig.scene.add_trail(hand)
        applied = None
        anchor = self._drag_anchor
        if anchor is not None:
            applied = self._spring_k.value * (anchor - hand)
        rig.scene.set_spring(hand, anchor)
        push = self._push
        if push is not None:
            if snap["t"][-1] <= push[1]:
                applied = push[0] if applied is None else applied + push[0]
            else:
                self._push = None
        rig.scene.set_forces(hand, applied, estimated_hand_force(J, snap["tau_ext"][-1]))
        self.contact.draw(hand)

    def _plot_frame(self, force: bool) -> None:
        rig = self.rig
        if rig is None:
            return
        loop = rig.loop
        status = loop.status
        snap = loop.recorder.snapshot(self.plots.angle.window_s + 0.5)
        law_loop = law_loop_of(loop)
        self.plots.update(snap, force=force, reference=None if law_loop is None
                          else partial(reference_angle, law_loop))
        self.contact.plot(force)
        self._update_status(status, snap, rig)
        now = time.monotonic()
        if force or now - self._last_teach > 0.5:
            self._last_teach = now
            self._update_teach(status, snap, loop.params)
        if force or now - self._last_servos > 1.0:
            self._last_servos = now
            self.servo_html.content = safe_health_html(rig.backend, rig.model.joint_names)

    def _update_status(self, st: LoopStatus, snap: dict[str, np.ndarray], rig: Rig) -> None:
        if self.reconnect_button.visible != st.link_down:
            self.reconnect_button.visible = st.link_down
        stopped = stopped_state(st)
        if stopped is not None:  # (the loop names the model's joints: the page's names)
            state, color = joint_label(stopped), STOPPED_COLOR
        elif not st.active:
            state, color = "starting", "#555"
        elif st.trajectory:
            state, color = f"running {st.trajectory} ({100 * st.progress:.0f} %)", "#1f5eea"
        else:
            state, color = "holding", "#2e7d32"
        failing = None if self.law_view is None or stopped is not None else (
            self.law_view.failing_state())
        if failing is not None:  # the student's law: the dot says so, as red as its error
            state, color = failing, ERROR_COLOR
        push = self._push
        if st.active and push is not None and len(snap["t"]) and snap["t"][-1] <= push[1]:
            state += (f" · pushing {np.linalg.norm(push[0]):.3g} N "
                      f"({push[1] - snap['t'][-1]:.1f} s left)")
        torque = ("torque unknown (the torque-off was not sent)" if st.torque_off_unsent
                  else "torque on" if st.torque_on else "torque off")
        where = "simulated arm" if not self.hardware else f"servos on {self.ctx.port}"
        hand = ""
        if self._hand is not None:  # from the latest pose frame (at most 1/30 s old)
            p = self._hand * 100
            hand = f" · hand ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) cm"
        msg = ""
        if st.message and not st.fault and st.message != state:
            msg = f"<div style='color:#555;font-size:0.85em'>{esc(joint_label(st.message))}</div>"
        msg += link_note(self._link, rig.backend)  # retries hold the arm; many are told
        if self.law_view is not None:  # the student's law: its error, file and line
            msg += self.law_view.status_extra()
        if st.skipped_recent:  # the machine could not keep up: say so, do not hide it
            msg += (f"<div style='color:#a15c00;font-size:0.85em'>late: {st.skipped_recent} "
                    "periods skipped in the last 10 s</div>")
        set_content(self.status, status_html(
            state, color, f"{where} · {torque} · t = {st.t:.0f} s · T = {st.period_ms:.0f} ms"
            f"{hand}", extra=msg))

    def _update_teach(self, st: LoopStatus, snap: dict[str, np.ndarray], params: Params) -> None:
        j = self.plots.joint
        live = latest_values(snap, j, self.plots.labels[j])
        eq = equations_markdown(params, live, torque_unit=self.plots.unit,
                                mode=st.controller)
        note = thesis_preset_note(params)
        set_content(self.equations, f"{note}\n\n{eq}" if note else eq)
        set_content(self.design, design_table(params, self.measured_pd, self.measured_env,
                                              servo_step_deg=SERVO_STEP_DEG))
        set_content(self.last_run_md, self.last_run_text)

    def _measure(self) -> None:
        """The last experiment's figures, once it is over (the publisher calls this at each
        of its ticks: the loop's status is read only while one runs)."""
        self.runs.tick()  # the run's rows kept apart from the recorder's window
        self.challenges.measure()
        self.contact.tick()
        exp, rig = self.experiment, self.rig
        if exp is None or exp.over or rig is None:
            return
        st = rig.loop.status
        try:
            self._measure_experiment(exp, rig, st)
        finally:
            if exp.over:  # the run file keeps this run's own figures, nothing older
                self.runs.finish_run(self._figures_of(exp), t=st.t)
                exp.done = True  # (after its figures: whoever waits for it reads them)

    def _figures_of(self, exp: Experiment) -> dict[str, float | None]:
        """The figures experiment ``exp`` measured (those the page showed for it)."""
        figures = self.run_figures()
        if self._measured is not exp:  # not measured (no samples, a step cut short)
            return {}
        if exp.kind == "line":
            names = (("pushed_error_deg", "yield_deg", "line_push_n") if exp.pushed
                     else ("max_error_deg",))
            return {k: figures[k] for k in names}
        if exp.kind == "step" and self.measured_pd is not None:
            m = self.measured_pd
            return {"overshoot_pct": m.overshoot_pct, "peak_time_s": m.peak_time_s,
                    "settling_s": m.settling_time_s, "rise_time_s": m.rise_time_s,
                    "step_joint": figures["step_joint"]}
        if exp.kind == "push" and self.measured_env is not None:
            return {"push_n": figures["push_n"], "static_gain_rad_per_nm":
                    self.measured_env.static_gain,
                    "stiffness_nm_per_rad": figures["stiffness_nm_per_rad"]}
        return {}

    def _measure_experiment(self, exp: Experiment, rig: Rig, st: LoopStatus) -> None:
        """Measure ``exp`` if it is over (``exp.over`` then)."""
        if exp.kind == "line":
            if st.t < exp.t0 + 0.1 or st.trajectory is not None:
                return
            exp.over = True
            snap = rig.loop.recorder.snapshot(st.t - exp.t0 + 0.2)
            if not np.any(snap["t"] >= exp.t0):  # the loop stopped before recording the run
                self.last_run_text = "**Last run** (thesis line): no samples (the loop stopped)"
                return
            keep = snap["t"] >= exp.t0  # from the line's own start (after any approach):
            first = line_part(snap["q_cmd"][keep], rig.line.q[0])  # error, yield alike
            q = snap["q"][keep][first:]
            err = line_errors(snap, t0=float(snap["t"][keep][first])) * DEG
            ch4 = self.chapter4
            if exp.pushed:
                free_q = self._free_q
                yld = None
                if free_q is not None and free_q.shape[1] == q.shape[1]:
                    yld = line_yield(q, free_q) * DEG
                self.chapter4 = Chapter4(ch4.free, err, yld)
                self._line_push_n = exp.push_n
            else:
                self._free_q = q
                self.chapter4 = Chapter4(err, ch4.pushed, None)
            self.last_run_text = chapter4_markdown(
                self.chapter4, self.joint_labels)
            self._measured = exp
            return
        if st.t < exp.ready_at:
            return
        exp.over = True
        snap = rig.loop.recorder.snapshot(st.t - exp.t0 + 0.2)
        try:
            if exp.kind == "step":
                self.measured_pd = measure_step(snap, t0=exp.t0, joint=exp.joint, q0=exp.q0,
                                                q1=exp.q1, what=exp.label,
                                                params=rig.loop.params)
                self._step_joint = exp.joint
                set_content(self.step_result, measured_line(self.measured_pd))
                self._measured = exp
            elif exp.kind == "push":
                self.measured_env = measure_push(
                    snap, t0=exp.t0, t1=exp.ready_at, what=exp.label,
                    joint_labels=self.joint_labels, params=rig.loop.params)
                self._push_n = exp.push_n
                for beside in (self.pushes.result, self.push_result_run):  # both buttons
                    set_content(beside, measured_line(self.measured_env))
                self._measured = exp
        except ValueError as exc:
            self.last_run_text = f"**Last run** ({exp.label}): not measured: {esc(str(exc))}"

    # ================================================================== lifetime

    def close(self) -> None:
        """Stop the publisher and the loop (torque off), remove scene and GUI."""
        if not self.mark_closed():
            return
        self.publisher.close()
        if self.law_view is not None:
            self.law_view.remove()
        self.contact.close()
        self.runs.remove()
        rig, self.rig = self.rig, None
        close_in_turn(partial(self._close_rig, rig) if rig is not None else None,
                      self._gui.remove_all)


#: This lesson, as the lab lists it (:data:`armlab.app.lessons.catalog.LESSONS`).
LESSON = Lesson(name=NAME, title=TITLE, help=HELP, first_step=TRY, robots=ROBOTS, build=build,
                order=ORDER, private=PRIVATE, figures=FIGURES, overview=OVERVIEW)

__all__ = ["ComplianceLesson", "build", "NAME", "TITLE", "HELP", "ROBOTS", "LESSON"]


def _index(j: int | None) -> float | None:
    """A joint index as a figure (None: none)."""
    return None if j is None else float(j)


def _largest(x: np.ndarray | None) -> float | None:
    """The largest |x| over its finite entries, ° (None: no run, or none finite)."""
    if x is None or not np.any(np.isfinite(x)):
        return None
    return float(np.nanmax(np.abs(x)))


#: wall seconds a Step waits for the first command of a loop that has just started
FIRST_COMMAND_S = 0.5


def _recorded_commands(loop: ControlLoop) -> dict[str, np.ndarray]:
    """The loop's last 0.2 s of record (for :func:`plan_step`). A loop that has just become
    active records its first command at the end of that period: a Step pressed in between
    waits for it (up to :data:`FIRST_COMMAND_S`) rather than being told the controller is
    not running."""
    snap = loop.recorder.snapshot(0.2)
    deadline = time.monotonic() + FIRST_COMMAND_S
    while (last_finite(snap["q_cmd"]) is None and loop.status.active
           and time.monotonic() < deadline):
        time.sleep(0.005)
        snap = loop.recorder.snapshot(0.2)
    return snap
