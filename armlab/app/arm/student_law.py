"""A student's own law on their own arm: ``armlab serve --exercise FILE``.

:class:`StudentLaw` is the student's file, loaded (:func:`armlab.exercises.load_student`)
and watched: a thread polls its modification time and size and loads it again after each
save. Its :meth:`~StudentLaw.laws` are the equations a
:class:`~armlab.control.compliance.ComplianceController` runs, the student's function in
place of the lab's own (:data:`LIVE_EXERCISES` says which exercise replaces which), each
call checked: an exception, a wrong shape, NaN or a call slower than
:data:`BUDGET_FRACTION` of the period is the student's error (their file and line), shown
by the lesson and printed once in the terminal. Until the next save fixes it the arm
*holds*: on the simulated arm the lab's own PD law keeps it where it was when the error
came (torque on); on real servos (``servos=True``) the call raises, so the loop's fault
turns the torque off.

:class:`LawLoop` is the student's arm's loop with the reference beside it: a second,
simulated arm run by the lab's own law, ticked in the same thread right after theirs,
with the same commands and gains (the lesson draws it as a see-through ghost and charts
its angle).

Where student code runs: only in the lab it was given to (``--exercise`` is refused with
``--classroom``; no page can send code to a server).
"""

from __future__ import annotations

import gc
import os
import sys
import threading
import time
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from armlab.control.backend import Backend
from armlab.control.commands import Command, Stop
from armlab.control.compliance import Laws, environment_step, pd_reference_accel
from armlab.control.laws import compliance_accel, with_student
from armlab.control.loop import ControlLoop
from armlab.control.params import GainCheck, Params
from armlab.control.restart import RestartableArm
from armlab.exercises import StudentError, load_student
from armlab.exercises.core import Exercise
from armlab.exercises.student import Hang, locate
from armlab.kinematics.model import SerialChain

#: Exercise name -> the :class:`~armlab.control.compliance.Laws` field its function
#: replaces: the compliance controller's equations, run live by these lessons.
LIVE_EXERCISES: dict[str, str] = {"pd_reference": "pd",
                                  "environment_impedance": "environment",
                                  "compliance_law": "compliance"}
#: The lessons that run a live law (both drive their arm through ``open_arm``'s loop).
LIVE_LESSONS: tuple[str, ...] = ("compliance", "arm")
#: When each live law's function runs (for the page's note).
WHEN: dict[str, str] = {
    "pd": "runs while compliance is off (controller PD)",
    "environment": "runs while compliance is on (law 2.6)",
    "compliance": "runs while compliance is on with law 2.6",
}
#: A call may use this share of the control period (CPU time of the loop's thread, its
#: garbage collections left out: :func:`cpu_limit`).
BUDGET_FRACTION = 0.5
#: s between two looks at the file's modification time and size.
POLL_S = 0.1


class LawFault(RuntimeError):
    """The student's law failed on real servos: the loop's fault turns the torque off."""


def refusal(exercise: Exercise) -> str | None:
    """Why ``exercise`` cannot run live in the lab (None: it can)."""
    if exercise.name in LIVE_EXERCISES:
        return None
    live = ", ".join(LIVE_EXERCISES)
    return (f"exercise {exercise.name} has no live lesson: `armlab check` checks it. "
            f"--exercise runs the controller laws ({live}) in the lessons "
            f"{' and '.join(LIVE_LESSONS)}")


class _Collections:
    """CPU time the garbage collector spends in the thread that made this, while it is in
    ``gc.callbacks`` (:func:`cpu_limit` puts it there for the student's call only: the
    lab's other threads and calls pay nothing for it)."""

    def __init__(self) -> None:
        self.thread = threading.get_ident()
        self.total = 0.0
        self._start: float | None = None

    def __call__(self, phase: str, info: dict[str, int]) -> None:
        if threading.get_ident() != self.thread:
            return
        if phase == "start":
            self._start = time.thread_time()
        elif self._start is not None:
            self.total += time.thread_time() - self._start
            self._start = None

    def own_time(self) -> float:
        """This thread's CPU time (``time.thread_time``) without its collections (one under
        way included): a collection the student's call happens to set off frees the whole
        process's garbage, not theirs alone, and is not theirs to pay for."""
        now = time.thread_time()
        return now - self.total - (0.0 if self._start is None else now - self._start)


_COLLECTIONS_CODE = _Collections.__call__.__code__


