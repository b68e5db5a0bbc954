"""The hand's and the quadruped's challenge runs: each one a function of the settings, the
challenge and the robot alone (issue 50 item 3), as the compliance lesson's are
(:mod:`armlab.app.lessons.compliance_challenge`).

- **grasp**: the simulated hand is started again open and at rest around the lesson's
  object, a fresh controller with the student's force limit and approach speed
  (:meth:`armlab.control.grip_loop.GripLoop.restart`, inside one period); the close
  follows :data:`CLOSE_DELAY` periods later, and the grasp's figures are worked out over
  the :data:`GRASP_S` s of periods from the close (times counted k · period), never up
  to "now".
- **walk**: the simulated quadruped is started again standing at rest at the gait's
  start pose, at the origin (:class:`armlab.control.restart.RestartableArm` around its
  servos, the gait loop reset in the same period); it stands up, walks forward from
  :data:`WALK_DELAY` periods after the restart, is told to stop ``walk_s`` of loop time
  later (in periods, whatever the wall clock did) and stands again within a cycle; eq.
  4.1 is worked out over that fixed window of periods.

Two runs with the same settings give the same figures for every student, on a loaded
machine, after any earlier runs. The figures are tagged with the challenge's key
(:meth:`RestartRuns.tags`): only a run made as the challenge's run counts for it (a
student's private hand in a class is restarted in the class's worker, the restart a
command of its loop; a class's quadruped, a student's private one or the shared one of
a simulated class, is restarted there too, its row of the batch reset in place
(:meth:`armlab.app.workers.class_quadrupeds.ClassQuadrupeds.restart`, the worker's
``quad_restart``), its restart's count and period mirrored in its ``GaitStatus``). A
robot that cannot be put back (real servos) walks from where it is, stopped ``walk_s``
of loop time later, and the page says so.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from armlab.app.lessons.compliance_challenge import KEEP, refuse_while, window
from armlab.control.challenges import Challenge
from armlab.control.commands import Reset
from armlab.control.gait_loop import SetPlan, StopWalking, Walk
from armlab.control.grip import GraspTrace, grasp_figures
from armlab.control.grip_loop import CloseHand
from armlab.control.restart import RestartableArm
from armlab.control.walking import Walker

#: periods from the hand's restart to its close (the close is applied one more later)
CLOSE_DELAY = 10
#: s of the grasp's window, from the close
GRASP_S = 6.0
#: s the quadruped stands up before it walks (the gait loop's rise is 1.5 s)
STAND_S = 2.0
#: periods the quadruped's window goes on after its last cycle could have ended
WALK_TAIL = 5
#: the figures each kind of run measures (what its tag covers)
FIGURES = {"grasp": ("grasp_force_n", "grasp_peak_n", "grasp_held"),
           "walk": ("eq41_error_pct",)}
_NUMBERS = itertools.count(1)
#: what the page says of a run that cannot start from the challenge's state
NOT_RESTARTED = {
    "grasp": "this hand cannot be put back open at rest, so the grasp starts from the "
             "hand as it is",
    "walk": "this robot cannot be put back at the start (real servos), so this walk "
            "starts where it is and is judged from its own start",
}


@dataclass
class Pending:
    """A challenge run started and not measured yet: its challenge, kind, the restart's
    number (None: not restarted), loop time of the restart (None until known), what the
    page calls it, and the periods from the restart to its window (``delay``) and of
    the window (``length``)."""

    challenge: Challenge
    kind: str
    number: int | None
    label: str
    delay: int
    length: int
    t0: float | None = None
    stop_at: float | None = None  #: (not restarted: a walk) loop time to stop at


class RestartRuns:
    """A hand or quadruped lesson's challenge runs (module docstring).

    Args:
        lesson: the :class:`~armlab.app.lessons.hand.HandLesson` or
            :class:`~armlab.app.lessons.quadruped.QuadrupedLesson`.
        kind: "grasp" or "walk".
    """

    def __init__(self, lesson: Any, kind: str) -> None:
        self.lesson = lesson
        self.kind = kind
        self.pending: Pending | None = None
        self._key: str | None = None  #: the challenge whose run measured the figures now
        #: the challenge runs measured, newest last (at most KEEP): (number, figures, tags)
        self.results: list[tuple[int, dict[str, float | None], dict[str, str | None]]] = []

    def tags(self) -> dict[str, str | None]:
        """Per figure, the key of the challenge whose run measured it (None: another run)."""
        return dict.fromkeys(FIGURES[self.kind], self._key)

    def untag(self) -> None:
        """The lesson's figures now come from another run."""
        self._key = None

    def busy(self) -> None:
        """Raise ValueError while a challenge's run is going on."""
        refuse_while(self.pending)

    def cancel(self, why: str) -> None:
        """Cut the run going on short (it counts for nothing)."""
        run, self.pending = self.pending, None
        if run is None:
            return
        loop = self.lesson.loop
        backend = getattr(self.lesson, "backend", None)
        if isinstance(backend, RestartableArm):
            backend.cancel()
        cancel_plan = getattr(loop, "cancel_plan", None)
        if callable(cancel_plan):
            cancel_plan()
        if run.t0 is not None:
            self.lesson.runs.finish_run(None, t=loop.status.t)
        self.lesson.challenge_text = f"**Challenge run** ({run.label}): cut short by {why}"

    # -- starting ----------------------------------------------------------------------

    def start(self, challenge: Challenge) -> str:
        """Start ``challenge``'s run; what was started, for a person (ValueError when it
        cannot be)."""
        self.busy()
        run = self._start_grasp(challenge) if self.kind == "grasp" else self._start_walk(
            challenge)
        self.pending = run
        self.untag()
        return run.label

    def _start_grasp(self, challenge: Challenge) -> Pending:
        loop = self.lesson.loop
        if loop.status.fault:
            raise ValueError(f"the hand is stopped: {loop.status.fault}")
        length = int(round(GRASP_S / loop.dt))
        label = f"a grasp with F = {loop.params.force_limit:g} N"
        if callable(getattr(loop, "restart", None)):
            number = loop.restart([(CLOSE_DELAY, CloseHand())])
            return Pending(challenge, "grasp", number, label, CLOSE_DELAY + 1, length)
        # a hand that cannot be put back: from where it is (it must be open)
        if any(m not in ("idle", "opening") for m in loop.status.modes):
            raise ValueError("open the hand first (Open), then run the challenge")
        self.lesson.runs.post(loop, CloseHand(), run=f"challenge {label}")
        return Pending(challenge, "grasp", None, f"{label} ({NOT_RESTARTED['grasp']})", 0,
                       length, t0=loop.status.t)

    def _start_walk(self, challenge: Challenge) -> Pending:
        lesson = self.lesson
        loop = lesson.loop
        st = loop.status
        if not lesson.has_servos:
            raise ValueError("no servos: eq. 4.1 needs the servos' feedback")
        if st.fault:
            raise ValueError(f"the servos are stopped ({st.fault}): press Reset first")
        walk_s = challenge.run.walk_s
        period = float(getattr(loop, "period", 0.02))
        plan = lesson._replan(replace(lesson.spec, command="forward"))
        walk_n = int(round(walk_s / period))
        cycle_n = int(math.ceil(1.0 / (st.speed * period)))
        label = f"a walk forward of {walk_s:g} s"
        backend = getattr(lesson, "backend", None)
        remote = callable(getattr(loop, "restart", None))  # a robot in the class's worker
        lesson._walk_from = None  # (a walk going on is not measured: the run replaces it)
        if isinstance(backend, RestartableArm) or remote:
            delay = int(round(STAND_S / period))
            q0 = Walker(plan).state().q  # standing at the gait's start, at the origin
            timed = [(delay, Walk(plan)), (delay + walk_n, StopWalking())]
            if remote:  # its servos restarted in the worker, SetPlan and Reset with them
                number = loop.restart(q0, plan, timed)
            else:
                assert isinstance(backend, RestartableArm)  # (not remote: the branch's case)
                number = backend.restart(q0, timed, loop.post)
                loop.post(SetPlan(plan))  # (the walker's start is this plan's: Reset takes it)
                loop.post(Reset())
            return Pending(challenge, "walk", number, label, 0,
                           delay + 2 + walk_n + cycle_n + WALK_TAIL)
        # real servos: from where it is, stopped in loop time
        t0 = st.t
        lesson.runs.begin_run(f"challenge {label}", t=t0)
        loop.go(plan)
        return Pending(challenge, "walk", None, f"{label} ({NOT_RESTARTED['walk']})", 0,
                       walk_n + cycle_n + WALK_TAIL, t0=t0, stop_at=t0 + walk_s)

    # -- measuring ---------------------------------------------------------------------

    def measure(self) -> bool:
        """Measure the run going on once its window is recorded (the lesson's publisher
        calls this at each tick); whether one is going on (still or just measured)."""
        run = self.pending
        if run is None:
            return False
        if run.t0 is None:
            at = self._restarted(run)
            if at is None:
                return True
            run.t0 = at
            self.lesson.runs.begin_run(f"challenge {run.label}", t=at)
        if self.kind == "grasp":
            self._measure_grasp(run)
        else:
            self._measure_walk(run)
        return True

    def _restarted(self, run: Pending) -> float | None:
        """Loop time of the run's restart once done (None: not yet)."""
        if self.kind == "grasp":
            st = self.lesson.loop.status
            done, at = st.restarts, st.restarted_at
        elif isinstance(self.lesson.backend, RestartableArm):
            done, at = self.lesson.backend.restarts, self.lesson.backend.restarted_at
        else:  # a robot in the class's worker: as its mirrored status says
            st = self.lesson.loop.status
            done, at = st.restarts, st.restarted_at
        if run.number is None or done < run.number:
            return None
        return at

    def _done(self, figures: dict[str, float | None], t: float) -> None:
        run, self.pending = self.pending, None
        assert run is not None
        self._key = run.challenge.key
        self.results.append((next(_NUMBERS), dict(figures), self.tags()))
        del self.results[:-KEEP]
        self.lesson.runs.finish_run(figures, t=t)
        self.lesson.challenge_text = ""

    def _measure_grasp(self, run: Pending) -> None:
        loop, lesson = self.lesson.loop, self.lesson
        st = loop.status
        dt = loop.dt
        assert run.t0 is not None
        if st.t < run.t0 + (run.delay + run.length + 2) * dt:
            return
        snap = loop.snapshot()
        t = snap["t"]
        i = int(np.searchsorted(t, run.t0, side="right")) + run.delay
        if i == run.delay and len(t) > 0 and t[0] > run.t0 + 1.5 * dt:  # (its start gone)
            self.cancel("a record that lost its rows")
            return
        if len(t) < i + run.length:
            return
        rows = slice(i, i + run.length)
        trace = GraspTrace((np.arange(run.length) + 1) * dt, snap["voltage"][rows],
                           snap["current"][rows], snap["force"][rows], snap["estimate"][rows])
        limit = float(loop.params.force_limit)
        fig = grasp_figures(trace, limit)
        held = fig["time_to_grasp_s"] is not None
        lesson._grasp = (st.closed_at, fig)
        lesson._settled = (st.closed_at, fig, held)
        self._done(lesson.grasp_figures(), st.t)

    def _measure_walk(self, run: Pending) -> None:
        lesson = self.lesson
        loop = lesson.loop
        st = loop.status
        period = float(getattr(loop, "period", 0.02))
        assert run.t0 is not None
        if run.stop_at is not None and st.t >= run.stop_at:
            run.stop_at = None
            loop.post(StopWalking())
        if st.t < run.t0 + (run.length + 1) * period:
            return
        snap: dict[str, np.ndarray] | None = loop.snapshot(st.t - run.t0 + 1.0)
        if run.number is not None:
            assert snap is not None  # (a loop that has run its periods has rows)
            snap = window(snap, run.t0, run.length, period)
        else:  # (from where it was: its rows from its start)
            assert snap is not None
            keep = snap["t"] >= run.t0 - 0.5 * period
            snap = {k: v[keep][:run.length] for k, v in snap.items()}
        if snap is None:
            self.cancel("a record that lost its rows")
            return
        err = loop.angle_error_of(snap)
        lesson._walk_error = None if err is None else float(err["mean_pct"])
        lesson._walk_from = None
        self._done({"eq41_error_pct": lesson._walk_error}, st.t)


__all__ = ["RestartRuns", "FIGURES", "GRASP_S", "CLOSE_DELAY", "STAND_S"]
