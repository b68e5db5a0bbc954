"""Challenges: a target a teacher sets ("%OS ≤ 10 % and Ts ≤ 2 s"), and runs judged against it.

Pure (no server, no page): what the lab's Challenge panel and a classroom's gradebook use.

- :class:`Threshold`: one figure of a run against one limit (``≤``, ``≥``, ``=``, or within
  a tolerance of a target), with its unit;
- :class:`Challenge`: what it measures, the lesson and robot it runs in, its thresholds
  and how its run is started (:class:`RunSpec`); :data:`PRESETS` are the ones a teacher
  picks from, with limits taken from the seeds' and the lab's own numbers (each says
  where it comes from);
- :func:`judge`: a run's figures against a challenge -> :class:`Verdict` (passed, and per
  threshold the figure, the limit and whether it is met; a missing or non-finite figure
  fails, saying why);
- :class:`RunLog`: the distinct runs seen of one arm (figures, which challenge's run
  measured each, and the UTC time they were first seen), its last run and its best run
  against a challenge: only a run started as that challenge's run counts for it;
- :func:`gradebook_csv`: one row per student (name, seat, challenge, thresholds, best
  figures as the page shows them, passed, time), for a spreadsheet.

The figures are those the challenge's lesson declares (its module's ``FIGURES``: SI, or
the unit in the name, ``overshoot_pct``, ``settling_s``, ``grasp_force_n``,
``contact_steady_n``, ...; a test checks every challenge's against its lesson's). They are
measured by the server on the arm that ran; nothing here takes a page's word for a figure.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from typing import Literal

from armlab.kinematics.validate import check_number

#: how a figure is compared with its limit
Kind = Literal["max", "min", "equal", "near"]
#: what the challenge's run is (what the page's "Run the challenge" starts)
RunKind = Literal["step", "line_push", "push", "grasp", "walk", "contact"]
#: runs a :class:`RunLog` keeps (the oldest go first)
MAX_RUNS = 500

_SYMBOL = {"max": "≤", "min": "≥", "equal": "=", "near": "≈"}


@dataclass(frozen=True)
class Threshold:
    """One figure of a run against one limit.

    Attributes:
        figure: the figure's name (one its lesson declares, in the lesson module's ``FIGURES``).
        label: what the page calls it ("%OS").
        unit: its unit as shown ("%", "s", "°", "N", "N·m/rad"; "" for none).
        kind: "max" (figure ≤ limit), "min" (figure ≥ limit), "equal" (figure == limit,
            e.g. which joint was stepped) or "near" (|figure − limit| ≤ tolerance_pct % of
            |limit|).
        limit: the limit (the target for "near").
        tolerance_pct: "near" only: the tolerance, % of the target.
        lo, hi: the range a teacher may set the limit within.
        joint: the figure is a joint's index, shown as the page names the joint ("θ2").
    """

    figure: str
    label: str
    unit: str
    kind: Kind
    limit: float
    tolerance_pct: float = 0.0
    lo: float = 0.0
    hi: float = math.inf
    joint: bool = False

    def __post_init__(self) -> None:
        if self.kind not in _SYMBOL:
            raise ValueError(f"{self.label}: kind must be one of {', '.join(_SYMBOL)}, "
                             f"got {self.kind!r}")
        check_number(self.limit, name=self.label, lo=self.lo, hi=self.hi)
        if self.kind == "near":
            check_number(self.tolerance_pct, name=f"{self.label} tolerance", lo=0.0,
                         hi=100.0)
            if self.limit == 0.0:
                raise ValueError(f"{self.label}: a target of 0 has no relative tolerance")

    def text(self) -> str:
        """The threshold as a person reads it: "%OS ≤ 10 %", "K ≈ 8 N·m/rad ± 10 %",
        "joint stepped = θ2"."""
        unit = f" {self.unit}" if self.unit else ""
        tol = f" ± {self.tolerance_pct:g} %" if self.kind == "near" else ""
        value = joint_name(self.limit) if self.joint else f"{self.limit:g}"
        return f"{self.label} {_SYMBOL[self.kind]} {value}{unit}{tol}"

    def number(self, x: float) -> str:
        """The figure ``x`` as the page shows it, without its unit: 3 significant digits
        ("2.27"), a joint by its name ("θ2")."""
        return joint_name(x) if self.joint else f"{x:.3g}"

    def show(self, x: float | None) -> str:
        """The figure ``x`` as the page shows it, with its unit ("2.27 %", "θ2"; "—":
        none)."""
        if x is None:
            return "—"
        return self.number(x) + (f" {self.unit}" if self.unit else "")

    def met_by(self, x: float) -> bool:
        """Whether the finite figure ``x`` meets this threshold."""
        if self.kind == "max":
            return x <= self.limit
        if self.kind == "min":
            return x >= self.limit
        if self.kind == "equal":
            return x == self.limit
        return abs(x - self.limit) <= self.tolerance_pct / 100.0 * abs(self.limit)

    def usage(self, x: float) -> float:
        """How much of the allowance ``x`` uses: ≤ 1 meets it, smaller is better (the rank
        of runs that all pass or all fail)."""
        if self.kind == "equal":
            return 0.0 if x == self.limit else math.inf
        if self.kind == "near":
            allowed = self.tolerance_pct / 100.0 * abs(self.limit)
            miss = abs(x - self.limit)
            return miss / allowed if allowed > 0 else (0.0 if miss == 0 else math.inf)
        if self.kind == "max":
            return x / self.limit if self.limit > 0 else (0.0 if x <= self.limit else math.inf)
        return self.limit / x if x > 0 else (0.0 if x >= self.limit else math.inf)


@dataclass(frozen=True)
class RunSpec:
    """How the challenge's run is started on the student's arm (the server starts it; the
    page only asks).

    Attributes:
        kind: "step" (one joint's command stepped, ``step_deg``, joint from the challenge's
            ``step_joint`` threshold), "line_push" (the thesis line with a push of the
            ``line_push_n`` threshold's force along −y for ``push_s``), "push" (a push of that
            force for ``push_s`` with the arm holding), "grasp" (the hand closes with the
            student's force limit), "walk" (the quadruped walks forward ``walk_s`` and
            stops), "contact" (``armlab experiment contact``'s run: the hand along the
            thesis line into a wall ``wall_cm`` ahead of the line's start, ``stiffness``
            N/m and ``damping`` N·s/m, to ``depth_cm`` behind its surface, held there;
            judged on the wall's force the loop records every period).
    """

    kind: RunKind
    step_deg: float = -20.0
    push_s: float = 2.0
    walk_s: float = 10.0
    wall_cm: float = 4.0
    depth_cm: float = 2.0
    stiffness: float = 2e4
    damping: float = 50.0


@dataclass(frozen=True)
class Challenge:
    """A target a teacher sets.

    Attributes:
        key: short id ("step").
        title: what the picker shows.
        measures: what it measures, one sentence for the page.
        lesson: the lesson it runs in (a lesson's ``NAME``); robot: that lesson's robot.
        run: how its run is started.
        thresholds: every one must be met.
        source: where the preset's limits come from.
    """

    key: str
    title: str
    measures: str
    lesson: str
    robot: str
    run: RunSpec
    thresholds: tuple[Threshold, ...]
    source: str = ""

    def __post_init__(self) -> None:
        if not self.thresholds:
            raise ValueError(f"challenge {self.key}: no thresholds")
        names = [t.figure for t in self.thresholds]
        if len(set(names)) != len(names):
            raise ValueError(f"challenge {self.key}: a figure has two thresholds")

    @property
    def figures(self) -> tuple[str, ...]:
        """The figures it judges, in its thresholds' order."""
        return tuple(t.figure for t in self.thresholds)

    def threshold(self, figure: str) -> Threshold | None:
        """Its threshold on ``figure``, or None."""
        return next((t for t in self.thresholds if t.figure == figure), None)

    def setting(self, figure: str) -> float | None:
        """The limit of its threshold on ``figure`` (what the run is started with: the
        joint to step, the push's force), or None."""
        t = self.threshold(figure)
        return None if t is None else t.limit

    def text(self) -> str:
        """Its thresholds as one line: "step joint = 2; %OS ≤ 10 %; Ts ≤ 2 s"."""
        return "; ".join(t.text() for t in self.thresholds)

    def with_limit(self, figure: str, value: float) -> Challenge:
        """A copy with the limit (the target, for "near") on ``figure`` set to ``value``.

        Raises:
            ValueError: no threshold on ``figure``, or ``value`` not finite or out of its
                range (the message names the threshold).
        """
        return self._with(figure, limit=value)

    def with_tolerance(self, figure: str, pct: float) -> Challenge:
        """A copy with the tolerance of the "near" threshold on ``figure`` set to ``pct``."""
        t = self.threshold(figure)
        if t is None or t.kind != "near":
            raise ValueError(f"challenge {self.key}: no target with a tolerance on {figure}")
        return self._with(figure, tolerance_pct=pct)

    def _with(self, figure: str, **change: float) -> Challenge:
        t = self.threshold(figure)
        if t is None:
            raise ValueError(f"challenge {self.key}: no threshold on {figure!r}")
        for name, value in change.items():
            lo, hi = (0.0, 100.0) if name == "tolerance_pct" else (t.lo, t.hi)
            change[name] = check_number(value, name=t.label, lo=lo, hi=hi)
        if t.kind == "equal":
            change = {k: float(round(v)) for k, v in change.items()}
        new = replace(t, **change)  # type: ignore[arg-type]  # replace(): only the float fields are named here
        return replace(self, thresholds=tuple(new if x is t else x for x in self.thresholds))


@dataclass(frozen=True)
class Check:
    """One threshold of a judged run.

    Attributes:
        threshold: what was asked. figure: what the run measured (None: nothing).
        ok: met. reason: why not, for a person ("" when met).
    """

    threshold: Threshold
    figure: float | None
    ok: bool
    reason: str = ""

    @property
    def usage(self) -> float:
        """:meth:`Threshold.usage` of the figure (inf: no figure)."""
        return math.inf if self.figure is None else self.threshold.usage(self.figure)


@dataclass(frozen=True)
class Verdict:
    """A run judged against a challenge: passed when every threshold is met."""

    challenge: str
    passed: bool
    checks: tuple[Check, ...]

    @property
    def measured(self) -> bool:
        """Whether the run measured any of the challenge's figures."""
        return any(c.figure is not None for c in self.checks)

    def rank(self) -> tuple[bool, float]:
        """Sort key, best first: passed runs, then the one furthest inside its limits."""
        return (not self.passed, max((c.usage for c in self.checks), default=math.inf))

    def figures(self) -> dict[str, float | None]:
        """The judged figures by name."""
        return {c.threshold.figure: c.figure for c in self.checks}


def joint_name(index: float) -> str:
    """A joint's index as the lesson's page names the joint: 2 -> "θ2" (the receptionist
    arm's joints are θ0, θ1, θ2; an index that is not a whole number is shown as it is)."""
    return f"θ{int(index)}" if float(index).is_integer() else f"joint {index:g}"


def _figure(figures: Mapping[str, object], name: str) -> tuple[float | None, str]:
    """(the finite figure ``name``, "") or (None, why there is none)."""
    if name not in figures or figures[name] is None:
        return None, "not measured yet: run the challenge"
    value = figures[name]
    if isinstance(value, bool):
        value = float(value)
    if not isinstance(value, int | float):
        return None, f"{value!r} is not a number"
    x = float(value)
    if not math.isfinite(x):
        return None, f"{x} is not a finite number"
    return x, ""


def judge(challenge: Challenge, figures: Mapping[str, object]) -> Verdict:
    """``figures`` (name -> value, e.g. a lesson's ``run_figures()``) against
    ``challenge``: every threshold checked; a missing, None or non-finite figure fails
    with the reason."""
    checks = []
    for t in challenge.thresholds:
        x, why = _figure(figures, t.figure)
        if x is None:
            checks.append(Check(t, None, False, why))
        elif t.met_by(x):
            checks.append(Check(t, x, True))
        else:
            checks.append(Check(t, x, False, f"{t.show(x)} does not meet {t.text()}"))
    return Verdict(challenge.key, all(c.ok for c in checks), tuple(checks))


def utc_now() -> str:
    """Now, UTC, ISO 8601 to the second ("2026-11-28T03:18:35Z")."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


#: what a figure's tag says when no challenge's run measured it
NOT_A_CHALLENGE_RUN = "not measured as this challenge's run: press Run the challenge"


@dataclass(frozen=True)
class LoggedRun:
    """A run as a :class:`RunLog` keeps it: its figures, when they were first seen, and per
    figure the key of the challenge whose run measured it (absent or None: a run the
    student made otherwise)."""

    figures: Mapping[str, float | None]
    when: str
    tags: Mapping[str, str | None] = field(default_factory=dict)

    def counted(self, key: str) -> dict[str, float | None]:
        """The figures that count for challenge ``key``: those its own run measured (the
        others None)."""
        return {k: (v if self.tags.get(k) == key else None) for k, v in self.figures.items()}


class RunLog:
    """The distinct runs of one arm, as the server saw its lesson's figures change.

    The lab reads a lesson's figures now and then (:meth:`observe`), with the challenge
    whose run measured each (a lesson's ``run_tags()``); a run is kept when they differ
    from the last kept ones. Its last and best runs are worked out against whichever
    challenge is set now, so a teacher's new limits apply to runs already made; only
    figures measured by that challenge's own run count (a step made before the challenge
    was set, or by the Step button, does not). A lesson that tags nothing (the hand, the
    quadruped) is tagged here: :meth:`expect` says a challenge's run was started, and the
    next change of that challenge's figures is its run.
    Not thread-safe: one owner calls it (the lab's ticker, under its lock).
    """

    def __init__(self, *, max_runs: int = MAX_RUNS) -> None:
        self.runs: list[LoggedRun] = []
        self._max = max_runs
        self._expect: tuple[str, tuple[str, ...], dict[str, float | None]] | None = None
        self._result = 0  #: the newest challenge run taken by :meth:`take`

    def take(self, results: Iterable[tuple[int, Mapping[str, float | None],
                                           Mapping[str, str | None]]]) -> int:
        """Keep a lesson's challenge runs not kept yet: (number, figures, tags), numbered
        from 1 (a lesson's ``challenge_results()``; each kept even if the lesson's figures
        changed again before this look); how many were new."""
        new = 0
        for number, figures, tags in results:
            if number > self._result:
                self._result = number
                new += self.observe(figures, tags=tags)
        return new

    def expect(self, challenge: Challenge, figures: Mapping[str, float | None]) -> None:
        """``challenge``'s run was just started on an arm whose figures are ``figures``
        now (for a lesson without ``run_tags``): its next change of them is that run."""
        self._expect = (challenge.key, challenge.figures,
                        {f: figures.get(f) for f in challenge.figures})

    def observe(self, figures: Mapping[str, float | None], *,
                tags: Mapping[str, str | None] | None = None, when: str | None = None) -> bool:
        """Keep ``figures`` (with ``tags``: figure -> key of the challenge whose run measured
        it) as a new run if they differ from the last kept; True if kept."""
        figures = dict(figures)
        tags = self._tag(figures) if tags is None else dict(tags)
        if self.runs and _same(self.runs[-1].figures, figures) and self.runs[-1].tags == tags:
            return False
        self.runs.append(LoggedRun(figures, when or utc_now(), tags))
        del self.runs[:-self._max]
        return True

    def _tag(self, figures: Mapping[str, float | None]) -> dict[str, str | None]:
        """Tags of an untagged lesson's ``figures``: the expected challenge's once its
        figures changed, else those of the last run (figures left as they were)."""
        last = dict(self.runs[-1].tags) if self.runs else {}
        if self._expect is not None:
            key, names, before = self._expect
            now = {f: figures.get(f) for f in names}
            if not _same(now, before) and all(v is not None for v in now.values()):
                self._expect = None
                return {**{k: None for k in figures}, **dict.fromkeys(names, key)}
        if self.runs and not _same(self.runs[-1].figures, figures):
            changed = {k for k in figures if not _same({k: figures[k]},
                                                       {k: self.runs[-1].figures.get(k)})}
            return {k: (None if k in changed else last.get(k)) for k in figures}
        return last

    def _judged(self, challenge: Challenge) -> Iterable[tuple[LoggedRun, Verdict]]:
        for run in self.runs:
            verdict = judge(challenge, run.counted(challenge.key))
            if verdict.measured:
                yield run, _why_not_counted(verdict, run)

    def last(self, challenge: Challenge) -> tuple[LoggedRun, Verdict] | None:
        """The newest run of ``challenge``'s own (one that measured any of its figures),
        judged; or None."""
        judged = list(self._judged(challenge))
        return judged[-1] if judged else None

    def best(self, challenge: Challenge) -> tuple[LoggedRun, Verdict] | None:
        """The best run of ``challenge``'s own (a pass first, then the one furthest inside
        its limits; the earlier of equals), judged; None before any."""
        best: tuple[LoggedRun, Verdict] | None = None
        for run, verdict in self._judged(challenge):
            if best is None or verdict.rank() < best[1].rank():
                best = (run, verdict)
        return best


def _why_not_counted(verdict: Verdict, run: LoggedRun) -> Verdict:
    """``verdict`` with a figure measured by another run than the challenge's said so."""
    checks = tuple(replace(c, reason=NOT_A_CHALLENGE_RUN)
                   if c.figure is None and run.figures.get(c.threshold.figure) is not None
                   else c for c in verdict.checks)
    return replace(verdict, checks=checks)


def _same(a: Mapping[str, object], b: Mapping[str, object]) -> bool:
    """Equal figure dicts, NaN equal to NaN."""
    if a.keys() != b.keys():
        return False
    for k in a:
        x, y = a[k], b[k]
        if x != y and not (isinstance(x, float) and isinstance(y, float)
                           and math.isnan(x) and math.isnan(y)):
            return False
    return True


def _cell(text: str) -> str:
    """A CSV cell a spreadsheet shows as text (a typed name starting with = + - @ would
    otherwise be run as a formula)."""
    return "'" + text if text[:1] in ("=", "+", "-", "@", "\t", "\r") else text


def figure_header(t: Threshold) -> str:
    """A gradebook column's header: the figure as the page labels it, with its unit
    ("%OS (%)", "Ts (s)", "joint stepped")."""
    return f"{t.label} ({t.unit})" if t.unit else t.label


#: the gradebook's encoding: UTF-8 with a byte-order mark, so a spreadsheet reads "≤", "θ2"
GRADEBOOK_ENCODING = "utf-8-sig"


def gradebook_csv(challenge: Challenge,
                  rows: Iterable[tuple[str, str, tuple[LoggedRun, Verdict] | None]]) -> str:
    """The gradebook: one row per (student name, seat, best run or None), in the given
    order (encode it with :data:`GRADEBOOK_ENCODING`; :func:`gradebook_bytes`).

    Columns: name, seat (tells two students of one name apart), challenge, thresholds,
    one per judged figure (headed and written as the page shows it: 3 significant
    digits in the header's unit, a joint by its name, "θ2"), passed ("yes", "no", or
    "no run"), time_utc (ISO 8601, when the server first saw the best run). Lines end in
    CRLF (RFC 4180).
    """
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\r\n")
    w.writerow(["name", "seat", "challenge", "thresholds",
                *(figure_header(t) for t in challenge.thresholds), "passed", "time_utc"])
    for name, seat, best in rows:
        if best is None:
            figs: list[str] = [""] * len(challenge.figures)
            passed, when = "no run", ""
        else:
            run, verdict = best
            got = verdict.figures()
            figs = ["" if got[t.figure] is None else t.number(float(got[t.figure]))  # type: ignore[arg-type]  # got[t.figure] is not None: checked just before
                    for t in challenge.thresholds]
            passed, when = ("yes" if verdict.passed else "no"), run.when
        w.writerow([_cell(name), _cell(seat), challenge.key, challenge.text(), *figs, passed,
                    when])
    return out.getvalue()


def gradebook_bytes(challenge: Challenge,
                    rows: Iterable[tuple[str, str, tuple[LoggedRun, Verdict] | None]]) -> bytes:
    """:func:`gradebook_csv` as the file a spreadsheet opens: UTF-8 with a byte-order
    mark."""
    return gradebook_csv(challenge, rows).encode(GRADEBOOK_ENCODING)


# ---------------------------------------------------------------------------- presets

def _step() -> Challenge:
    return Challenge(
        key="step", title="Step: %OS and Ts",
        measures="A −20° step of one joint's command: the PD loop's overshoot and settling "
                 "time (eq. 2.16, 2.18), measured on the arm.",
        lesson="compliance", robot="receptionist_arm", run=RunSpec("step", step_deg=-20.0),
        thresholds=(
            Threshold("step_joint", "joint stepped", "", "equal", 2.0, lo=0.0, hi=5.0,
                      joint=True),
            Threshold("overshoot_pct", "%OS", "%", "max", 2.0, lo=0.0, hi=100.0),
            Threshold("settling_s", "Ts", "s", "max", 3.0, lo=0.05, hi=20.0),
        ),
        source="Measured on the simulated arm by the challenge's run (from the thesis "
               "line's start at rest: the same figures every run): the lab's default (Kp "
               "20, Kv 5; designed %OS 12 %, Ts 1.6 s, armlab/control/params.py) gives %OS 4.28 %, "
               "Ts 1.74 s and fails; Kv 8 (ζp = Kv/(2√Kp) 0.89, eq. 2.12) gives 0 %, Ts "
               "2.08 s. Ts is within 2 % of a 20° step, 0.4°: about the servos' resolution, "
               "so a small change of gains moves it much; its limit is loose. Joint 2 is "
               "θ2, the thesis's servo 3 (chapter 4's metric).")


def _line_push() -> Challenge:
    return Challenge(
        key="line_push", title="Thesis line under a push",
        measures="The thesis's 20 cm line with a push of the hand against the motion: the "
                 "largest |θ_cmd − θ| of any joint over the run (chapter 4's metric).",
        lesson="compliance", robot="receptionist_arm", run=RunSpec("line_push", push_s=2.0),
        thresholds=(
            Threshold("line_push_n", "push", "N", "min", 4.0, lo=0.5, hi=20.0),
            Threshold("pushed_error_deg", "max angle error", "°", "max", 6.0, lo=0.1,
                      hi=90.0),
        ),
        source="Thesis ch. 4: the free line stays under 6° with the PD loop, the pushed one "
               "goes over 15° on servo 3 with compliance on (fig. 4.9/4.12); the lesson's "
               "push is 4 N. Measured on the simulated arm by the challenge's run (the push "
               "begins with the line, from its start at rest): the default gains give "
               "19.8°; K_env 64, Kv 8 7.7°; K_env 100, Kv 8 5.97°.")


def _stiffness() -> Challenge:
    return Challenge(
        key="stiffness", title="Reach a joint stiffness",
        measures="A 4 N push on the holding arm: the environment's static stiffness "
                 "Δτ_ext/Δθ_env = 1/C_f on the joint that felt the most torque (eq. 2.15), "
                 "measured.",
        lesson="compliance", robot="receptionist_arm", run=RunSpec("push", push_s=3.0),
        thresholds=(
            Threshold("push_n", "push", "N", "min", 4.0, lo=0.5, hi=20.0),
            Threshold("stiffness_nm_per_rad", "stiffness", "N·m/rad", "near", 8.0,
                      tolerance_pct=10.0, lo=0.1, hi=1000.0),
        ),
        source="The default K_env 16 N·m/rad, K_f 4 give 1/C_f = K_env/K_f = 4 N·m/rad "
               "(armlab/control/params.py, eq. 2.15; measured 4.04); the target doubles it, within "
               "10 % (K_env 32 measured 8.00).")


def _grasp() -> Challenge:
    return Challenge(
        key="grasp", title="Hold a grasp",
        measures="The hand closes on the object: it must hold (every finger at 90 % of F) "
                 "with a steady fingertip force of at least E, and squeeze no harder than "
                 "P at any time (the first touch).",
        lesson="hand", robot="receptionist_arm", run=RunSpec("grasp"),
        thresholds=(
            Threshold("grasp_held", "held (1 = yes)", "", "equal", 1.0, lo=0.0, hi=1.0),
            Threshold("grasp_force_n", "steady force", "N", "min", 1.0, lo=0.05, hi=5.0),
            Threshold("grasp_peak_n", "peak force", "N", "max", 1.5, lo=0.05, hi=10.0),
        ),
        source="The lesson's default force limit is 0.8 N (armlab/app/lessons/hand.py; `armlab "
               "experiment hand-grip`: steady 0.800 N, peak 0.801 N): the student raises F "
               "to hold 1 N, and no higher than 1.5 N (the grasp should not crush). The "
               "simulated hand does not slip: 'held' is every finger at 90 % of F.")


def _walk() -> Challenge:
    return Challenge(
        key="walk", title="Walk: eq. 4.1 error",
        measures="The quadruped walks forward 10 s: seed 003's eq. 4.1, the mean "
                 "|servo − commanded| / commanded angle over every servo, %.",
        lesson="quadruped", robot="quadruped", run=RunSpec("walk", walk_s=10.0),
        thresholds=(
            Threshold("eq41_error_pct", "eq. 4.1 error", "%", "max", 1.201, lo=0.01,
                      hi=100.0),
        ),
        source="Seed 003 §4.1.2: the paper's robot measured 1.201 % "
               "(armlab/app/lessons/quadruped.py, PAPER_ERROR_PCT). Measured on the simulated "
               "robot: 1.38 % at the lesson's 0.5 cycles/s, 1.12 % at 0.25.")


def _contact() -> Challenge:
    return Challenge(
        key="contact", title="Touch the wall",
        measures="The hand runs along the thesis line into a wall 4 cm ahead (2·10⁴ N/m: "
                 "a wooden table), the command 2 cm behind its surface, and holds 4 s: the "
                 "impact's peak force must stay at most P, and the steady force (the mean "
                 "of the last second) within a tolerance of F; measured from the wall's "
                 "force the loop records every period (the plant's ground truth).",
        lesson="compliance", robot="receptionist_arm", run=RunSpec("contact"),
        thresholds=(
            Threshold("contact_peak_n", "peak force", "N", "max", 9.0, lo=0.1, hi=100.0),
            Threshold("contact_steady_n", "steady force", "N", "near", 4.0,
                      tolerance_pct=25.0, lo=0.05, hi=100.0),
        ),
        source="`armlab experiment contact` (its defaults: wall 4 cm ahead, 2 cm of "
               "command behind it, 2·10⁴ N/m, 50 N·s/m), whose figures the challenge's run "
               "gives to the last digit: the lab's default gains (K_q = K_env/K_f = 4 "
               "N·m/rad) press 2.01 N after a 6.81 N peak and fail on the steady force; "
               "K_env 32, D_env 20 press 4.83 N after 8.78 N and pass (K_env 32 alone: "
               "1.44 N after 8.98 N; K_env 32, K_f 2: 8.78 N after 10.6 N), each a mean "
               "over the hand's bounces: with the thesis's α 0.05 the load filter's lag "
               "makes it limit-cycle on the wall. With α 0.6 it rests on it: K_env 64 "
               "presses a steady 4.40 N after 6.92 N, the law's prediction 4.21 N "
               "(docs/compliance.md, \"Contact\").")


#: The challenges a teacher picks from, by key.
PRESETS: dict[str, Challenge] = {c.key: c for c in (
    _step(), _line_push(), _stiffness(), _grasp(), _walk(), _contact())}
