"""The any-arm lesson's compliance and redundancy controls (composed by
:mod:`armlab.app.lessons.arm`).

The receptionist arm's compliance lesson on any arm, from its reusable pieces:

- a **Gains** tab: :class:`~armlab.app.lessons.compliance_controls.GainControls` (Kp, Kv, M_env,
  D_env, K_env, K_f, the period, presets, guarded inputs) applied to the arm's loop by
  :func:`~armlab.app.lessons.compliance_controls.apply_gains`, the gain warning under the status;
- a **Push** tab: :class:`~armlab.app.lessons.compliance_push.PushControls` with directions
  that mean the same on any arm (away from its base, sideways, down, ...); once the arm
  has come back the push is measured (:func:`armlab.control.response.hand_excursion`,
  :func:`armlab.control.response.measure_push`). Real servos are pushed by hand: the purple
  arrow and the τ_ext chart show what the controller estimates;
- a **Spare joints** tab, seed 002 on an n-joint arm: what the joints that the hand's
  position (3 coordinates) leaves free aim for while the hand follows its target
  (:class:`armlab.control.commands.UseSpareJoints`), with the manipulability and the nearest
  joint limit read out; an arm of 3 joints or fewer is told why it has none;
- the **Live charts** panel (:class:`~armlab.app.lessons.compliance_plots.JointPlots`, any one
  joint of the n) and the force arrows at the hand
  (:class:`~armlab.app.lessons.compliance_scene.ForceArrows`).

UI callbacks only post commands and swap parameters; the publisher's frames read the
loop's recorder and status (:meth:`ArmControls.pose_frame`, :meth:`ArmControls.plot_frame`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
import viser

from armlab.app.lessons._common import LessonGui, esc, guarded, set_content
from armlab.app.lessons.compliance_controls import GainControls, apply_gains, show_gain_warning
from armlab.app.lessons.compliance_plots import JointPlots
from armlab.app.lessons.compliance_push import PushControls
from armlab.app.lessons.compliance_scene import ForceArrows, estimated_hand_force
from armlab.app.lessons.compliance_teach import (
    design_table,
    equations_markdown,
    latest_values,
    measured_line,
)
from armlab.app.lessons.law_view import LawView, law_loop_of, reference_angle
from armlab.app.page.inputs import guarded_slider
from armlab.app.page.surface import Surface
from armlab.control.backend import Backend, Pushable
from armlab.control.commands import MAX_NULL_SPACE_GAIN, Push, UseSpareJoints
from armlab.control.loop import ControlLoop
from armlab.control.response import Measured, hand_excursion, measure_push
from armlab.kinematics.fk import fk_and_jacobian
from armlab.kinematics.model import SerialChain
from armlab.kinematics.redundancy import POSITION_ROWS, manipulability, task_jacobian

#: Push directions offered on any arm, seen from its base (see :func:`push_direction`).
PUSH_DIRECTIONS = ("down (with gravity)", "up", "away from the base", "towards the base",
                   "sideways, left (seen from the base)", "sideways, right (seen from the base)")
#: s after a push ends before it is measured (the arm comes back)
SETTLE_S = 2.0
#: The spare joints' aims as the dropdown shows them (keys of armlab.kinematics.redundancy.AIMS).
AIM_LABELS = {"off": "off (plain RMRC)", "limits": "away from the joint limits",
              "manipulability": "more manipulability", "both": "both"}
#: cm³ per m³: w of a position task (3 rows of metres) is shown in cm³
CM3_PER_M3 = 1e6


def push_direction(label: str, hand: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """The unit vector (3,), base frame, of the push direction ``label`` (one of
    :data:`PUSH_DIRECTIONS`) for a hand at ``hand`` (3,) m.

    "Down" is along ``gravity`` (−z without gravity); "away from the base" is the hand's
    horizontal direction from the base (the base's x axis for a hand right above it);
    "left" is to the left of that, seen from the base.

    Raises:
        ValueError: an unknown label.
    """
    if label not in PUSH_DIRECTIONS:
        raise ValueError(f"push direction: unknown {label!r}; known: {', '.join(PUSH_DIRECTIONS)}")
    g = np.asarray(gravity, dtype=float)
    down = g / np.linalg.norm(g) if np.linalg.norm(g) > 1e-9 else np.array([0.0, 0.0, -1.0])
    hand = np.asarray(hand, dtype=float)
    out = hand - (hand @ down) * down
    if np.linalg.norm(out) < 0.01:  # the hand right above (or below) the base
        out = np.array([1.0, 0.0, 0.0]) - down[0] * down
    out /= np.linalg.norm(out)
    left = np.cross(out, down)
    return {PUSH_DIRECTIONS[0]: down, PUSH_DIRECTIONS[1]: -down, PUSH_DIRECTIONS[2]: out,
            PUSH_DIRECTIONS[3]: -out, PUSH_DIRECTIONS[4]: left, PUSH_DIRECTIONS[5]: -left}[label]


def nearest_limit(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[int, float]:
    """(index of the joint nearest one of its limits, its distance to it, rad)."""
    gap = np.minimum(np.asarray(q) - lower, upper - np.asarray(q))
    j = int(np.argmin(gap))
    return j, float(gap[j])


def spare_readout(model: SerialChain, q: np.ndarray, lower: np.ndarray,
                  upper: np.ndarray) -> str:
    """One line for the Spare joints tab: manipulability of the hand position at ``q``
    (seed 002 §2, in cm³) and the joint nearest one of its limits (degrees)."""
    w = manipulability(task_jacobian(model, q, POSITION_ROWS)) * CM3_PER_M3
    j, gap = nearest_limit(q, lower, upper)
    return (f"manipulability w = √det(J Jᵀ) = **{w:.0f} cm³** · nearest limit: "
            f"**{esc(model.joint_names[j])}**, {math.degrees(gap):.1f}° away")


#: The label of a push's run (Save run).
PUSH_RUN = "push"


@dataclass(frozen=True)
class PushRun:
    """A push given: force (3,) N base frame, loop times it began and ends, its label."""

    force: np.ndarray
    t0: float
    t1: float
    label: str


class ArmControls:
    """The Gains, Push and Spare joints tabs, the live charts and the hand's force arrows
    of the any-arm lesson.

    Args:
        server: the viser server.
        lesson_gui: the lesson's top-level GUI (the warning line and the charts panel are
            kept there, to be removed with the lesson).
        tabs: the lesson's tab group; the three tabs are added to it in turn.
        model, backend, loop: the arm.
        base_node: the scene node of the arm's base frame (the arrows hang there).
        place_target: called with the hand position (3,) m, base frame, when turning the
            spare joints on makes the hand's place its target (to move the target there).
    """

    def __init__(self, server: Surface, lesson_gui: LessonGui,
                 tabs: viser.GuiTabGroupHandle, *, model: SerialChain, backend: Backend,
                 loop: ControlLoop, base_node: str,
                 place_target: Callable[[np.ndarray], None]) -> None:
        gui = server.gui
        self.model, self.backend, self.loop = model, backend, loop
        self.servos = not isinstance(backend, Pushable)  # real (or emulated) servos
        self._place_target = place_target
        self._aim = loop.spare_joints  # the spare joints' aim last posted
        self._push: PushRun | None = None
        self._measured: PushRun | None = None  # the push last measured
        #: told of each command posted here, with its loop time (the lesson's run file)
        self.on_post: Callable[..., None] | None = None
        #: told, with its label and loop time, of a command that begins a run (a push)
        self.on_run: Callable[[str, float], None] | None = None
        #: the push last measured and its figures (those the Push tab shows; {}: not
        #: measured), for its run file
        self.push_figures: tuple[PushRun, dict[str, float | None]] | None = None
        self.measured_env: Measured | None = None
        self._last_teach = 0.0
        self.warning = lesson_gui.add(gui.add_html("", order=-79.0, visible=False))
        with tabs.add_tab("Gains", viser.Icon.ADJUSTMENTS):
            #: the student's own law (``armlab serve --exercise``): its note, error, ghost
            law = law_loop_of(loop)
            self.law_view = None if law is None else LawView(server, gui, law.law,
                                                             root="/arm_reference")
            self.gains = GainControls(gui, loop.params, apply=lambda p: apply_gains(
                self.loop, p, warning=self.warning))
        show_gain_warning(self.warning, loop.gains)
        with tabs.add_tab("Push", viser.Icon.HAND_FINGER):
            gui.add_markdown(
                "Push the **real arm by hand**: the purple arrow and the τ_ext chart show "
                "the external torque the controller estimates (eq. 2.23)." if self.servos
                else "Push the hand: the compliant arm gives way and comes back (eq. 2.6/2.7; "
                     "untick **Compliance on** in Gains to feel the plain PD loop).")
            self.pushes = PushControls(gui, PUSH_DIRECTIONS, servos=self.servos,
                                       on_push=self.push, force=2.0, duration=1.5)
        with tabs.add_tab("Spare joints", viser.Icon.ROUTE):
            self._build_spare(gui)
        with lesson_gui.chart_panel("Live charts") as charts:
            self.plots = JointPlots(gui, charts, model.joint_names,
                                    default_joint=min(1, model.n - 1),
                                    reference=self.law_view is not None)
        self.arrows = ForceArrows(server.scene, base_node)

    # ================================================================== GUI

    def _build_spare(self, gui: viser.GuiApi) -> None:
        n = self.model.n
        spare = n - len(POSITION_ROWS)
        self.spare_readout: viser.GuiMarkdownHandle | None = None
        if spare <= 0:
            gui.add_markdown(
                f"**No spare joints.** The hand's position has 3 coordinates and this arm "
                f"has {n} joint{'s' if n > 1 else ''}: none is left over for a second aim "
                "while the hand follows its target (seed 002 needs more joints than task "
                "coordinates; the redundancy lesson shows it on a planar 3-joint arm).")
            return
        gui.add_markdown(
            f"This arm has {n} joints and the hand's position needs 3: **{spare} spare**. "
            "While the hand follows the orange target they can aim for something else "
            "without moving it: θ̇ = J⁺ẋ + (I − J⁺J) k_a ∇H (seed 002 eq. 4, 6). A joint "
            "slider lets go of the target; drag it again to go on.")
        now = self._aim
        self.aim = gui.add_dropdown("Spare joints aim", tuple(AIM_LABELS.values()),
                                    initial_value=AIM_LABELS[now.aim],
                                    hint="Turned on while the arm holds, the hand stays where "
                                         "it is and the other joints move")
        self.gain = guarded_slider(gui, "Null-space gain k_a (1/s)", name="null-space gain",
                                   lo=0.0, hi=MAX_NULL_SPACE_GAIN, step=0.1,
                                   initial=now.gain, apply=self._set_gain,
                                   hint="How fast the spare joints move towards the aim "
                                        "(seed 002 eq. 2)")
        self.aim.on_update(lambda e: guarded(e, self._set_aim, undo=self._show_aim))
        self.spare_readout = gui.add_markdown("")

    def _set_aim(self) -> None:
        aim = next(k for k, v in AIM_LABELS.items() if v == self.aim.value)
        if aim == self._aim.aim:
            return
        # the target is placed first: a drag that starts once the loop holds the new aim
        # (all a page can see) must not have its target moved back by this call
        snap = self.loop.recorder.snapshot(0.1)
        if aim != "off" and self.loop.status.trajectory is None and len(snap["t"]) \
                and np.all(np.isfinite(snap["q_cmd"][-1])):
            self._place_target(self.model.fk(snap["q_cmd"][-1])[:3, 3])
        self._post_aim(UseSpareJoints(aim, self._aim.gain))

    def _show_aim(self) -> None:
        self.aim.value = AIM_LABELS[self._aim.aim]  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none

    def _set_gain(self, gain: float) -> None:
        self._post_aim(UseSpareJoints(self._aim.aim, gain))

    def _post_aim(self, cmd: UseSpareJoints) -> None:
        self.loop.post(cmd)
        self._aim = cmd

    def add_teach(self, gui: viser.GuiApi) -> None:
        """Add the control law with live numbers and the design figures (inside the
        lesson's Teach tab)."""
        self.equations = gui.add_markdown("")
        self.design = gui.add_markdown(design_table(self.loop.params, None, None))

    # ================================================================== actions

    def refuse_while_law_fails(self, what: str) -> None:
        """Raise ValueError (the page shows it) while the student's law fails
        (``armlab serve --exercise``): ``what`` would run on a law that does not work."""
        if self.law_view is not None:
            self.law_view.refuse_commands(what)

    def failing_state(self) -> str | None:
        """The status's state while the student's law fails (shown in its error's red),
        or None."""
        return None if self.law_view is None else self.law_view.failing_state()

    def push(self) -> None:
        """Push the hand as the Push tab says (the simulated arm)."""
        if self.servos:
            raise ValueError("real servos: push the arm by hand")
        self.refuse_while_law_fails("Push")
        snap = self.loop.recorder.snapshot(0.2)
        if not len(snap["t"]) or not np.all(np.isfinite(snap["q"][-1])):
            raise ValueError("the arm has not been read yet; try again")
        pushes = self.pushes
        hand = self.model.fk(snap["q"][-1])[:3, 3]
        force = pushes.force * push_direction(pushes.direction, hand, self.model.gravity)
        t0 = self.loop.status.t
        push = Push(force, link=self.model.n - 1, point=self.model.tip[:3, 3],
                    duration=pushes.duration)
        self.loop.post(push)
        self._push = PushRun(force, t0, t0 + pushes.duration,
                             f"push of {pushes.force:g} N {pushes.direction} for "
                             f"{pushes.duration:g} s")
        if self.on_run is not None:  # (the lesson's run file: a push is a run)
            self.on_run(PUSH_RUN, t0)
        if self.on_post is not None:
            self.on_post(push, t=t0)

    @property
    def last_push(self) -> PushRun | None:
        """The push last given (None: none yet)."""
        return self._push

    # ================================================================== frames

    def pose_frame(self, snap: dict[str, np.ndarray]) -> None:
        """Draw the force arrows at the hand for the newest sample of ``snap`` (its angles
        finite: the lesson draws only those)."""
        q = snap["q"][-1]
        T, J = fk_and_jacobian(self.model, q)
        push = self._push
        applied = push.force if push is not None and push.t0 <= snap["t"][-1] <= push.t1 \
            else None
        self.arrows.set(T[:3, 3], applied, estimated_hand_force(J, snap["tau_ext"][-1]))
        law = law_loop_of(self.loop)
        if law is not None and self.law_view is not None:
            self.law_view.draw(law, self.model)

    def law_note(self) -> str:
        """The student's law's error line for the status ("" without one)."""
        return "" if self.law_view is None else self.law_view.status_extra()

    def status_note(self) -> str:
        """" · pushing 2 N (1.2 s left)" while a push acts, else ""."""
        push, t = self._push, self.loop.status.t
        if push is None or not push.t0 <= t <= push.t1:
            return ""
        return f" · pushing {np.linalg.norm(push.force):.3g} N ({push.t1 - t:.1f} s left)"

    def plot_frame(self, force: bool) -> None:
        """Charts, the spare joints' readout and the Teach tab (twice a second)."""
        loop = self.loop
        snap = loop.recorder.snapshot(self.plots.window_s + 0.5)
        law = law_loop_of(loop)
        self.plots.update(snap, force=force, reference=None if law is None
                          else partial(reference_angle, law))
        if not len(snap["t"]):
            return
        q = snap["q"][-1]
        if self.spare_readout is not None and np.all(np.isfinite(q)):
            set_content(self.spare_readout, spare_readout(self.model, q, loop.lower, loop.upper))
        now = time.monotonic()
        if force or now - self._last_teach > 0.5:
            self._last_teach = now
            self._update_teach(snap)

    def _update_teach(self, snap: dict[str, np.ndarray]) -> None:
        j = self.plots.joint
        params = self.loop.params
        live = latest_values(snap, j, self.plots.labels[j])
        set_content(self.equations, equations_markdown(params, live, torque_unit=self.plots.unit,
                                                       mode=self.loop.status.controller))
        set_content(self.design, design_table(params, None, self.measured_env))

    def measure(self) -> None:
        """The last push's figures, once it is over (the publisher calls this at each of
        its ticks)."""
        push = self._push
        if push is None or push is self._measured:
            return  # (the loop's status is read only while a push waits to be measured)
        t = self.loop.status.t
        if t < push.t1 + SETTLE_S:
            return
        self._measured = push
        snap = self.loop.recorder.snapshot(t - push.t0 + 0.2)
        try:
            most, last = hand_excursion(self.model, snap, t0=push.t0)
        except ValueError as exc:
            set_content(self.pushes.result, f"**Last push**: not measured: {esc(str(exc))}")
            self.push_figures = (push, {})
            return
        figures: dict[str, float | None] = {
            "push_n": float(np.linalg.norm(push.force)), "hand_gave_way_cm": 100 * most,
            "hand_back_mm": 1000 * last}
        text = (f"**Last push** ({esc(push.label)}): the hand gave way "
                f"**{100 * most:.1f} cm** and came back to {1000 * last:.1f} mm from where "
                "it was.")
        try:
            self.measured_env = measure_push(snap, t0=push.t0, t1=push.t1, what=push.label,
                                             joint_labels=self.plots.labels,
                                             params=self.loop.params)
            text += "\n\n" + measured_line(self.measured_env)
            m = self.measured_env
            figures.update({"peak_time_s": m.peak_time_s, "overshoot_pct": m.overshoot_pct,
                            "settling_s": m.settling_time_s,
                            "static_gain_rad_per_nm": m.static_gain})
        except ValueError:  # compliance off: no θ_env to measure
            pass
        set_content(self.pushes.result, text)
        self.push_figures = (push, figures)

    def remove(self) -> None:
        """Remove the force arrows and the reference ghost (the GUI goes with the lesson's
        tabs and panels)."""
        self.arrows.remove()
        if self.law_view is not None:
            self.law_view.remove()
