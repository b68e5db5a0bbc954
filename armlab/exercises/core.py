"""What an exercise is, and how one case of it judges a student's function.

An :class:`Exercise` names the one function a student fills in (its name, signature and
statement live in the starter, ``armlab/exercises/starters/NAME.py``), the lab's own
implementation it is checked against (``reference``), the common mistakes planted as
variants of that reference (:class:`Mistake`), and its cases. A case is either a
:class:`ValueCase` (one call, its output compared with the reference's) or a
:class:`RunCase` (a closed-loop run of the simulated arm with the student's function in
place of the lab's, compared with the lab's own run).

A failed value case names the input, what was expected, what came back, and, when the
student's output equals what planted mistakes give on that input, their hints (every one
that gives it: a hint is never a guess between two mistakes that look the same there).

The student's function is either a plain callable (a notebook's ``armlab.check(fn)``,
called in this process under :func:`guarded_call`) or a
:class:`~armlab.exercises.boundary.RemoteFunction` (``armlab check``: their file runs in a
child process, and this module only judges what comes back).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from armlab.exercises.harness import Other
from armlab.exercises.student import StudentError, guarded_call

#: Seconds one value case may take before it counts as a hang.
VALUE_CASE_S = 5.0
#: Seconds a closed-loop run may take.
RUN_CASE_S = 90.0


@dataclass(frozen=True)
class Mistake:
    """A common mistake, planted: ``fn`` takes the student's arguments and returns what a
    function with this mistake returns; ``hint`` is what the student is told."""

    name: str
    hint: str
    fn: Callable[..., Any]


@dataclass(frozen=True)
class Outcome:
    """The verdict on one case: ``lines[0]`` is the case's line, the rest its details."""

    name: str
    passed: bool
    lines: tuple[str, ...]
    points: float = 1.0

    @property
    def text(self) -> str:
        """The case's line and its indented details, one string."""
        return "\n".join(self.lines)


@dataclass(frozen=True)
class ValueCase:
    """One call of the student's function, compared with the reference's output.

    Attributes:
        name: what the case checks ("seed 004 Table 1 row 3", "random 2", ...).
        args, kwargs: the call (copied before each call: a student may change them).
        atol, rtol: the tolerance of ``np.allclose`` on the flattened outputs.
        angles: the outputs are angles: compare them modulo 2π.
        expected: the expected output; None: the reference's output on the same call.
        check: judges the output instead of the comparison (returns "" when it is
            right, else why not), for cases whose answer is not one array (the seed's
            table, judged through the lab's servo rounding).
    """

    name: str
    args: tuple[Any, ...]
    kwargs: dict[str, Any] = field(default_factory=dict)
    atol: float = 1e-9
    rtol: float = 1e-9
    angles: bool = False
    expected: Any = None
    check: Callable[[np.ndarray], str] | None = None

    def call_text(self, function: str) -> str:
        """``function(arg, ..., key=value)`` with the arrays written out."""
        parts = [_show(a) for a in self.args]
        parts += [f"{k}={_show(v)}" for k, v in self.kwargs.items()]
        return f"{function}({', '.join(parts)})"


@dataclass(frozen=True)
class RunCase:
    """A closed-loop run: ``run(fn)`` runs the student's function on the simulated arm
    and returns "" when it behaves as the lab's own law on the same run, else why not
    (the student's own errors come back as :class:`StudentError`)."""

    name: str
    run: Callable[[Callable[..., Any]], str]


Case = ValueCase | RunCase


@dataclass(frozen=True)
class Exercise:
    """One exercise: a function to fill in, its reference, mistakes and cases.

    Attributes:
        name: the exercise's name (``armlab exercise start NAME``).
        title: what it is, with its seed and equation.
        function: the name of the function the student writes.
        reference: the lab's own implementation, with the student's signature.
        shape: the shape of the output (a value case with another shape fails as such).
        mistakes: the planted common mistakes.
        cases: builds the cases (lazily: some need a robot model or a reference run).
        teaches: one sentence for the teacher (docs/teaching.md).
        lesson: the lab's lesson or experiment that shows it.
    """

    name: str
    title: str
    function: str
    reference: Callable[..., Any]
    mistakes: tuple[Mistake, ...]
    cases: Callable[[], Sequence[Case]]
    teaches: str
    lesson: str


def as_array(value: Any) -> np.ndarray:
    """The output as a float array (a tuple of arrays stacks); raises ValueError if it is
    not numbers."""
    if value is None:
        raise ValueError("returned None, not numbers (a missing return?)")
    if isinstance(value, Other):  # what the student's process said it was
        raise ValueError(f"returned {value.text:.100}, not numbers")
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"returned {type(value).__name__} {value!r:.80}, not numbers "
                         f"({exc})") from None


def close(got: np.ndarray, want: np.ndarray, case: ValueCase) -> bool:
    """The two outputs agree within the case's tolerance (angles modulo 2π)."""
    if got.shape != want.shape or not np.all(np.isfinite(got)):
        return False
    diff = got - want
    if case.angles:
        diff = np.mod(diff + math.pi, 2.0 * math.pi) - math.pi
    return bool(np.all(np.abs(diff) <= case.atol + case.rtol * np.abs(want)))


