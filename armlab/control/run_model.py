"""A recorded run (:class:`Run`) and what every run must be, written or read (docs/runs.md).

The run file's format (its members, version, lesson signals' rules) is fixed here; writing
it is :mod:`armlab.control.run_save`, reading it :mod:`armlab.control.run_read`, and
:mod:`armlab.control.runs` offers all three.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import numpy as np

from armlab.control.recorder import CONTACT_SIGNALS, SIGNALS, UNITS
from armlab.control.run_errors import RunFileError, quote

FORMAT = "armlab-run"
#: The newest version this lab reads. A run is written as version 1 (every reader reads it)
#: unless it holds a lesson's own signals (:attr:`Run.lesson_signals`): then 2; or the
#: hand's contact force (:data:`armlab.control.recorder.CONTACT_SIGNALS`, one column each):
#: then 3. So an older reader says "written by a newer armlab" rather than refusing a
#: column, and a file of any older version still reads.
VERSION = 3
#: A lesson signal's name: lower-case letters, digits and ``_``, a letter first, at most 32.
LESSON_SIGNAL_NAME = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
#: The most lesson signals a run may hold, and the longest unit text.
MAX_LESSON_SIGNALS = 32
MAX_UNIT_CHARS = 16
#: The most joints a run may have, and the longest robot or joint name (characters).
MAX_JOINTS = 64
MAX_NAME_CHARS = 128
#: The largest loop time a run may hold (s), and the least step between two samples (s):
#: a loop's period is at least 1 ms.
MAX_TIME_S = 1e9
MIN_STEP_S = 1e-6
#: The largest magnitude a signal's value may have for the run to be drawn (an angle in
#: rad, a torque in N·m, a current in A): far beyond any robot's, far inside float64's
#: range, so no chart's or pose's arithmetic overflows. The file itself keeps any float.
MAX_DRAWN_VALUE = 1e6
#: The suffix a saved run is given (any name is accepted when reading).
SUFFIX = ".armlab-run.zip"
#: The run file's two members.
JSON_MEMBER = "run.json"
CSV_MEMBER = "signals.csv"

__all__ = ["CSV_MEMBER", "FORMAT", "JSON_MEMBER", "LESSON_SIGNAL_NAME", "MAX_LESSON_SIGNALS",
           "MAX_DRAWN_VALUE", "MAX_JOINTS", "MAX_NAME_CHARS", "MAX_TIME_S", "MAX_UNIT_CHARS",
           "MIN_STEP_S", "SUFFIX", "VERSION", "Run", "RunFileError", "check_drawable",
           "check_lesson_signals", "check_run", "lab_version", "ordered_signals",
           "run_from_snapshot", "signal_columns", "utc_now"]

@dataclass(frozen=True)
class Run:
    """One recorded run.

    Attributes:
        robot: robot model name, e.g. "thesis", "receptionist_arm".
        joint_names: the model's joint names, in its order (n).
        source: what made it, e.g. "page:compliance", "experiment:thesis-line".
        lab_version: armlab's version when written.
        created: ISO 8601 UTC time it was made.
        params: gains and environment (``Params`` fields: kp, kv, m_env, ...): numbers,
            strings or booleans.
        commands: what was commanded, in order: {"t": s, "kind": "...", ...JSON fields}.
        figures: measured figures by name, units in the name ("overshoot_pct",
            "settling_s", "max_error_deg", ...); None where not measured.
        t: (m,) loop time, s, strictly increasing.
        signals: name -> (m, n) array, SI, names from
            :data:`armlab.control.recorder.SIGNALS` or :attr:`lesson_signals`; "q" (measured
            angles, rad) required; or name -> (m, 1) for a contact signal
            (:data:`armlab.control.recorder.CONTACT_SIGNALS`: the wall's force on the hand,
            N, one column whatever the joints).
        extra: free JSON kept verbatim (e.g. {"challenge": {...}}).
        lesson_signals: a lesson's own per-joint signals, name -> unit, in the file's
            column order (after the recorder's), e.g. {"current": "A", "force": "N"}: the
            hand's motor currents, what the recorder's SIGNALS have no name for.
    """

    robot: str
    joint_names: tuple[str, ...]
    source: str
    lab_version: str
    created: str
    params: dict[str, float | str]
    commands: tuple[dict, ...]
    figures: dict[str, float | None]
    t: np.ndarray
    signals: dict[str, np.ndarray]
    extra: dict[str, object] = field(default_factory=dict)
    lesson_signals: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "commands", tuple(self.commands))
        object.__setattr__(self, "t", np.asarray(self.t, dtype=np.float64))
        object.__setattr__(self, "lesson_signals", dict(self.lesson_signals))
        known = [*SIGNALS, *CONTACT_SIGNALS, *self.lesson_signals]
        order = sorted(self.signals, key=lambda k: (known.index(k) if k in known
                                                    else len(known)))
        object.__setattr__(self, "signals", {  # in the file's order: SIGNALS, then the lesson's
            k: np.asarray(self.signals[k], dtype=np.float64) for k in order})

    @property
    def version(self) -> int:
        """The run format version this run is written as: 1; 2 with lesson signals; 3 with
        a contact signal."""
        if any(name in self.signals for name in CONTACT_SIGNALS):
            return 3
        return 2 if self.lesson_signals else 1

    def unit(self, signal: str) -> str:
        """The unit of ``signal`` ("t", a recorder signal or a lesson signal)."""
        return "s" if signal == "t" else UNITS.get(signal) or self.lesson_signals[signal]


def lab_version() -> str:
    """armlab's installed version ("unknown" when it is not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("armlab")
    except PackageNotFoundError:
        return "unknown"


def utc_now() -> str:
    """The time now, ISO 8601 UTC to the second, e.g. "2026-11-28T03:20:00Z"."""
    return datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def run_from_snapshot(snap: Mapping[str, np.ndarray], *, robot: str,
                      joint_names: Sequence[str], source: str,
                      params: Mapping[str, Any], commands: Sequence[Mapping[str, Any]] = (),
                      figures: Mapping[str, float | None] | None = None,
                      extra: Mapping[str, object] | None = None,
                      lesson_signals: Mapping[str, str] | None = None) -> Run:
    """A :class:`Run` from a ``Recorder.snapshot()`` (keys t, wall, q_cmd, q, ...).

    Rows at the start where ``q`` is not yet recorded (NaN) are dropped; signals that
    are NaN throughout are left out ("q" and every one of ``lesson_signals``, name ->
    unit, the snapshot's keys of a lesson's own signals, are always kept; a contact
    signal, (m,) in the snapshot, is kept as one column, (m, 1), when it holds a value: a
    run into a wall); "wall" is not kept. The arrays are copied. Stamped with this lab's
    version and the time now.
    """
    t = np.asarray(snap["t"], dtype=np.float64)
    q = np.asarray(snap["q"], dtype=np.float64).reshape(len(t), -1)
    recorded = np.isfinite(q).all(axis=1) & np.isfinite(t)
    start = int(np.argmax(recorded)) if recorded.any() else len(t)
    signals: dict[str, np.ndarray] = {}
    for name in SIGNALS:
        if name not in snap:
            continue
        values = np.array(snap[name], dtype=np.float64).reshape(len(t), -1)[start:]
        if name == "q" or not np.isnan(values).all():
            signals[name] = values
    for name in CONTACT_SIGNALS:
        if name in snap:
            values = np.array(snap[name], dtype=np.float64).reshape(len(t), 1)[start:]
            if not np.isnan(values).all():
                signals[name] = values
    own = dict(lesson_signals or {})
    for name in own:
        signals[name] = np.array(snap[name], dtype=np.float64).reshape(len(t), -1)[start:]
    return Run(robot=robot, joint_names=tuple(joint_names), source=source,
               lab_version=lab_version(), created=utc_now(), params=dict(params),
               commands=tuple(dict(c) for c in commands),
               figures=dict(figures or {}), t=t[start:].copy(), signals=signals,
               extra=dict(extra or {}), lesson_signals=own)


def ordered_signals(run: Run) -> list[str]:
    """The run's signal names in the file's order: :data:`SIGNALS`, the contact signals,
    then its lesson's."""
    return [name for name in (*SIGNALS, *CONTACT_SIGNALS, *run.lesson_signals)
            if name in run.signals]


def signal_columns(name: str, joints: Sequence[str]) -> list[str]:
    """The run file's column names of signal ``name``: ``name.<joint>`` for each of
    ``joints``, or ``name`` alone for a contact signal (one column)."""
    if name in CONTACT_SIGNALS:
        return [name]
    return [f"{name}.{j}" for j in joints]


def check_run(run: Run, label: str) -> None:
    """Everything a run must be, whether about to be written or just read: named joints
    (at most :data:`MAX_JOINTS`, names of at most :data:`MAX_NAME_CHARS`), times finite,
    within :data:`MAX_TIME_S` and each at least :data:`MIN_STEP_S` after the last, every
    signal one column per joint (a contact signal one column), ``q`` finite, params,
    commands and figures of their types. Messages quote at most ~200 characters of any
    text (:func:`quote`)."""
    for key in ("robot", "source", "lab_version", "created"):
        if not isinstance(getattr(run, key), str):
            raise RunFileError(f"{label}: {key} must be text, got {quote(getattr(run, key))}")
    if not run.robot or len(run.robot) > MAX_NAME_CHARS:
        raise RunFileError(f"{label}: the robot is not named (a name of 1 to "
                           f"{MAX_NAME_CHARS} characters), got {quote(run.robot)}")
    joints = run.joint_names
    if not joints or len(joints) > MAX_JOINTS or not all(
            isinstance(j, str) and 0 < len(j) <= MAX_NAME_CHARS for j in joints):
        raise RunFileError(f"{label}: joint names must be 1 to {MAX_JOINTS} texts of 1 to "
                           f"{MAX_NAME_CHARS} characters, got {quote(joints)}")
    if len(set(joints)) != len(joints):
        raise RunFileError(f"{label}: joint names repeat: {quote(', '.join(joints))}")
    n = len(joints)
    t = run.t
    if t.ndim != 1 or len(t) == 0:
        raise RunFileError(f"{label}: t must hold at least one sample, shape {t.shape}")
    _check_times(t, label)
    if "q" not in run.signals:
        raise RunFileError(f"{label}: no 'q' signal (the measured joint angles), which a run "
                           "must hold")
    check_lesson_signals(run.lesson_signals, label)
    for name in run.lesson_signals:
        if name not in run.signals:
            raise RunFileError(f"{label}: the lesson signal {quote(name)} is declared but "
                               "has no columns")
    for name, values in run.signals.items():
        if name in CONTACT_SIGNALS:
            if values.shape != (len(t), 1):
                raise RunFileError(f"{label}: the contact signal {quote(name)} has shape "
                                   f"{values.shape}, but the run has {len(t)} samples of "
                                   "one column")
            continue
        if name not in SIGNALS and name not in run.lesson_signals:
            raise RunFileError(f"{label}: {quote(name)} is no signal this lab knows "
                               f"({', '.join((*SIGNALS, *CONTACT_SIGNALS))}) nor a declared "
                               "lesson signal")
        if values.shape != (len(t), n):
            raise RunFileError(f"{label}: signal {quote(name)} has shape {values.shape}, but "
                               f"the run has {len(t)} samples of {n} joints")
    q = run.signals["q"]
    bad_q = np.argwhere(~np.isfinite(q))
    if len(bad_q):
        i, j = bad_q[0]
        raise RunFileError(f"{label}: q (the measured angles) is NaN or infinite at sample "
                           f"{i} (t = {float(t[i])!r} s), joint {quote(joints[j])}; a run's poses "
                           "must all be known")
    value: object  # a parameter's, then a figure's
    for key, value in run.params.items():
        if not isinstance(key, str) or not (
                isinstance(value, str | bool | int | float) and _finite(value)):
            raise RunFileError(f"{label}: parameter {quote(key)} = {quote(value)} is not a "
                               "finite number, text or a boolean")
    for i, command in enumerate(run.commands):
        when = command.get("t") if isinstance(command, Mapping) else None
        if (not isinstance(command, Mapping) or not isinstance(command.get("kind"), str)
                or not isinstance(when, int | float) or isinstance(when, bool)
                or not _finite(when) or abs(when) > MAX_TIME_S):
            raise RunFileError(f"{label}: command {i} needs a 'kind' (text) and a finite "
                               f"'t' (s, at most {MAX_TIME_S:g}), got {quote(command)}")
    for key, value in run.figures.items():
        if not isinstance(key, str) or not (value is None or (
                isinstance(value, int | float | np.floating | np.integer)
                and not isinstance(value, bool))):
            raise RunFileError(f"{label}: figure {quote(key)} = {quote(value)} is not a "
                               "number or null")
    if not isinstance(run.extra, Mapping):
        raise RunFileError(f"{label}: extra must be a JSON object, got {quote(run.extra)}")


def _check_times(t: np.ndarray, label: str) -> None:
    """t finite, within :data:`MAX_TIME_S`, each sample at least :data:`MIN_STEP_S` after
    the one before (so every step is far above float spacing: a chart's axis over it has
    distinct ticks)."""
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise RunFileError(f"{label}: t is NaN or infinite at sample {bad[0]}; every "
                           "sample needs its loop time")
    far = np.flatnonzero(np.abs(t) > MAX_TIME_S)
    if len(far):
        i = int(far[0])
        raise RunFileError(f"{label}: t is {float(t[i])!r} s at sample {i}, beyond the "
                           f"{MAX_TIME_S:g} s a loop time may reach")
    step = np.diff(t)
    back = np.flatnonzero(step <= 0.0)
    if len(back):
        i = int(back[0]) + 1
        raise RunFileError(f"{label}: t does not increase at sample {i} "
                           f"({float(t[i - 1])!r} s then {float(t[i])!r} s); samples must be "
                           "in time order")
    short = np.flatnonzero(step < MIN_STEP_S)
    if len(short):
        i = int(short[0]) + 1
        raise RunFileError(f"{label}: t advances by only {step[i - 1]:.3g} s at sample {i} "
                           f"({float(t[i - 1])!r} s then {float(t[i])!r} s); samples are at least "
                           f"{MIN_STEP_S:g} s apart")


def check_drawable(run: Run, label: str) -> None:
    """Refuse to draw ``run`` (export it, replay it) if a finite value of a signal is
    beyond :data:`MAX_DRAWN_VALUE` (e.g. q = 1e308 rad: a run file may hold it, no arm
    reaches it, and degrees of it overflow)."""
    for name, values in run.signals.items():
        with np.errstate(invalid="ignore"):
            far = np.argwhere(np.isfinite(values) & (np.abs(values) > MAX_DRAWN_VALUE))
        if len(far):
            i, j = far[0]
            where = "" if name in CONTACT_SIGNALS else f", joint {quote(run.joint_names[j])}"
            raise RunFileError(
                f"{label}: {quote(name)} is {values[i, j]:.6g} {_unit(run, name)} at sample "
                f"{i}{where}, beyond the {MAX_DRAWN_VALUE:g} a "
                "run may hold to be drawn; it was not recorded by a lab")


def _unit(run: Run, name: str) -> str:
    try:
        return run.unit(name)
    except KeyError:
        return ""


def check_lesson_signals(own: Mapping[Any, Any], label: str) -> None:
    """A lesson's own signals: at most :data:`MAX_LESSON_SIGNALS`, each named by
    :data:`LESSON_SIGNAL_NAME` (not "t" nor a recorder signal) with a unit of printable
    text of at most :data:`MAX_UNIT_CHARS` characters."""
    if len(own) > MAX_LESSON_SIGNALS:
        raise RunFileError(f"{label}: {len(own)} lesson signals; a run may hold at most "
                           f"{MAX_LESSON_SIGNALS}")
    for name, unit in own.items():
        if (not isinstance(name, str) or LESSON_SIGNAL_NAME.match(name) is None
                or name in SIGNALS or name in CONTACT_SIGNALS or name == "t"):
            raise RunFileError(f"{label}: {quote(name)} cannot name a lesson signal (lower-case "
                               "letters, digits and _, a letter first, at most 32, none of "
                               f"t, {', '.join((*SIGNALS, *CONTACT_SIGNALS))})")
        if not (isinstance(unit, str) and len(unit) <= MAX_UNIT_CHARS and unit.isprintable()):
            raise RunFileError(f"{label}: the lesson signal {quote(name)} has no valid "
                               f"unit ({quote(unit)}): printable text of at most {MAX_UNIT_CHARS} "
                               "characters, e.g. \"A\"")


def _finite(value: Any) -> bool:
    return not isinstance(value, float) or math.isfinite(value)
