"""Checking a student's function: its cases run, one line each, and the Gradescope results.

``armlab check FILE`` is :func:`check_file`: the student's file runs in a child process
(:mod:`armlab.exercises.boundary`) that only calls their function on the inputs this
process sends; this process alone judges, scores and reports. A notebook's
``armlab.check(fn)`` is :func:`check`: the function is called in the notebook's own
kernel (formative feedback, not a grade). Both return a :class:`Report`.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from armlab.exercises.boundary import PRINTED_LINES, ChildGone, RemoteFunction, StudentProcess
from armlab.exercises.catalog import BY_FUNCTION, BY_NAME, get
from armlab.exercises.core import Exercise, Outcome, RunCase, judge_run, judge_value
from armlab.exercises.student import StudentError, load_module


@dataclass(frozen=True)
class Student:
    """A student's function, loaded: which exercise it answers, the function, its file."""

    exercise: Exercise
    function: Callable[..., Any]
    path: str


def load_student(path: str | Path, *, exercise: str | None = None) -> Student:
    """Load the student's file (``.py`` or ``.ipynb``) and find their function.

    The exercise is ``exercise``, else the file's ``EXERCISE = "name"`` (the starter has
    it), else the one whose function the file defines, else the file's name.

    Raises:
        StudentError: the file cannot be run (their file and line), names no known
            exercise, or lacks the exercise's function.
        ValueError: ``exercise`` is not a known name.
    """
    p = Path(path)
    module = load_module(p)
    ns = vars(module)
    ex = _which(p, exercise or ns.get("EXERCISE"),
                [fn for fn in BY_FUNCTION if callable(ns.get(fn))])
    return Student(ex, ns[ex.function], str(p))


def _which(p: Path, name: object, defined: list[str]) -> Exercise:
    """The exercise a student's file answers: ``name`` (the option, or the file's
    ``EXERCISE``), else the one whose function it alone defines, else the file's name;
    ``defined`` are the exercises' function names the file defines.

    Raises:
        StudentError: no known exercise, or the file lacks its function.
    """
    if not isinstance(name, str):
        found = [fn for fn in BY_FUNCTION if fn in defined]
        name = BY_FUNCTION[found[0]].name if len(found) == 1 else p.stem
    try:
        ex = get(name)
    except ValueError as exc:
        raise StudentError(str(p), 0, f"which exercise is this? {exc}; put "
                           "EXERCISE = \"NAME\" at the top of the file") from None
    if ex.function not in defined:
        raise StudentError(str(p), 0, f"no function {ex.function}() in the file (exercise "
                           f"{ex.name} asks for it; `armlab exercise start {ex.name}` "
                           "writes its starter)")
    return ex


@dataclass(frozen=True)
class Report:
    """The outcome of a check.

    Attributes:
        exercise: the exercise's name ("" when the file named none).
        source: the student's file, or the function's name in a notebook.
        outcomes: one per case, in order.
        error: the student's code could not be loaded (no case ran).
        seconds: how long the check took.
    """

    exercise: str
    source: str
    outcomes: tuple[Outcome, ...]
    error: StudentError | None = None
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        """Every case passed (and there were cases)."""
        return self.error is None and bool(self.outcomes) and all(
            o.passed for o in self.outcomes)

    @property
    def score(self) -> float:
        """Points of the passed cases (one per case)."""
        return sum(o.points for o in self.outcomes if o.passed)

    @property
    def max_score(self) -> float:
        """Points of all cases."""
        return sum(o.points for o in self.outcomes)

    def summary(self) -> str:
        """The last line: how many cases passed."""
        n = len(self.outcomes)
        ok = sum(o.passed for o in self.outcomes)
        if self.error is not None:
            return f"{self.exercise or self.source}: not run: {self.error}"
        verdict = "all cases pass" if self.passed else f"{n - ok} of {n} cases fail"
        return f"{self.exercise}: {ok}/{n} cases pass ({verdict})"

    def text(self) -> str:
        """Every case's line (with a failed one's details) and the summary."""
        lines = [o.text for o in self.outcomes] if self.error is None else []
        return "\n".join([*lines, self.summary()])

    def gradescope(self) -> dict[str, Any]:
        """Gradescope's autograder results (``results.json``): one test per case
        (name, score, max_score, status, output) and the total score."""
        tests = []
        for o in self.outcomes:
            output = o.text if self.error is None else f"not run: {self.error}"
            tests.append({
                "name": f"{self.exercise}: {o.name}",
                "score": o.points if o.passed and self.error is None else 0.0,
                "max_score": o.points,
                "status": "passed" if o.passed and self.error is None else "failed",
                "output": output,
            })
        return {
            "score": sum(t["score"] for t in tests),
            "execution_time": round(self.seconds, 3),
            "output": self.summary(),
            "visibility": "visible",
            "stdout_visibility": "visible",
            "tests": tests,
        }

    def __repr__(self) -> str:
        return f"<Report {self.summary()}>"


