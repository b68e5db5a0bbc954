"""The compliance lesson's challenge runs: each one a function of the gains, the challenge
and the robot alone (issue 50 item 3).

A challenge's run (a step, the thesis line under a push, a push on the holding arm)
starts from the challenge's own state: the simulated arm is started again at the
thesis line's first pose, at rest, its controller reset
(:class:`armlab.control.restart.RestartableArm`; a private arm's in the class's worker),
and the run's commands follow at fixed numbers of periods from that instant. It is
measured on loop time over a fixed window of periods from the restart, never up to
"now", so two runs with the same gains give the same figures for every student, on a
loaded machine, after any earlier runs. The contact challenge's run is ``armlab experiment
contact``'s (:func:`armlab.control.experiments.contact.contact_plan`: the hand into a
wall across the thesis line, in the restarted arm's world only:
:meth:`armlab.control.restart.RestartableArm.meet_wall`; a private arm's, or a classroom's
shared arm's, in its worker: ``RemoteBackend.meet_wall``), judged by the same
:func:`~armlab.control.experiments.contact.contact_figures` on the wall's force the loop
records every period (``f_contact``, ``f_contact_peak``): the experiment's figures for
the same wall and gains. A real (serial) arm cannot be put back: its
challenge run starts from where the arm is, is judged from the run's own start, and the
page says so.

The figures it measures are the lesson's own (the page shows them as a Step or Push
would), tagged with the challenge's key (:meth:`ChallengeRuns.tags`): only a run made as
that challenge's run counts for it (:class:`armlab.control.challenges.RunLog`). While one
runs, the lesson's Step, Run thesis line and Push are refused; a drag, a target, new
gains, Stop, Reset or E-STOP cut it short (not counted).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.control.backend import BackendError, Touchable, WallSetting
from armlab.control.challenges import Challenge
from armlab.control.commands import Command, Push, Reset, RunTrajectory
from armlab.control.experiments.contact import (
    LEAD,
    check_wall_numbers,
    contact_plan,
    joint_stiffness,
    predicted_force,
    recorded_contact,
)
from armlab.control.response import line_errors, measure_push, measure_step, plan_step
from armlab.control.restart import RestartableArm
from armlab.control.trajectory import JointTrajectory, hold

#: s the arm holds the challenge's start pose after its restart, before the run's commands
HOLD_S = 1.0
#: s the thesis line's window goes on after the line and the push have ended
LINE_TAIL_S = 0.5
#: the figures each kind of run measures (what its tag covers)
FIGURES = {
    "step": ("overshoot_pct", "settling_s", "step_joint"),
    "line_push": ("pushed_error_deg", "yield_deg", "line_push_n"),
    "push": ("push_n", "stiffness_nm_per_rad"),
    "contact": ("contact_peak_n", "contact_steady_n"),
}
#: challenge runs a lesson keeps for its readers
KEEP = 50
_NUMBERS = itertools.count(1)
#: what the page says of a real arm's challenge run
SERVOS_NOTE = ("real servos: the arm cannot be put back at the challenge's pose, so this "
               "run starts where the arm is and is judged from its own start")


@dataclass
class PendingRun:
    """A challenge run started and not measured yet.

    Attributes:
        challenge: the challenge it runs for. kind: its run's kind.
        number: the restart's number (None: a real arm, not restarted).
        t0: loop time of its first period (the restart's; None until known).
        delay: periods from the restart to the period its commands are applied.
        length: periods it is measured over, from the restart's.
        force_n: the push's force (line_push, push). joint, q0, q1: the step's.
        label: what the page calls it.
        predicted_n: contact: the steady force the law's stiffness predicts (None: PD).
    """

    challenge: Challenge
    kind: str
    number: int | None
    t0: float | None
    delay: int
    length: int
    label: str
    force_n: float = 0.0
    joint: int = -1
    q0: float = 0.0
    q1: float = 0.0
    predicted_n: float | None = None


def restart_arm(backend: Any, loop: Any, q: np.ndarray,
                plan: list[tuple[int, Command]]) -> int | None:
    """Start the simulated arm behind ``backend`` again at ``q`` at rest, its controller
    reset, then ``plan``'s (periods, command); the restart's number, or None when the arm
    cannot be put back (real servos)."""
    if isinstance(backend, RestartableArm):
        post = loop.post
        twin = getattr(loop, "restart_reference", None)  # serve --exercise: the ghost's arm
        if twin is not None:  # started again with it, the plan at the same periods
            twin(q, plan)
            post = loop.post_student
        number = backend.restart(q, plan, post)
        loop.post(Reset())
        return number
    remote = getattr(backend, "restart", None)  # a private arm in the class's worker
    return None if remote is None else int(remote(q, plan))


def steady_end(line: JointTrajectory, period: float) -> JointTrajectory:
    """``line`` then two periods at rest at its end: the loop samples a trajectory at
    t − t_start in its absolute time, whose last bits differ from run to run; at the end of
    a trajectory moving to the last sample (θ̇, θ̈ ≠ 0) they decide whether a period gets
    the last segment or the end at rest. Ending at rest, both give the same command."""
    return line.then(hold(line.q[-1], 2.0 * period, dt=period), name=line.name)


def can_restart(backend: Any) -> bool:
    """Whether the arm behind ``backend`` can be put back at a pose (a simulated one)."""
    return isinstance(backend, RestartableArm) or callable(getattr(backend, "restart", None))


def restarted(backend: Any) -> tuple[int, float | None]:
    """(restarts done, loop time of the last one's period) of ``backend``."""
    if isinstance(backend, RestartableArm):
        return backend.restarts, backend.restarted_at
    return backend.restarted()


def window(snap: dict[str, np.ndarray], t0: float, length: int, period: float
           ) -> dict[str, np.ndarray] | None:
    """The rows of ``snap`` from the one at loop time ``t0`` on, ``length`` of them, their
    times counted from that row (k · ``period``: the same numbers whenever the run was
    made); None: not all recorded yet, or ``t0`` no longer in it."""
    t = snap["t"]
    i = int(np.searchsorted(t, t0))
    if i >= len(t) or t[i] != t0 or len(t) < i + length:
        return None
    rows = {k: v[i:i + length] for k, v in snap.items()}
    rows["t"] = np.arange(length) * period
    return rows


def refuse_while(pending: Any) -> None:
    """Raise ValueError while a challenge's run ``pending`` (its ``label``) goes on: a
    lesson's own commands wait for its figures (every lesson's challenge runs say so)."""
    if pending is not None:
        raise ValueError(f"the challenge's run ({pending.label}) is going on: wait "
                         "for its figures")


class ChallengeRuns:
    """A compliance lesson's challenge runs (module docstring).

    Args:
        lesson: the :class:`armlab.app.lessons.compliance.ComplianceLesson`.
    """

    def __init__(self, lesson: Any) -> None:
        self.lesson = lesson
        self.pending: PendingRun | None = None
        self._tags: dict[str, str | None] = {}
        #: the challenge runs measured, newest last (at most :data:`KEEP`): (number, the
        #: lesson's figures then, their tags), for a reader that may look rarely; the
        #: numbers grow across the lessons of this process (a seat's reopened lesson)
        self.results: list[tuple[int, dict[str, float | None], dict[str, str | None]]] = []
        self._measured = 0

    def tags(self) -> dict[str, str | None]:
        """Per figure, the key of the challenge whose run measured it (None: another run)."""
        return dict(self._tags)

    def untag(self, kind: str) -> None:
        """Figures of ``kind`` ("step", "line_push", "push") now come from another run."""
        for name in FIGURES[kind]:
            self._tags[name] = None

    def busy(self) -> None:
        """Raise ValueError while a challenge's run is going on (the person waits for it)."""
        refuse_while(self.pending)

    def cancel(self, why: str) -> None:
        """Cut the run going on short (it counts for nothing); ``why`` shown."""
        run, self.pending = self.pending, None
        if run is None:
            return
        rig = self.lesson.rig
        if rig is not None and isinstance(rig.backend, RestartableArm):
            rig.backend.cancel()
            twin = getattr(getattr(rig.loop, "reference", None), "backend", None)
            if isinstance(twin, RestartableArm):  # serve --exercise: the ghost's plan too
                twin.cancel()
        elif rig is not None and callable(getattr(rig.backend, "cancel", None)):
            try:  # a private arm in the class's worker: its plan stopped there
                rig.backend.cancel()
            except BackendError:  # (the worker ended: nothing is posted any more)
                pass
        if run.t0 is not None and rig is not None:  # its file ends here, unmeasured
            self.lesson.runs.finish_run(None, t=rig.loop.status.t)
        if run.kind == "contact":
            self.lesson.contact.end_challenge_wall()
        self.lesson.last_run_text = f"**Challenge run** ({run.label}): cut short by {why}"

    # -- starting ----------------------------------------------------------------------

    def start(self, challenge: Challenge) -> str:
        """Start ``challenge``'s run (a step, the line under a push, a push); what was
        started, for a person. ValueError when it cannot be (the arm stopped, ...)."""
        lesson = self.lesson
        rig = lesson.rig
        if rig is None:
            raise ValueError("the arm is being rebuilt; try again")
        self.busy()
        loop = rig.loop
        if loop.status.fault is not None or loop.status.link_down:
            raise ValueError("the arm is stopped: press Reset first")
        spec = challenge.run
        period = loop.params.period
        fresh = can_restart(rig.backend)
        delay = int(round(HOLD_S / period)) if fresh else 0
        q0 = np.asarray(rig.line.q[0], dtype=float)
        tip = dict(link=rig.model.n - 1, point=rig.model.tip[:3, 3])
        plan: list[tuple[int, Command]]
        if spec.kind == "step":
            joint = int(challenge.setting("step_joint") or 0)
            if not 0 <= joint < rig.model.n:
                raise ValueError(f"step: no joint {joint} (the arm has {rig.model.n})")
            label = lesson.joint_labels[joint]
            start = {"q_cmd": q0[None, :]} if fresh else loop.recorder.snapshot(0.2)
            step = plan_step(start, joint=joint,
                             step=math.radians(spec.step_deg), lower=loop.lower,
                             upper=loop.upper, params=loop.params, label=label)
            plan = [(delay, RunTrajectory(step.trajectory, approach=False))]
            run = PendingRun(challenge, "step", None, None, delay + 2,
                             delay + 2 + int(round(step.wait_s / period)),
                             f"step of {label} by {math.degrees(step.q1 - step.q0):+.0f}°",
                             joint=joint, q0=step.q0, q1=step.q1)
        elif spec.kind in ("line_push", "push"):
            if not lesson.pushable():
                raise ValueError("real servos: push the arm by hand (the lab cannot push "
                                 "them for a challenge)")
            figure = "line_push_n" if spec.kind == "line_push" else "push_n"
            force = float(challenge.setting(figure) or 4.0)
            push = Push(force * np.array((0.0, -1.0, 0.0)), duration=spec.push_s, **tip)
            span = spec.push_s
            if spec.kind == "line_push":
                plan = [(delay, RunTrajectory(steady_end(rig.line, period))), (delay, push)]
                span = max(span, rig.line.duration) + LINE_TAIL_S
                label = f"thesis line under a push of {force:g} N"
            else:
                plan = [(delay, push)]
                label = f"push of {force:g} N against the line (−y) for {spec.push_s:g} s"
            n = int(round(span / period)) + 1
            run = PendingRun(challenge, spec.kind, None, None, delay + 2, delay + 2 + n,
                             label, force_n=force)
        elif spec.kind == "contact":
            plan, run = self._contact_run(challenge, rig, period, fresh)
        else:
            raise ValueError(f"the {spec.kind} challenge runs in another lesson")
        run.number = restart_arm(rig.backend, loop, q0, plan) if fresh else None
        if run.number is None:  # real servos: from where the arm is, now
            run.t0 = loop.status.t
            for _, command in plan:
                lesson.runs.post(loop, command)
            run.label += f" ({SERVOS_NOTE})"
        self.pending = run
        lesson.experiment = None  # (an experiment of the lesson's own going on: replaced)
        self.untag(run.kind)  # (tagged again once measured)
        lesson.run_label = f"challenge {challenge.key}"
        return run.label

    def _contact_run(self, challenge: Challenge, rig: Any, period: float,
                     fresh: bool) -> tuple[list[tuple[int, Command]], PendingRun]:
        """The contact challenge's plan and pending run: its wall in the restarted arm's
        world (the Contact tab draws it), the experiment's command from the restart's third
        period (when the loop applies it)."""
        spec = challenge.run
        if not fresh:
            raise ValueError("real servos: the wall is virtual only in simulation for now "
                             "(open the lab on the simulated arm)")
        # a RestartableArm here, or in a worker (RemoteBackend): the restarted arm's wall
        meet_wall = getattr(rig.backend, "meet_wall", None)
        if not (isinstance(rig.backend, Touchable) and callable(meet_wall)):
            raise ValueError("this simulated arm's world holds no wall to start it again "
                             "against: run the challenge on the lab's simulated arm")
        check_wall_numbers(stiffness=spec.stiffness, damping=spec.damping,
                           names=("wall stiffness", "wall damping"))
        cp = contact_plan(rig.model, period, wall=spec.wall_cm / 100.0,
                          depth=spec.depth_cm / 100.0)
        params = rig.loop.params
        k_q = joint_stiffness(params, "compliance" if params.compliance else "pd")
        predicted = None if k_q is None else predicted_force(
            rig.model, cp.q_end, cp.normal, cp.depth, k_joint=k_q, k_wall=spec.stiffness)
        # the wall in the restarted arm's world only: the arm in use may be behind it
        meet_wall(WallSetting(cp.origin, cp.normal, spec.stiffness, spec.damping))
        self.lesson.contact.challenge_wall(rig, cp.origin, cp.normal)
        label = (f"into a wall {spec.wall_cm:g} cm ahead, {spec.stiffness:g} N/m, the "
                 f"command {spec.depth_cm:g} cm behind it")
        return ([(0, RunTrajectory(cp.plan, approach=False))],
                PendingRun(challenge, "contact", None, None, LEAD, LEAD + cp.periods, label,
                           predicted_n=predicted))

    # -- measuring ---------------------------------------------------------------------

    def measure(self) -> None:
        """Measure the run going on once its window is recorded (the lesson's publisher
        calls this at each of its ticks)."""
        run, rig = self.pending, self.lesson.rig
        if run is None or rig is None:
            return
        if run.t0 is None:
            done, at = restarted(rig.backend)
            if run.number is None or done < run.number or at is None:
                return
            run.t0 = at
            self.lesson.run_start = at
            # Save run keeps this run whole, from its restart (armlab.app.lessons.run_files)
            self.lesson.runs.begin_run(f"challenge {run.label}", t=at)
        loop = rig.loop
        period = loop.params.period
        if loop.status.t < run.t0 + (run.length + 1) * period:
            return
        snap = window(loop.recorder.snapshot(loop.status.t - run.t0 + 1.0), run.t0,
                      run.length, period)
        if snap is None:
            if loop.status.t > run.t0 + (run.length + 10) * period + 5.0:
                self.cancel("a record that lost its rows")
            return
        self.pending = None
        if run.kind == "contact":  # (its figures are of the record: the wall may go)
            self.lesson.contact.end_challenge_wall()
        try:
            self._take(run, snap)
        except ValueError as exc:
            self.lesson.last_run_text = (f"**Challenge run** ({run.label}): not measured: "
                                         f"{exc}")
            self.lesson.runs.finish_run(None, t=loop.status.t)
            return
        for name in FIGURES[run.kind]:
            self._tags[name] = run.challenge.key
        self._measured = next(_NUMBERS)
        figures = {k: None if v is None else float(v)
                   for k, v in self.lesson.run_figures().items()}
        self.results.append((self._measured, figures, self.tags()))
        del self.results[:-KEEP]
        self.lesson.runs.finish_run({name: figures.get(name) for name in FIGURES[run.kind]},
                                    t=loop.status.t)

    def _take(self, run: PendingRun, snap: dict[str, np.ndarray]) -> None:
        """The figures of ``run`` from its window ``snap``, into the lesson."""
        lesson = self.lesson
        rig = lesson.rig
        params = rig.loop.params if rig is not None else None  # (what they were run with)
        if run.kind == "step":
            lesson.take_step(measure_step(snap, t0=0.0, joint=run.joint, q0=run.q0,
                                          q1=run.q1, what=run.label, params=params),
                             run.joint)
        elif run.kind == "push":
            t = snap["t"]
            lesson.take_push(measure_push(snap, t0=t[run.delay], t1=t[-1], what=run.label,
                                          joint_labels=lesson.joint_labels, params=params),
                             run.force_n)
        elif run.kind == "contact":
            lesson.contact.take_challenge(recorded_contact(snap, start=run.delay),
                                          predicted=run.predicted_n, label=run.label)
        else:
            t = snap["t"]
            err = line_errors(snap, t0=t[run.delay]) * (180.0 / math.pi)
            lesson.take_pushed_line(err, snap["q"][run.delay:], run.force_n)