@contextmanager
def cpu_limit(seconds: float, what: str) -> Iterator[_Collections]:
    """Raise :class:`Hang` in this thread once its CPU time, its garbage collections left
    out, passes ``seconds`` from now, at the next line of Python it runs (``sys.settrace``:
    works in any thread, unlike SIGALRM; code in C runs to its end and is measured
    afterwards). Yields the meter (:meth:`_Collections.own_time`)."""
    meter = _Collections()
    deadline = meter.own_time() + seconds

    def trace(frame: types.FrameType, event: str, arg: Any) -> Any:
        if frame.f_code is _COLLECTIONS_CODE:  # (a collection's own callback: not theirs)
            return None
        if time.thread_time() > deadline and meter.own_time() > deadline:
            raise Hang(f"{what} took more than {seconds * 1e3:.3g} ms")
        return trace

    previous = sys.gettrace()
    gc.callbacks.append(meter)
    sys.settrace(trace)
    try:
        yield meter
    finally:
        sys.settrace(previous)
        gc.callbacks.remove(meter)


class StudentLaw:
    """The student's law file, loaded and reloaded on each save.

    Args:
        path: the student's ``.py`` (or ``.ipynb``) file.
        servos: the lab drives real servos: an error faults the loop (torque off)
            instead of holding the simulated arm.
        echo: where one line per event goes (the terminal: stderr).

    Raises:
        ValueError: the file names an exercise that runs in no lesson, or none the lab
            knows (the one message says which do).
    """

    def __init__(self, path: str | Path, *, servos: bool = False,
                 echo: Callable[[str], None] | None = None) -> None:
        if not Path(path).is_file():
            raise ValueError(f"--exercise: no file {path} (`armlab exercise start NAME` "
                             "writes a starter)")
        self.path = str(path)
        self.servos = servos
        self._echo = echo or (lambda line: print(line, file=sys.stderr, flush=True))
        self._lock = threading.Lock()
        self._fn: Callable[..., Any] | None = None
        self._error: StudentError | None = None
        self._said: StudentError | None = None  # the error last printed
        self.generation = 0  #: loads that succeeded
        self._stamp = self._file_stamp()
        self.exercise, fn, error = self._load_first()
        why = refusal(self.exercise)
        if why is not None:
            raise ValueError(why)
        self.field = LIVE_EXERCISES[self.exercise.name]
        self._fn, self._error = fn, error
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ loading

    def _file_stamp(self) -> tuple[int, int] | None:
        try:
            st = os.stat(self.path)
        except OSError:
            return None
        return (st.st_mtime_ns, st.st_size)

    def _load(self) -> tuple[Exercise | None, Callable[..., Any] | None, StudentError | None]:
        try:
            with cpu_limit(10.0, "loading the file"):
                student = load_student(self.path)
        except StudentError as err:
            return None, None, err
        except Hang as exc:
            return None, None, locate(exc)
        return student.exercise, student.function, None

    def _load_first(self) -> tuple[Exercise, Callable[..., Any] | None, StudentError | None]:
        from armlab.exercises.checking import _guess

        exercise, fn, error = self._load()
        if exercise is None:  # broken at the start: its EXERCISE line or its name says which
            exercise = _guess(Path(self.path))
            if exercise is None:
                raise ValueError(f"--exercise {self.path}: {error}")
            self._said = error
            self._echo(self._line(error))  # type: ignore[arg-type]  # a None exercise comes with its error
        return exercise, fn, error

    def reload(self) -> bool:
        """Load the file again; True when it loaded (its law runs from the next period)."""
        exercise, fn, error = self._load()
        if error is None and exercise is not None and exercise.name != self.exercise.name:
            error = StudentError(self.path, 0, f"the file now answers exercise "
                                 f"{exercise.name}; this lab runs {self.exercise.name} "
                                 "(restart the lab for another)")
        with self._lock:
            if error is None:
                self._fn, self._error = fn, None
                self.generation += 1
            else:
                self._error = error
        if error is None:
            self._said = None
            self._echo(f"armlab serve: {self.path} reloaded: your law runs")
        else:
            self._say(error)
        return error is None

    # ------------------------------------------------------------------ watching

    def start(self) -> None:
        """Watch the file: reload it within :data:`POLL_S` of a save (a daemon thread)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._watch, name="armlab-law-watch",
                                            daemon=True)
            self._thread.start()

    def _watch(self) -> None:
        while not self._stop.wait(POLL_S):
            stamp = self._file_stamp()
            if stamp != self._stamp:
                self._stamp = stamp
                try:
                    self.reload()
                except Exception as exc:  # never a traceback: one line, and watch on
                    self.fail(StudentError(self.path, 0, f"could not reload the file ({exc})"))
            err = self.error
            if err is not None and err is not self._said:  # an error the loop met
                self._say(err)

    def close(self) -> None:
        """Stop watching the file."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)

    # ------------------------------------------------------------------ state

    @property
    def error(self) -> StudentError | None:
        """What is wrong with the student's law now (None: it runs)."""
        with self._lock:
            return self._error

    def fail(self, error: StudentError, *, generation: int | None = None) -> None:
        """Hold the arm on ``error`` until the next good save (the first error stays; one
        met by the law of an earlier load than ``generation``'s is dropped)."""
        with self._lock:
            if self._error is None and generation in (None, self.generation):
                self._error = error

    def note(self) -> str:
        """What the page says where the gains are: the file, its function, when it runs."""
        return f"Your law: {self.path} ({self.exercise.function}, {WHEN[self.field]})"

    def _line(self, error: StudentError) -> str:
        hold = "torque off" if self.servos else "the arm holds"
        return f"armlab serve: your law: {error}; {hold} until you save a fix"

    def _say(self, error: StudentError) -> None:
        self._said = error
        self._echo(self._line(error))

    def laws(self) -> LawGuard:
        """A guard for one loop: its :attr:`LawGuard.laws` go to the loop's controller."""
        return LawGuard(self)


