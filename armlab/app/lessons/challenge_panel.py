"""The Challenge panel: the target a teacher sets, and where a run stands against it.

- :class:`ChallengeDesk`: the lab's one challenge (:mod:`armlab.control.challenges`). A
  "Challenge" folder on the server's GUI, so on every page: a picker of the
  :data:`~armlab.control.challenges.PRESETS`, the limits as number inputs, the target, a
  **Run the challenge** button, and the last and best run of the lab's own lesson against
  it. In a classroom that folder is part of the shared GUI, so
  :class:`armlab.app.classroom.roles.Roles` admits its changes from presenters only: the
  presenter picks and edits, a student's change is refused and put back. A thread reads
  the lab's lesson's figures once a second (``run_figures()``: worked out by the server
  from the arm that ran) into a :class:`~armlab.control.challenges.RunLog`.
- :class:`MyChallenge`: one student's page's own panel (``client.gui``): their last and
  best run against the challenge, and a button that asks the server to start the
  challenge's run on their own arm. The page sends only that click; what passes is
  judged from the figures the server measured.
- :func:`start_run`: what a **Run the challenge** click starts on a lesson.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Protocol

import viser

from armlab.app.lessons import LessonHandle
from armlab.app.lessons._common import guarded, set_content
from armlab.app.lessons.catalog import all_lessons
from armlab.app.page.inputs import GuardedNumber, notify
from armlab.control.challenges import (
    PRESETS,
    Challenge,
    LoggedRun,
    RunLog,
    Verdict,
)

#: what the picker shows for no challenge
NO_CHALLENGE = "none"
#: s between two readings of a lesson's figures
READ_S = 1.0


def figures_of(lesson: LessonHandle | None) -> dict[str, float | None]:
    """The lesson's figures by name, as plain floats (None: not measured; {}: no lesson)."""
    if lesson is None:
        return {}
    return {k: None if v is None else float(v)
            for k, v in lesson.run_figures().items()}


def tags_of(lesson: LessonHandle | None) -> dict[str, str | None] | None:
    """Per figure of the lesson's, the key of the challenge whose run measured it (its
    ``run_tags()``); None: the lesson tags none (the run log tags it, ``RunLog.expect``)."""
    tags = getattr(lesson, "run_tags", None)
    return None if tags is None else dict(tags())


def results_of(lesson: LessonHandle | None) -> list:
    """The lesson's challenge runs (its ``challenge_results()``: number, figures, tags),
    or [] (a lesson that keeps none)."""
    results = getattr(lesson, "challenge_results", None)
    return [] if results is None else list(results())


def _lesson_title(name: str) -> str:
    """The switcher's title of lesson ``name`` ("Hand grasp")."""
    lesson = all_lessons().get(name)
    return name if lesson is None else lesson.title


def target_markdown(challenge: Challenge | None) -> str:
    """The target as the page shows it (markdown)."""
    if challenge is None:
        return "*No challenge set.*"
    lines = [f"**{challenge.title}** (in the {_lesson_title(challenge.lesson)} lesson)",
             "", challenge.measures, ""]
    lines += [f"- {t.text()}" for t in challenge.thresholds]
    return "\n".join(lines)


def verdict_markdown(title: str, judged: tuple[LoggedRun, Verdict] | None) -> str:
    """One judged run (its time, ✓/✗ per threshold with the figure) as markdown."""
    if judged is None:
        return f"**{title}**: no run yet (press **Run the challenge**)."
    run, verdict = judged
    head = "✓ passed" if verdict.passed else "✗ not passed"
    lines = [f"**{title}** ({run.when.replace('T', ' ').rstrip('Z')} UTC): {head}"]
    for c in verdict.checks:
        mark = "✓" if c.ok else "✗"
        got = c.threshold.show(c.figure)
        why = f" — {c.reason}" if c.reason and c.figure is None else ""
        lines.append(f"- {mark} {c.threshold.label}: {got} (target {c.threshold.text()}){why}")
    return "\n".join(lines)


def standing_markdown(challenge: Challenge | None, log: RunLog, *, whose: str) -> str:
    """Last and best run of ``log`` against ``challenge`` (``whose``: "Your", "The shared
    arm's")."""
    if challenge is None:
        return ""
    last, best = log.last(challenge), log.best(challenge)
    text = verdict_markdown(f"{whose} last run", last)
    if best is not None and (last is None or best[0] is not last[0]):
        text += "\n\n" + verdict_markdown(f"{whose} best run", best)
    return text


