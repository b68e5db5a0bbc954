"""Lesson: your own arm from its URDF — joint sliders, a hand target, compliance, spare joints.

Any serial chain of 1 to 7 revolute joints (``armlab serve --robot PATH.urdf
--tip-link LINK``, or the shipped ``open_manipulator_x``) runs the thesis's
compliance controller (eq. 2.6/2.20, :mod:`armlab.control.compliance`) through the same
:class:`~armlab.control.loop.ControlLoop` as the receptionist arm, on the simulated arm
or on Dynamixel servos (``--backend serial --joint-map MAP.toml``). A slider per
joint moves that joint (minimum-jerk approach, degrees in the page, limits from
the URDF narrowed to the servos'); dragging the hand target makes the loop follow
it by resolved-motion rate control (position only, so a 4+ joint arm is redundant
for it). The Teach tab lists every joint's limits and says which come from a
stated default (a continuous joint whose file gives none).

The compliance lesson's controls run on it too (:mod:`armlab.app.lessons.arm_controls`): the
gains and the virtual environment with presets, a push at the hand, live charts of any
joint; and an arm of more than 3 joints may use its spare joints (seed 002's gradient
projection) to stay away from its limits or gain manipulability while the hand follows
the target. An arm whose gripper has its own servo (the OpenManipulator-X's ID 15, the
SO-101's ID 6, simulated or on the bus) gets Open / Close buttons and a slider (a sliding
finger's travel in mm, a turning jaw's angle in degrees), and the 3D view's fingers follow
the servo (:mod:`armlab.app.lessons.arm_gripper`).

Runs (what Save run saves, :mod:`armlab.app.lessons.run_files`): a joint slider's move
("joint <name>") and **Home** ("home"), each over once its trajectory has played; a drag
of the hand target ("hand target"), over when the target is let go; a push ("push"),
over once it is measured, with the figures the Push tab shows (how far the hand gave way
and came back, and the environment filter's Tp, %OS, Ts and C_f when measured). A move
measures nothing: its file has no figures. Every run keeps a settling tail.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from functools import partial

import numpy as np
import viser
import viser.transforms as vtf

from armlab.app.lessons import ANY_URDF, Lesson, LessonContext
from armlab.app.lessons._common import (
    LessonBase,
    close_in_turn,
    esc,
    guarded,
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
from armlab.app.lessons.arm_controls import PUSH_RUN, ArmControls
from armlab.app.lessons.arm_gripper import GripperControls
from armlab.app.lessons.compliance_controls import GainControls
from armlab.app.lessons.compliance_servos import LinkMonitor
from armlab.app.lessons.law_view import ERROR_COLOR
from armlab.app.lessons.run_files import RunControls
from armlab.app.page.arm_view import ArmView
from armlab.app.page.camera import View, show
from armlab.app.page.in_order import InOrder
from armlab.app.page.inputs import inward_range
from armlab.app.page.surface import Surface
from armlab.control.backend import BackendError
from armlab.control.commands import EStop, RunTrajectory, SetTarget
from armlab.control.params import DEFAULT
from armlab.control.trajectory import hold
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import all_finite
from armlab.kinematics.urdf_read import CONTINUOUS_LIMIT

NAME = "arm"
TITLE = "Your URDF arm"
HELP = ("Any arm from its URDF: a slider per joint, a hand target to drag (the loop follows it "
        "by resolved-motion rate control) and the compliance controller holding the pose, "
        "with its gains, a push at the hand and live charts; spare joints (more than 3) "
        "can aim away from the limits. Limits come from the file; the Teach tab lists them.")
#: The first action, shown under the status line.
TRY = ("Move a slider on the **Joints** tab a few degrees, then drag the orange target: the "
       "hand follows it. (Your own arm: `armlab serve --robot your_arm.urdf`.)")
ROBOTS = ("open_manipulator_x", "so101", ANY_URDF)
ORDER = 50
#: a student's page can hold a private copy of this lesson (``ctx.arms``)
PRIVATE = True
MAX_JOINTS = 7
#: s a slider's goal is held after the smooth approach (the loop then keeps it).
SLIDER_HOLD_S = 0.2
#: °: a joint slider's step; its ends are the joint's limits rounded inwards to it
SLIDER_STEP_DEG = 0.5
#: s of signals the loop's recorder keeps (the hand pose and the status read the newest).
HISTORY_S = 20.0
#: s after a person's last slider move before the sliders follow the arm again
SLIDER_QUIET_S = 1.0
#: the name of a slider's move (its trajectory), while it plays the sliders stay put
SLIDER_MOVE = "joint slider"
#: The labels of the lesson's runs (Save run): Home, a drag of the hand target (a joint
#: slider's is "joint <name>"; a push's is arm_controls.PUSH_RUN)
HOME_RUN, TARGET_RUN = "home", "hand target"


def build(server: Surface, ctx: LessonContext) -> ArmLesson:
    """Open the lesson on ``server`` (see :mod:`armlab.app.lessons`)."""
    return ArmLesson(server, ctx)


def private_key(ctx: LessonContext) -> str:
    """Which of the class's batched plants a student's copy of this arm lives in: one per
    robot and tip link (the arms of one plant share the model)."""
    return f"arm {ctx.robot} {ctx.tip_link or '(default tip)'}"


def check_servo_arm(model: SerialChain) -> None:
    """Refuse a chain the lab cannot drive as a servo arm, naming the joint.

    Raises:
        ValueError: not 1..7 joints, or a prismatic joint on the chain.
    """
    if not 1 <= model.n <= MAX_JOINTS:
        raise ValueError(f"robot {model.name}: {model.n} joints on the chain "
                         f"({', '.join(model.joint_names)}); the lab drives 1 to {MAX_JOINTS} "
                         "(pick another --tip-link)")
    for j in model.joints:
        if j.kind == "prismatic":
            raise ValueError(f"robot {model.name}: joint {j.name!r} is prismatic; the lab "
                             "drives revolute joints only (pick a --tip-link before it)")


def limits_markdown(model: SerialChain, lower: np.ndarray, upper: np.ndarray) -> str:
    """The Teach tab's table: each joint's limits in degrees and where they come from."""
    rows = ["| joint | lower ° | upper ° | from |", "|---|---|---|---|"]
    for j, lo, hi in zip(model.joints, lower, upper, strict=True):
        if j.limit_default:
            source = f"default ±{math.degrees(CONTINUOUS_LIMIT):.0f}° (continuous, no limit)"
        elif lo > j.lower + 1e-9 or hi < j.upper - 1e-9:
            source = "URDF narrowed to the servo"
        else:
            source = "URDF"
        rows.append(f"| {esc(j.name)} | {math.degrees(lo):+.1f} | {math.degrees(hi):+.1f} | "
                    f"{source} |")
    return "\n".join(rows)


class ArmLesson(LessonBase):
    """The any-arm lesson on ``server`` (a :class:`armlab.app.lessons.LessonHandle`).

    Attributes:
        model: the chain from the URDF.
        loop: the control loop (compliance controller).
        sliders: one slider per joint, degrees.
    """

    def __init__(self, server: Surface, ctx: LessonContext, *,
                 pose_hz: float = 30.0) -> None:
        super().__init__(server, ctx)
        self._link = LinkMonitor()
        self._slider_t = -math.inf  # monotonic s of a person's last slider move
        self._setting = threading.Lock()  # held while the lab sets a slider itself
        #: each slider's value as the lab last set it or handled a person's move: a slider
        #: showing another holds a person's value its handler has not run for yet
        self._slider_known: list[float] = []
        model = load_robot(ctx.robot, tip_link=ctx.tip_link, package_paths=ctx.package_paths)
        if not isinstance(model, SerialChain):
            raise ValueError(f"robot: {ctx.robot} is not a serial arm")
        check_servo_arm(model)
        self.model = model
        extra = {"joint_map": ctx.joint_map} if ctx.backend != "sim" and ctx.joint_map else {}
        self.backend, self.loop = open_arm(ctx, model, DEFAULT, preset=private_key(ctx),
                                           q0=model.neutral(), history_s=HISTORY_S,
                                           backend_kw=extra)
        # a student's arm stays with their seat; the lab's is let go if the page fails
        undo = None if ctx.arms is not None else partial(shut_arm, self.backend, self.loop)
        #: (n,) rad where the arm was when the lesson opened: the sliders and the target
        #: start there (the servos read once)
        self._opened_at = self._held()
        #: the label of the last move's run (a slider, Home): over once it has played
        self._move_run: str | None = None
        with self.opening(undo):
            self.view = ArmView(server, model, root="/arm")
            self._build_scene()
            self._build_gui()
        if ctx.arms is None:
            self.loop.start()
        # a push is measured once it is over, whether a page is open to see it or not
        self.publish(pose=self._pose_frame, plots=self._status_frame, pose_hz=pose_hz,
                     plot_hz=min(pose_hz, 10.0), every=self._measure)

    # ================================================================== scene and GUI

    def _held(self) -> np.ndarray:
        """(n,) rad the arm is at now: its newest recorded angles (a kept private arm), or
        what the servos report (a loop that has not started: real servos are wherever a
        person left them, never at zero), else the neutral pose."""
        snap = self.loop.recorder.snapshot(1.0)
        if len(snap["t"]) and all_finite(snap["q"][-1]):
            return np.asarray(snap["q"][-1], dtype=float)
        if self.ctx.arms is None and not self.loop.status.running:
            try:
                q = np.asarray(self.backend.read().position, dtype=float)
            except (BackendError, OSError, ValueError):
                q = np.full(self.model.n, np.nan)
            if all_finite(q):
                return np.clip(q, self.loop.lower, self.loop.upper)
        return self.model.neutral()

    @staticmethod
    def _shown(snap: dict[str, np.ndarray], *, active: bool) -> np.ndarray | None:
        """(n,) rad the joint sliders show, from the newest of ``snap`` (a recorder
        snapshot): the command while the loop holds the arm (``active``); where the arm is
        while it holds nothing (E-STOP, a fault, a lost link, torque held off: the arm may
        fall or be moved by hand), so the next slider move or Reset starts there. None
        when nothing is recorded yet."""
        if not len(snap["t"]):
            return None
        q_cmd, q = snap["q_cmd"][-1], snap["q"][-1]
        if active and all_finite(q_cmd):
            return np.asarray(q_cmd, dtype=float)
        return np.asarray(q, dtype=float) if all_finite(q) else None

    def _follow_arm(self, snap: dict[str, np.ndarray]) -> None:
        """Keep the joint sliders on the pose the arm holds (:meth:`_shown`) when it was
        not a slider that put it there: the hand target, Reset, E-STOP, a fault, a
        reconnect. A slider a person moved in the last :data:`SLIDER_QUIET_S`, whose
        approach still plays, or whose move viser has applied but not yet handed to
        :meth:`_on_slider` (a busy machine: the value first, its handler a moment later),
        is left where the person put it."""
        if time.monotonic() - self._slider_t < SLIDER_QUIET_S or self._person_waiting():
            return
        st = self.loop.status  # (one snapshot a frame)
        if st.trajectory == SLIDER_MOVE:
            return
        q = self._shown(snap, active=st.active)
        if q is None:
            return
        for i, (slider, deg) in enumerate(zip(self.sliders, np.degrees(q), strict=True)):
            value = _on_step(float(deg), slider.min, slider.max)
            if abs(value - float(slider.value)) > 0.5 * SLIDER_STEP_DEG:
                if self._person_waiting():
                    return
                with self._setting:  # not a person's move (see _on_slider)
                    slider.value = value  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
                self._slider_known[i] = value

    def _person_waiting(self) -> bool:
        """Whether a slider shows a value neither the lab set nor :meth:`_on_slider`
        handled: a person's move on its way to its handler."""
        return any(float(s.value) != known
                   for s, known in zip(self.sliders, self._slider_known, strict=True))

    def _build_scene(self) -> None:
        base = self.model.base_pose
        hand = self.model.fk(self._opened_at)[:3, 3]
        scene = self.server.scene
        self.base = scene.add_frame("/arm_target_base", show_axes=False,
                                    position=base[:3, 3],
                                    wxyz=_wxyz(base[:3, :3]))
        self.target = scene.add_transform_controls(
            "/arm_target_base/target", scale=0.08, disable_rotations=True, depth_test=False,
            position=hand)
        scene.add_icosphere("/arm_target_base/target/dot", radius=0.008, color=(250, 160, 0))
        show(self.server, View(roots=(self.view.moving_root, "/arm_target_base"),
                               direction=_view_direction(base, hand)))

        def moved(event: viser.TransformControlsEvent) -> None:
            if event.client is None:
                return
            if event.phase == "start":  # said once, when the target is grabbed: a stopped
                # loop, or the student's law failing
                guarded(event, lambda: (check_running(self.loop.status),  # type: ignore[func-returns-value]  # a tuple to run both checks (each raises ValueError to refuse)
                                        self.controls.refuse_while_law_fails(  # type: ignore[func-returns-value]  # a tuple to run both checks (each raises ValueError to refuse)
                                            "Moving the target")))
            elif stopped_state(self.loop.status) is None:
                with contextlib.suppress(ValueError):  # (refused: said at the start)
                    self.set_target(np.asarray(self.target.position, dtype=float))
            if event.phase == "end":
                self.target_released()

        self._lane = InOrder("armlab-arm-target")  # the gizmo's moves in the page's order
        self.target.on_update(self._lane(moved))

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.status = self._gui.add_status(try_this=TRY)
        tabs = self._gui.add(gui.add_tab_group(order=-70.0))
        lower, upper = self.loop.lower, self.loop.upper
        held = np.degrees(self._opened_at)
        with tabs.add_tab("Joints", viser.Icon.ADJUSTMENTS):
            self.sliders = []
            for i, j in enumerate(self.model.joints):
                lo, hi = math.degrees(lower[i]), math.degrees(upper[i])
                # ends on the 0.5° step, inside the limits: round numbers at its ends
                ends = inward_range(lo, hi, step=SLIDER_STEP_DEG)
                start = _on_step(float(held[i]), *ends)
                slider = gui.add_slider(f"{j.name} °", min=ends[0], max=ends[1],
                                        step=SLIDER_STEP_DEG, initial_value=start,
                                        hint=f"Joint {j.name}: {lo:+.1f}° .. {hi:+.1f}°")
                slider.on_update(self._on_slider)
                self.sliders.append(slider)
                self._slider_known.append(float(start))
            # an uncalibrated arm on servos starts with torque off until a person says so
            self.confirm = gui.add_button(
                "Torque on: the arm is clear", color="orange", icon=viser.Icon.POWER,
                visible=self.loop.status.held_off is not None,
                hint="The joint map is not calibrated: the arm's angles may not be the "
                     "model's. Check that nothing is in its way, then switch its torque on "
                     "(it holds where it is)")
            self.confirm.on_click(lambda e: guarded(e, lambda: post_reset(self.loop)))
            reset = gui.add_button("Reset (after E-STOP or a fault)")
            reset.on_click(lambda e: guarded(e, lambda: post_reset(self.loop)))
            home = gui.add_button("Home", icon=viser.Icon.HOME,
                                  hint="Move every joint back to the arm's home pose (its "
                                       "zero, inside the limits) at the lab's calm approach "
                                       "speed")
            home.on_click(lambda e: guarded(e, self.home))
            self.gripper = GripperControls(gui, model=self.model, backend=self.backend,
                                           loop=self.loop, view=self.view)
        self.controls = ArmControls(self.server, self._gui, tabs, model=self.model,
                                    backend=self.backend, loop=self.loop,
                                    base_node=self.base.name, place_target=self._place_target)
        with tabs.add_tab("Teach", viser.Icon.SCHOOL):
            gui.add_markdown(
                f"**{esc(self.model.name)}**: {self.model.n} joints "
                f"({esc(', '.join(self.model.joint_names))}), tip "
                f"{esc(self._tip_name())}. The compliance controller (thesis eq. 2.6, 2.20) "
                "holds each joint; dragging the orange target moves the hand by "
                "resolved-motion rate control (Δq = J⁺ Δx, position only).")
            self.limits = gui.add_markdown(limits_markdown(self.model, lower, upper))
            self.controls.add_teach(gui)
            self.gripper.add_teach(gui)
        with tabs.add_tab("Files", viser.Icon.FILE):  # Save run, Open run (replay), Export page
            self.runs = RunControls(self.server, gui, lesson=NAME,
                                    arm=lambda: (self.model, self.loop),
                                    figures=lambda: self.run_figures(),
                                    extra=lambda: {"backend": self.ctx.backend,
                                                   "tip_link": self.ctx.tip_link},
                                    ghost_root="/arm_replay")
        self.controls.on_post = self.runs.note  # its pushes go into the run file too
        self.controls.on_run = lambda label, t: self.runs.begin_run(label, t=t)

    def _tip_name(self) -> str:
        return self.ctx.tip_link or "the file's default tip"

    # ================================================================== actions

    def _on_slider(self, event: viser.GuiEvent) -> None:
        """A person moved one joint's slider: that joint's goal goes where the slider
        says, every other joint's stays where the loop holds it (never where another
        slider was last left)."""
        if event.client is None and self._setting.locked():
            return  # the lab keeping the slider on the arm (:meth:`_follow_arm`)
        self._slider_t = time.monotonic()
        i = next((k for k, s in enumerate(self.sliders) if s is event.target), None)
        if i is None:
            return
        self._slider_known[i] = float(event.target.value)
        angle = math.radians(float(event.target.value))
        guarded(event, lambda: self.move_joint(i, angle))

    def move_joint(self, joint: int, angle: float) -> None:
        """Move joint ``joint`` smoothly to ``angle`` rad (clipped into its limits), every
        other joint held at its command: a slider moved by N° moves the goal N°.

        Raises:
            ValueError: the loop is stopped (a lost link, a fault, E-STOP, torque held off):
                saying why nothing happened.
        """
        st = self.loop.status
        check_running(st)
        q = self._shown(self.loop.recorder.snapshot(0.2), active=st.active)
        # (a loop that has not recorded yet holds the pose the lesson opened at)
        q = (self._opened_at if q is None else q).copy()
        q[joint] = angle
        self.move_to(q, run=f"joint {self.model.joint_names[joint]}")

    def move_to(self, q: np.ndarray, *, run: str = HOME_RUN) -> None:
        """Move smoothly to joint angles ``q`` (n,) rad, clipped into the joint limits:
        a minimum-jerk approach from the command whose peak joint speed is the lab's
        calm approach speed (:func:`~armlab.control.trajectory.approach_duration`,
        0.5 rad/s), however far it is.

        ``run``: the label of the run it begins (Save run), over once it has played.

        Raises:
            ValueError: the loop is stopped (a lost link, a fault, E-STOP, torque held off):
                saying why nothing happened.
        """
        check_running(self.loop.status)
        self.controls.refuse_while_law_fails("A joint move")
        q = np.clip(np.asarray(q, dtype=float), self.loop.lower, self.loop.upper)
        self.runs.post(self.loop, RunTrajectory(hold(q, SLIDER_HOLD_S, name=SLIDER_MOVE),
                                                approach=True), run=run)
        self._move_run = run

    def home(self) -> None:
        """Move the arm to its home pose (the model's zero, clipped into the limits) at the
        lab's approach speed: the way back after a run left it far away (Reset only holds
        it where it is, as on a real arm).

        Raises:
            ValueError: the loop is stopped: saying why nothing happened (Reset first).
        """
        self.move_to(self.model.neutral())

    def set_target(self, xyz: np.ndarray) -> None:
        """Make the hand follow ``xyz`` (3,) m in the arm's base frame (refused, with the
        reason, while the student's law fails)."""
        self.controls.refuse_while_law_fails("Moving the target")
        # a drag's first move begins its run; the rest are commands in it
        going = self.runs.going_on
        self.runs.post(self.loop, SetTarget(xyz),
                       run=None if going == TARGET_RUN else TARGET_RUN)

    def target_released(self) -> None:
        """The hand target was let go: its drag's run is over (it measures nothing; the
        settling tail holds the hand reaching it)."""
        if self.runs.going_on == TARGET_RUN:
            self.runs.finish_run({}, t=self.loop.status.t)

    def _measure(self) -> None:
        """At each publisher tick, a page open or not: measure a push that is over, keep
        the run's rows, and end a run that is over (a move once played, a push once
        measured)."""
        self.controls.measure()
        self.runs.tick()
        going = self.runs.going_on
        if going is None:
            return
        st = self.loop.status
        if going == self._move_run:
            t0 = self.runs.run_t0
            if t0 is not None and st.trajectory is None and st.t >= t0 + 0.1:
                self.runs.finish_run({}, t=st.t)
        elif going == PUSH_RUN:
            done = self.controls.push_figures
            if done is not None and done[0] is self.controls.last_push:
                self.runs.finish_run(done[1], t=st.t)

    def _place_target(self, xyz: np.ndarray) -> None:
        """Show the hand target at ``xyz`` (3,) m, base frame (viser reports only a page's
        moves, so this is not taken for one)."""
        self.target.position = np.asarray(xyz, dtype=float)

    def _pose_frame(self) -> None:
        snap = self.loop.recorder.snapshot(0.05)
        if len(snap["t"]) and np.all(np.isfinite(snap["q"][-1])):
            self.view.set_q(snap["q"][-1])
            self.controls.pose_frame(snap)
            self._follow_arm(snap)
        self.gripper.pose_frame()

    def _status_frame(self, force: bool) -> None:
        st = self.loop.status
        # (the arm named: the lesson opens the shipped OpenManipulator-X when no file is given)
        where = f"{self.model.name} · backend {self.ctx.backend} · loop t {st.t:.1f} s"
        state = stopped_state(st)
        if self.confirm.visible != (st.held_off is not None):
            self.confirm.visible = st.held_off is not None
        if state is not None:  # red; under an unsent torque-off, why the link failed
            color = STOPPED_COLOR
            detail = (st.fault if st.torque_off_unsent and st.fault else
                      st.held_off or where)
        else:
            state, color = ("holding", "#2e7d32") if st.active else ("starting", "#555")
            detail = st.message or where
            failing = self.controls.failing_state()
            if failing is not None:  # the student's law: the dot as red as its error
                state, color = failing, ERROR_COLOR
        set_content(self.status, status_html(state + self.controls.status_note(), color,
                                             esc(detail),
                                             extra=link_note(self._link, self.backend)
                                             + self.controls.law_note()))
        self.controls.plot_frame(force)
        self.gripper.status_frame()

    # ================================================================== lifetime

    def estop(self) -> None:
        """Torque off now (the lab's E-STOP button); never raises."""
        try:
            self.loop.post(EStop())
        finally:
            try:
                self.backend.estop()
            except Exception:  # an E-STOP must never raise
                pass

    def gain_controls(self) -> GainControls:
        """The Gains tab: the gains the arm runs, set as a person sets them."""
        return self.controls.gains

    def page_only_buttons(self) -> tuple[viser.GuiButtonHandle, ...]:
        """Save run and Export page: each answers the pressing page."""
        return self.runs.page_only_buttons()

    def close(self) -> None:
        """Stop the publisher and the loop (torque off), close the servos, remove GUI and
        scene. A student's arm (``ctx.arms``) keeps running, holding its pose, for a reload."""
        if self.mark_closed():
            own = self.ctx.arms is None
            close_in_turn(self.publisher.close,
                          (lambda: self.loop.shutdown(torque_off=True)) if own else None,
                          self.backend.close if own else None, self.runs.remove,
                          self.view.remove, self.controls.remove, self._lane.close,
                          self.base.remove, self._gui.remove_all)