def run_cases(exercise: Exercise, fn: Callable[..., Any], source: str, *,
              echo: Callable[[str], None] | None = None,
              progress: Callable[[Report], None] | None = None) -> Report:
    """Run every case of ``exercise`` on ``fn``; ``echo`` gets each case's text as it ends,
    ``progress`` the report so far (the cases not run yet failed) before the first case
    and after each.

    When the student's process goes (:class:`ChildGone`: it died, hung past its limit),
    the case it went in fails with one line saying why and the cases left fail as not run.
    """
    start = time.monotonic()
    cases = list(exercise.cases())
    outcomes: list[Outcome] = []
    gone: str | None = None

    def report(final: bool) -> Report:
        rest = () if final else tuple(Outcome(c.name, False, (f"FAIL  {c.name}: not run yet",))
                                      for c in cases[len(outcomes):])
        return Report(exercise.name, source, (*outcomes, *rest),
                      seconds=time.monotonic() - start)

    if progress is not None:
        progress(report(False))
    for case in cases:
        if gone is not None:
            outcome = Outcome(case.name, False, (f"FAIL  {case.name}: not run (your code's "
                                                 "process had stopped)",))
        else:
            try:
                if isinstance(case, RunCase):
                    outcome = judge_run(case, fn)
                else:
                    outcome = judge_value(exercise, case, fn)
            except ChildGone as exc:
                gone = exc.reason
                outcome = Outcome(case.name, False, (
                    f"FAIL  {case.name}: {gone}; this case and the ones left fail",))
        outcomes.append(outcome)
        if echo is not None:
            echo(outcome.text)
        if progress is not None:
            progress(report(False))
    return report(True)


def not_run(exercise: Exercise | None, source: str, error: StudentError) -> Report:
    """The report of a student's file that could not be loaded: every case failed (so a
    results file still lists them all), none run."""
    if exercise is None:
        return Report("", source, (Outcome("load", False, (f"FAIL  load: {error}",)),),
                      error=error)
    outcomes = tuple(Outcome(c.name, False, (f"FAIL  {c.name}: not run",))
                     for c in exercise.cases())
    return Report(exercise.name, source, outcomes, error=error)


def check_file(path: str | Path, *, exercise: str | None = None,
               echo: Callable[[str], None] | None = None,
               progress: Callable[[Report], None] | None = None) -> Report:
    """Check the student's file (``armlab check FILE``): it runs in a child process that
    cannot import armlab and only calls their function on the inputs sent to it; this
    process judges each value, so nothing the file does can change its verdict.

    ``echo`` gets each case's text as it ends and, at the end, what the student's code
    printed (at most :data:`PRINTED_LINES` lines, each marked ``  | ``); ``progress`` as
    :func:`run_cases`.
    """
    p = Path(path)
    guess = get(exercise) if exercise else _guess(p)
    _preload()
    with StudentProcess(p) as child:
        try:
            named, where = child.load(list(BY_FUNCTION))
            ex = _which(p, exercise or named, list(where))
        except StudentError as err:
            report = not_run(guess, str(p), err)
        except ChildGone as exc:
            report = not_run(guess, str(p), StudentError(str(p), 0, exc.reason))
        else:
            fn = RemoteFunction(child, ex.function, where[ex.function])
            report = run_cases(ex, fn, str(p), echo=echo, progress=progress)
    printed = child.printed()
    if printed and echo is not None:
        more = f" (the first {PRINTED_LINES} of {len(printed)})" if len(
            printed) > PRINTED_LINES else ""
        echo("\n".join([f"your code printed{more}:",
                        *(f"  | {ln}" for ln in printed[:PRINTED_LINES])]))
    return report


def _preload() -> None:
    """Import what the cases import lazily before the student's code runs (a file that
    rewrote the lab's installed files would otherwise reach the modules loaded later)."""
    import armlab.hardware.families.dynamixel1.sim_backend  # noqa: F401  (the closed-loop runs' arm)


def _guess(p: Path) -> Exercise | None:
    """The exercise a file that failed to load is probably for: the one its
    ``EXERCISE = "name"`` line names (also inside a notebook's JSON), else its file name's."""
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        text = ""
    for name in [*_EXERCISE_LINE.findall(text), p.stem]:
        if name in BY_NAME:
            return BY_NAME[name]
    return None


_EXERCISE_LINE = re.compile(r"""EXERCISE\s*=\s*\\?["']([A-Za-z0-9_]+)""")


def check(fn: Callable[..., Any], exercise: str | None = None, *,
          quiet: bool = False) -> Report:
    """Check a function in a notebook: ``armlab.check(hand_position)``.

    Runs the cases of the exercise whose function it is (by its name, or ``exercise``),
    prints one line per case (a failed one's input, expected and returned values, a hint)
    and the summary, and returns the :class:`Report`.

    Raises:
        ValueError: the function's name matches no exercise and ``exercise`` is not given.
    """
    if exercise is None:
        name = getattr(fn, "__name__", "")
        if name not in BY_FUNCTION:
            raise ValueError(f"which exercise is {name or fn!r}? name it: "
                             f"armlab.check(fn, \"NAME\") with NAME one of "
                             f"{', '.join(ex.name for ex in BY_FUNCTION.values())}")
        ex = BY_FUNCTION[name]
    else:
        ex = get(exercise)
    report = run_cases(ex, fn, getattr(fn, "__name__", "your function"),
                       echo=None if quiet else print)
    if not quiet:
        print(report.summary())
    return report