def start_run(lesson: LessonHandle | None, lesson_name: str, challenge: Challenge) -> str:
    """Start ``challenge``'s run on ``lesson`` (the lesson called ``lesson_name``); what was
    started, for a person.

    Raises:
        ValueError: no lesson, another lesson than the challenge's, or the lesson refuses
            (the arm stopped, the hand not open, ...).
    """
    if lesson is None:
        raise ValueError("no lesson is open")
    if lesson_name != challenge.lesson:
        raise ValueError(f"this challenge runs in the {_lesson_title(challenge.lesson)} "
                         "lesson: open it first")
    act: Any = lesson
    if not callable(getattr(act, "run_challenge", None)):
        raise ValueError(f"the {lesson_name} lesson has no challenge run")
    # from the challenge's own state (the pose, the hand open, the robot standing at its
    # start, at rest), its commands timed in loop periods, its figures tagged
    return str(act.run_challenge(challenge))


class DeskLab(Protocol):
    """What the desk uses of the lab (:class:`armlab.app.lab.server.Lab`)."""

    @property
    def server(self) -> viser.ViserServer: ...

    @property
    def lesson(self) -> LessonHandle | None: ...

    @property
    def lesson_name(self) -> str: ...


class ChallengeDesk:
    """The lab's challenge and its "Challenge" folder (see the module docstring).

    Args:
        lab: the lab (its server and open lesson).
        shared: the lesson drives the class's shared arm (classroom): the result is labelled
            so, and the folder has no Run button (a follower could not press it: each page
            has its own, :class:`MyChallenge`, the presenter's for the shared arm).
        order: the folder's place in the panel.
    """

    def __init__(self, lab: DeskLab, *, shared: bool = False, order: float = -88.0) -> None:
        self.lab = lab
        self._shared = shared
        self._whose = "The shared arm's" if shared else "Your"
        self._lock = threading.RLock()
        self._challenge: Challenge | None = None
        self.log = RunLog()  #: the runs of the lab's own lesson
        self._limits: list[Any] = []
        gui = lab.server.gui
        titles = {c.title: c.key for c in PRESETS.values()}
        self._keys = {NO_CHALLENGE: None, **titles}
        self.folder = gui.add_folder("Challenge", order=order, expand_by_default=False)
        with self.folder:
            self.pick = gui.add_dropdown("Target", tuple(self._keys),
                                         initial_value=NO_CHALLENGE,
                                         hint="A target to meet; the server measures every "
                                              "run and judges it")
            self.target = gui.add_markdown(target_markdown(None))
            self.limits = gui.add_folder("Limits", expand_by_default=False, visible=False)
            self.run_button = gui.add_button("Run the challenge", icon=viser.Icon.PLAYER_PLAY,
                                             visible=False,
                                             hint="Start the challenge's run on this arm; "
                                                  "the server measures it")
            self.result = gui.add_markdown("")
        self.pick.on_update(lambda e: guarded(e, self._on_pick, undo=self._show_pick))
        self.run_button.on_click(lambda e: guarded(e, self.run))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_often, name="armlab-challenge",
                                        daemon=True)
        self._thread.start()

    # -- the challenge ---------------------------------------------------------------

    @property
    def challenge(self) -> Challenge | None:
        """The challenge set now (None: none)."""
        with self._lock:
            return self._challenge

    def set_challenge(self, challenge: Challenge | None) -> None:
        """Make ``challenge`` the lab's (its preset's limits or edited ones); shown on every
        page."""
        with self._lock:
            self._challenge = challenge
            self._build_limits(challenge)
            self._show_pick()
            set_content(self.target, target_markdown(challenge))
            self.run_button.visible = challenge is not None and not self._shared
            self._show_result()

    def set_limit(self, figure: str, value: float, *, tolerance: bool = False) -> None:
        """Change the limit (or, ``tolerance``, the tolerance %) on ``figure`` of the
        challenge set now (ValueError to refuse)."""
        with self._lock:
            c = self._challenge
            if c is None:
                raise ValueError("no challenge is set")
            c = c.with_tolerance(figure, value) if tolerance else c.with_limit(figure, value)
            self._challenge = c
            set_content(self.target, target_markdown(c))
            self._show_result()

    def _on_pick(self) -> None:
        key = self._keys.get(str(self.pick.value))
        current = self.challenge
        if (None if current is None else current.key) == key:
            return
        self.set_challenge(None if key is None else PRESETS[key])

    def _show_pick(self) -> None:
        c = self.challenge
        want = NO_CHALLENGE if c is None else c.title
        if self.pick.value != want:
            self.pick.value = want  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none

    def _build_limits(self, challenge: Challenge | None) -> None:
        """The number inputs of ``challenge``'s limits (replacing the last one's)."""
        for handle in self._limits:
            handle.remove()
        self._limits = []
        self.limits.visible = challenge is not None
        if challenge is None:
            return
        gui = self.lab.server.gui
        with self.limits:
            for t in challenge.thresholds:
                unit = f" ({t.unit})" if t.unit else ""
                sym = {"max": "≤", "min": "≥", "equal": "=", "near": "≈"}[t.kind]
                step = 1.0 if t.kind == "equal" else 0.01
                handle = gui.add_number(f"{t.label} {sym}{unit}", initial_value=t.limit,
                                        min=t.lo, max=t.hi, step=step)
                GuardedNumber(handle, name=t.label, lo=t.lo, hi=t.hi,
                              apply=lambda v, f=t.figure: self.set_limit(f, v))  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
                self._limits.append(handle)
                if t.kind == "near":
                    tol = gui.add_number(f"{t.label} tolerance (%)",
                                         initial_value=t.tolerance_pct, min=0.0, max=100.0,
                                         step=0.5)
                    GuardedNumber(tol, name=f"{t.label} tolerance", lo=0.0, hi=100.0,
                                  apply=lambda v, f=t.figure: self.set_limit(  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
                                      f, v, tolerance=True))
                    self._limits.append(tol)

    # -- runs ------------------------------------------------------------------------

    def run(self) -> str:
        """Start the challenge's run on the lab's own lesson (the shared arm in a class);
        what was started. ValueError when it cannot be."""
        c = self.challenge
        if c is None:
            raise ValueError("pick a challenge first")
        lesson = self.lab.lesson
        before = figures_of(lesson)
        started = start_run(lesson, self.lab.lesson_name, c)
        if tags_of(lesson) is None:
            with self._lock:
                self.log.expect(c, before)
        return started

    def runs(self) -> RunLog:
        """A copy of :attr:`log` (the lab's own lesson's runs), for another thread."""
        with self._lock:
            copy = RunLog()
            copy.runs = list(self.log.runs)
            return copy

    def read(self) -> None:
        """Read the lab's lesson's figures into :attr:`log` and show where it stands."""
        lesson = self.lab.lesson
        figures, tags, results = figures_of(lesson), tags_of(lesson), results_of(lesson)
        with self._lock:
            self.log.take(results)
            if figures:
                self.log.observe(figures, tags=tags)
            self._show_result()

    def _show_result(self) -> None:
        set_content(self.result, standing_markdown(self.challenge, self.log, whose=self._whose))

    def _read_often(self) -> None:
        while not self._stop.wait(READ_S):
            try:
                self.read()
            except Exception as exc:  # a lesson closing mid-read: next time
                print(f"armlab: challenge: {type(exc).__name__}: {exc}"[:200], flush=True)

    def close(self) -> None:
        """Stop reading (the folder goes with the server)."""
        self._stop.set()