def _view_direction(base: np.ndarray, hand: np.ndarray) -> tuple[float, float, float]:
    """The camera's direction for any arm (what moves, not the body it stands on): from
    in front of where its hand reaches at rest (``base`` (4, 4) world <- base, ``hand``
    (3,) base frame), a little to one side and above. Seen so, a reaching arm shows its
    height rather than its length: it fills a narrow 3D view between docked panels too."""
    reach = (base @ np.append(hand, 1.0))[:2] - base[:2, 3]
    length = float(np.hypot(*reach))
    h = reach / length if length > 0.02 else np.array([1.0, 0.0])  # an arm standing up
    side = np.array([-h[1], h[0]])
    x, y = -h + 0.3 * side
    return float(x), float(y), -0.3


def _on_step(deg: float, lo: float, hi: float) -> float:
    """``deg`` on a joint slider's 0.5° step, inside its ends ``lo``..``hi``."""
    return float(np.clip(round(deg / SLIDER_STEP_DEG) * SLIDER_STEP_DEG, lo, hi))


def _wxyz(R: np.ndarray) -> np.ndarray:
    return vtf.SO3.from_matrix(R).wxyz


#: This lesson, as the lab lists it (:data:`armlab.app.lessons.catalog.LESSONS`).
LESSON = Lesson(name=NAME, title=TITLE, help=HELP, first_step=TRY, robots=ROBOTS, build=build,
                order=ORDER, private=PRIVATE)