class LawGuard:
    """The student's law as one loop calls it: checked, and holding the arm after an error.

    Attributes:
        period: the loop's control period, s (set by the loop at each tick).
        laws: the controller's equations: the student's in its field, the lab's own in
            the others, all holding while the student's has an error.
        held: the loop held the arm at its last period (a new hold starts with a Stop).
    """

    def __init__(self, law: StudentLaw) -> None:
        self.law = law
        self.period = 0.016
        self._hold_q: np.ndarray | None = None
        self.held = False
        self.laws = Laws(pd=self._pd, compliance=with_student(self._compliance),
                         environment=self._environment)

    def _student(self, *args: Any) -> Any:
        """The student's function on ``args``, or None after an error (recorded)."""
        law = self.law
        generation, fn = law.generation, law._fn
        if fn is None or law.error is not None:
            return None
        budget = BUDGET_FRACTION * self.period
        try:
            with cpu_limit(budget, f"{law.exercise.function}()") as meter:
                start = meter.own_time()
                out = fn(*args)
                spent = meter.own_time() - start
        except (Exception, Hang, SystemExit) as exc:  # (a sys.exit() ends no lab thread)
            law.fail(locate(exc, fallback=fn), generation=generation)
            return None
        why = _wrong_output(out, law.field, args)
        if not why and spent > budget:
            why = (f"one call took {spent * 1e3:.3g} ms; it may take "
                   f"{budget * 1e3:.3g} ms of the {self.period * 1e3:.3g} ms period")
        if why:
            code = getattr(fn, "__code__", None)
            law.fail(StudentError(code.co_filename if code else law.path,
                                  code.co_firstlineno if code else 0,
                                  f"{law.exercise.function} {why}"), generation=generation)
            return None
        arr = np.asarray(out, dtype=float)  # as the lab's own returns it
        return tuple(arr) if law.field == "environment" else arr

    def _call(self, field: str, own: Callable[..., Any], args: tuple[Any, ...]) -> Any:
        law = self.law
        if law.error is None:
            out = own(*args) if field != law.field else self._student(*args)
            if out is not None:
                if self.held:
                    self.held, self._hold_q = False, None
                return out
        error = law.error
        if law.servos:
            raise LawFault(f"your law: {error} (save a fix, then Reset)")
        self.held = True
        return self._hold(field, args)

    def _hold(self, field: str, args: tuple[Any, ...]) -> Any:
        """What holds the arm: the lab's PD towards where it was, no environment offset."""
        if field == "environment":
            zero = np.zeros(np.shape(args[5]))
            return zero, zero.copy(), zero.copy()
        kp, kv, _, _, q, qd = args[:6]
        if self._hold_q is None:
            self._hold_q = np.array(q, dtype=float)
        return pd_reference_accel(kp, kv, self._hold_q, 0.0 * np.asarray(qd), q, qd)

    def _pd(self, *args: Any) -> Any:
        return self._call("pd", pd_reference_accel, args)

    def _compliance(self, *args: Any) -> Any:
        return self._call("compliance", compliance_accel, args)

    def _environment(self, *args: Any) -> Any:
        return self._call("environment", environment_step, args)