def judge_value(exercise: Exercise, case: ValueCase, fn: Callable[..., Any]) -> Outcome:
    """Run one value case of ``fn`` (the student's function) and judge it."""
    call = case.call_text(exercise.function)
    want = None
    if case.check is None:
        want = as_array(case.expected if case.expected is not None else
                        exercise.reference(*copy.deepcopy(case.args),
                                           **copy.deepcopy(case.kwargs)))
    try:
        out = call_student(fn, copy.deepcopy(case.args), copy.deepcopy(case.kwargs),
                           seconds=VALUE_CASE_S)
        got = as_array(out)
    except StudentError as err:
        return _fail(case.name, f"{call}", f"error: {err}")
    except ValueError as exc:
        return _fail(case.name, call, f"error: {exc}")
    if case.check is not None:
        why = "" if np.all(np.isfinite(got)) else "returned NaN or inf"
        why = why or case.check(got)
        if not why:
            return Outcome(case.name, True, (f"PASS  {case.name}",))
        return _fail(case.name, call, f"got      {_show(got)}", why,
                     *_hint(exercise, case, got))
    assert want is not None
    if got.shape != want.shape and got.size == want.size and (
            got.squeeze().shape == want.squeeze().shape):
        same = "the same numbers" if close(got.reshape(want.shape), want, case) else "numbers"
        return _fail(case.name, call, f"got shape {got.shape}, expected shape {want.shape}: "
                     f"{same} in another shape; return shape {want.shape}"
                     f"{' (a plain float)' if want.shape == () else ''}")
    if got.shape != want.shape:
        return _fail(case.name, call, f"expected shape {want.shape}: {_show(want)}",
                     f"got      shape {got.shape}: {_show(got)}",
                     *(["hint: a transposed matrix (rows and columns swapped)"]
                       if got.ndim == 2 and got.T.shape == want.shape else []))
    if not np.all(np.isfinite(got)):
        return _fail(case.name, call, f"expected {_show(want)}",
                     f"got      {_show(got)} (NaN or inf)", *_hint(exercise, case, got))
    if close(got, want, case):
        return Outcome(case.name, True, (f"PASS  {case.name}",))
    return _fail(case.name, call, f"expected {_show(want)}", f"got      {_show(got)}",
                 f"(tolerance {case.atol:g} + {case.rtol:g}·|expected|"
                 f"{', angles modulo 2π' if case.angles else ''})",
                 *_hint(exercise, case, got))


def call_student(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any], *,
                 seconds: float) -> Any:
    """``fn(*args, **kwargs)`` within ``seconds``: across the process boundary for a
    :class:`~armlab.exercises.boundary.RemoteFunction` (its child keeps the time), else in
    this process under :func:`guarded_call`.

    Raises:
        StudentError: the student's code failed (their file and line).
        ChildGone: (remote only) the student's process died or hung.
    """
    if getattr(fn, "remote", False):
        fn.seconds = seconds  # type: ignore[attr-defined]  # a remote student function (a proxy) carries its time limit
        return fn(*args, **kwargs)
    return guarded_call(fn, args, kwargs, seconds=seconds)


def judge_run(case: RunCase, fn: Callable[..., Any]) -> Outcome:
    """Run one closed-loop case of ``fn`` and judge it."""
    what = "closed loop: your function in place of the lab's"
    try:
        if getattr(fn, "remote", False):
            with fn.run_limit(RUN_CASE_S):  # type: ignore[attr-defined]  # a remote student function (a proxy) has run_limit
                why = case.run(fn)
        else:
            why = guarded_call(case.run, (fn,), {}, seconds=RUN_CASE_S, user=False)
    except StudentError as err:
        return _fail(case.name, what, f"error: {err}")
    except Exception as exc:  # the lab's run stopped on what the function gave it
        text = str(exc).strip().splitlines()
        return _fail(case.name, what, f"the lab's run stopped with your function in it: "
                     f"{type(exc).__name__}: {text[0] if text else ''}")
    if not why:
        return Outcome(case.name, True, (f"PASS  {case.name}",))
    return _fail(case.name, what, why)


def _hint(exercise: Exercise, case: ValueCase, got: np.ndarray) -> list[str]:
    """The hints of every planted mistake whose output on this case equals the student's
    (and differs from the right answer): one line, ``hint (NAME): ...``, when one mistake
    gives that value; when several do, a line saying so, then each one's hint."""
    want = None
    if case.check is None:
        want = as_array(case.expected if case.expected is not None else
                        exercise.reference(*copy.deepcopy(case.args),
                                           **copy.deepcopy(case.kwargs)))
    hits = []
    for mistake in exercise.mistakes:
        try:
            planted = as_array(mistake.fn(*copy.deepcopy(case.args),
                                          **copy.deepcopy(case.kwargs)))
        except Exception:  # the mistake does not apply to this input (e.g. a shape)
            continue
        if want is not None and close(planted, want, case):
            continue  # the mistake makes no difference here: it cannot explain a failure
        if np.all(np.isfinite(planted)) and close(got, planted, case):
            hits.append(f"hint ({mistake.name}): {mistake.hint}")
    if len(hits) > 1:
        return [f"hint: {len(hits)} mistakes give this value here; one of them:", *hits]
    return hits


def _fail(name: str, *details: str) -> Outcome:
    first, *rest = details
    return Outcome(name, False, (f"FAIL  {name}: {first}", *(f"      {d}" for d in rest)))


def _show(value: Any) -> str:
    """A value as the student would write it, arrays rounded to 6 significant digits."""
    if isinstance(value, np.ndarray | list | tuple) and not isinstance(value, str):
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return repr(value)
        return np.array2string(arr, precision=6, separator=", ", suppress_small=False,
                               max_line_width=10_000, threshold=64).replace("\n", "")
    if isinstance(value, float):
        return f"{value:.6g}"
    return repr(value)