class MyChallenge:
    """One page's own challenge panel (``client.gui``, that page only): a student's, for
    their own arm, or a presenter's, for the shared arm.

    Args:
        client: the page.
        on_run: called when the page asks for the challenge's run (the room starts it on
            the page's arm; a ValueError's message is shown there); returns what started.
        whose: whose runs the panel shows ("Your", "The shared arm's").
        button: the run button's label.
        order: the folder's place in the panel.
    """

    def __init__(self, client: viser.ClientHandle, *, on_run: Callable[[], str],
                 whose: str = "Your", button: str = "Run the challenge on my arm",
                 order: float = -87.0) -> None:
        self.client = client
        self.whose = whose
        gui = client.gui
        self.folder = gui.add_folder("My challenge", order=order, visible=False)
        with self.folder:
            self.text = gui.add_markdown("")
            self.button = gui.add_button(button, icon=viser.Icon.PLAYER_PLAY,
                                         hint="Start the challenge's run; the server "
                                              "measures it on the arm that ran")
        self.button.on_click(lambda e: guarded(e, lambda: self._run(e, on_run)))

    @staticmethod
    def _run(event: viser.GuiEvent, on_run: Callable[[], str]) -> None:
        notify(event.client, "Challenge", f"Started {on_run()}.", color="green", seconds=4.0)

    def show(self, challenge: Challenge | None, log: RunLog | None) -> None:
        """Show where ``log``'s runs stand against ``challenge`` (hidden: no challenge)."""
        shown = challenge is not None
        if self.folder.visible != shown:
            self.folder.visible = shown
        if challenge is None:
            return
        # the target too: a page on its own arm does not get the shared folder's updates
        standing = standing_markdown(challenge, log or RunLog(), whose=self.whose)
        set_content(self.text, target_markdown(challenge) + "\n\n" + standing)

    def remove(self) -> None:
        """Take the panel off the page."""
        self.folder.remove()