def _wrong_output(out: Any, field: str, args: tuple[Any, ...]) -> str:
    """Why ``out`` cannot be the law's answer ("" when it can)."""
    want = (3, *np.shape(args[5])) if field == "environment" else np.shape(args[4])
    try:
        arr = np.asarray(out, dtype=float)
    except Exception:  # whatever the student's object does when made an array
        return f"returned {type(out).__name__}, not numbers"
    if arr.shape != want:
        return f"returned shape {arr.shape}, expected {want}"
    if not np.all(np.isfinite(arr)):
        return f"returned NaN or inf: {np.round(arr, 4).tolist()}"
    return ""


class LawLoop(ControlLoop):
    """The student's arm's loop (their law) with the reference loop beside it.

    The reference (:attr:`reference`) is a simulated arm run by the lab's own law; it
    gets every command and gain change at the same period as the student's loop and is
    ticked in the same thread right after it, so both run on the same loop times.
    When the student's law starts holding the arm, both loops get a Stop (the command
    holds too).

    Args:
        model, backend, params: as :class:`ControlLoop`.
        law: the student's law.
        reference_backend: the reference's simulated arm.
        **loop_kw: ``realtime``, ``history_s``...
    """

    def __init__(self, model: SerialChain, backend: Backend, params: Params, *,
                 law: StudentLaw, reference_backend: Backend, **loop_kw: Any) -> None:
        self.guard = law.laws()
        self._twin = threading.RLock()
        super().__init__(model, backend, params, controller="compliance",
                         laws=self.guard.laws, **loop_kw)
        history = loop_kw.get("history_s", 20.0)
        self.reference = ControlLoop(model, reference_backend, self.params,
                                     controller="compliance", realtime=False,
                                     history_s=history)
        self.law = law

    def post(self, command: Command) -> None:
        """Queue ``command`` for both arms (applied at the same period)."""
        with self._twin:
            super().post(command)
            self.reference.post(command)

    def set_params(self, params: Params) -> GainCheck:
        """Use ``params`` on both arms from the same period (the student's arm's rule)."""
        with self._twin:
            gains = super().set_params(params)
            self.reference.set_params(gains.params)
            return gains

    def restart_reference(self, q: np.ndarray, plan: list[tuple[int, Command]]) -> None:
        """A challenge's restart of the student's arm at ``q`` (n,) rad with ``plan``: the
        reference arm is started again there too, at rest (:class:`RestartableArm`), by
        the same Reset in the same period, and gets the plan's commands from a schedule of
        its own, at the same period as the student's arm (whose plan goes to
        :meth:`post_student`: posted at its sync, a command for both would reach the
        reference, ticked after it, a period early). Call it before the student's arm's
        restart and its Reset."""
        backend = self.reference.backend
        if isinstance(backend, RestartableArm):
            with self._twin:
                backend.restart(q, plan, self.reference.post)

    def post_student(self, command: Command) -> None:
        """Queue ``command`` for the student's arm alone (a restart's plan)."""
        super().post(command)

    def records(self, window_s: float | None = None
                ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """The student's arm's record and the reference's, both taken between the same two
        periods (so they end at the same loop time): :meth:`Recorder.snapshot` of each
        over the last ``window_s`` s."""
        with self._twin:
            return self.recorder.snapshot(window_s), self.reference.recorder.snapshot(window_s)

    def _tick(self) -> None:
        with self._twin:
            self.guard.period = self._params.period
            was_held = self.guard.held
            super()._tick()
            self.reference._tick()
            if self.guard.held and not was_held:  # the command holds where it is too
                super().post(Stop())
                self.reference.post(Stop())

    def shutdown(self, *, torque_off: bool = False, timeout: float = 2.0) -> None:
        """Stop the loop (optionally torque off) and let go of the reference arm."""
        super().shutdown(torque_off=torque_off, timeout=timeout)
        self.reference.backend.close()


def law_loop(law: StudentLaw, backend: Backend, model: SerialChain, params: Params, *,
             q0: np.ndarray, **loop_kw: Any) -> LawLoop:
    """The :class:`LawLoop` of ``model`` over ``backend``, its reference a simulated arm at
    ``q0`` (n,) rad; not started. Both backends are closed when it cannot be made."""
    from armlab.app.arm.backends import make_backend

    loop_kw.setdefault("hold_off", getattr(backend, "uncalibrated", None))
    try:
        # (restartable: a challenge's run starts it again with the student's arm)
        reference = RestartableArm(lambda q: make_backend("sim", model, q0=q), q0)
    except BaseException:
        backend.close()
        raise
    try:
        return LawLoop(model, backend, params, law=law, reference_backend=reference,
                       **loop_kw)
    except BaseException:
        reference.close()
        backend.close()
        raise
