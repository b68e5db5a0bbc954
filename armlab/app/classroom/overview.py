"""The presenter's class overview: who is there, their gains, the figures of their last run.

A table on every presenter's page (refreshed once a second), a "Student" picker and
two buttons: "Show" draws that student's arm as a ghost beside the shared one, labelled
with their name, on the presenters' pages only (the projector shows it; no student's
page does), and frames it with the shared arm ("Hide" while that student's ghost shows
takes it away); "Use these gains" copies the student's gains to the shared arm through
the shared lesson's own validation and gain warning.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import viser

from armlab.app.export.sections import figure_label
from armlab.app.lessons import Figures
from armlab.app.lessons._common import esc, send_download
from armlab.control.challenges import Challenge, LoggedRun, Verdict
from armlab.control.params import Params

#: what the picker shows when nobody is picked
NOBODY = "—"
#: m: where the ghost of a student's arm stands beside the shared one (world y)
GHOST_OFFSET = (0.0, 0.55, 0.0)
GHOST_RGBA = (0.2, 0.6, 0.9, 0.45)
#: the button's label while nobody's ghost shows (or another's) / while the picked one's does
SHOW, HIDE = "Show", "Hide"


@dataclass(frozen=True)
class StudentRow:
    """One student as the overview shows them.

    Attributes:
        client_id: their page. name: what they typed, or automatic.
        view: "Follow the teacher" or "My arm".
        params: the gains of their arm (None: no arm yet).
        figures: of their own lesson's last runs (its ``run_figures()``).
        best: their best run against the challenge, judged (None: no challenge or no run).
    """

    client_id: int
    name: str
    view: str
    params: Params | None = None
    figures: Figures = field(default_factory=dict)
    best: tuple[LoggedRun, Verdict] | None = None

    @property
    def label(self) -> str:
        """How the picker names them."""
        return f"{self.name} (#{self.client_id})"


def _fmt(x: float | None, spec: str) -> str:
    return "—" if x is None or not math.isfinite(x) else format(x, spec)


def best_html(best: tuple[LoggedRun, Verdict] | None) -> str:
    """A student's best run against the challenge, one table cell's HTML: ✓/✗, the judged
    figures, the time (UTC) the server saw it."""
    if best is None:
        return "—"
    run, verdict = best
    figs = ", ".join(f"{c.threshold.label} {c.threshold.show(c.figure)}" for c in verdict.checks)
    mark = ("<b style='color:#2e7d32'>✓</b>" if verdict.passed
            else "<b style='color:#b00020'>✗</b>")
    return f"{mark} {esc(figs)} <span style='color:#555'>{esc(run.when[11:19])}</span>"


def overview_html(rows: list[StudentRow], *, challenge: Challenge | None = None,
                  columns: Mapping[str, str] | None = None) -> str:
    """The overview table (HTML), one row per student: their gains and the ``columns``
    of their figures (figure -> column head: the class lesson's ``OVERVIEW``); with a
    ``challenge``, a column of each student's best run against it."""
    columns = columns or {}
    if not rows:
        return "<i>No students yet: they join by the url or the QR code.</i>"
    best_head = "" if challenge is None else f"<th>best: {esc(challenge.title)}</th>"
    heads = "".join(f"<th>{esc(head)}</th>" for head in columns.values())
    head = ("<tr><th>student</th><th>view</th><th>Kp</th><th>Kv</th>"
            f"{heads}{best_head}</tr>")
    body = []
    for r in rows:
        f = r.figures
        kp = None if r.params is None else r.params.kp
        kv = None if r.params is None else r.params.kv
        best = "" if challenge is None else f"<td>{best_html(r.best)}</td>"
        body.append(
            f"<tr><td>{esc(r.label)}</td><td>{'own arm' if r.view == 'My arm' else 'follows'}"
            f"</td><td>{_fmt(kp, '.3g')}</td><td>{_fmt(kv, '.3g')}</td>"
            + "".join(f"<td>{_fmt(f.get(c), figure_label(c)[2] or '.3g')}</td>"
                      for c in columns)
            + f"{best}</tr>")
    return ("<table style='font-size:0.8em;border-collapse:collapse;width:100%'>"
            f"{head}{''.join(body)}</table>")


class ClassOverview:
    """The overview on one presenter's page (its own GUI: ``client.gui``).

    Args:
        client: the presenter's page.
        on_show: called with the picked student's client id, or None to hide the ghost
            (the button pressed while the picked student's ghost shows: :meth:`showing`).
        on_use: called with the picked student's client id; returns the message to show.
        on_gradebook: makes the gradebook, (file name, CSV bytes); a ValueError's message
            is shown (no challenge yet).
    """

    def __init__(self, client: viser.ClientHandle, *, on_show: Callable[[int | None], None],
                 on_use: Callable[[int], str],
                 on_gradebook: Callable[[], tuple[str, bytes]] | None = None) -> None:
        self.client = client
        self._ids: dict[str, int] = {}
        self._shown: int | None = None  #: whose ghost shows (:meth:`showing`)
        gui = client.gui
        with gui.add_folder("Class", order=-93.0, expand_by_default=True):
            self.table = gui.add_html(overview_html([]))
            self.pick = gui.add_dropdown("Student", (NOBODY,), initial_value=NOBODY)
            self.show = gui.add_button(SHOW, icon=viser.Icon.EYE,
                                       hint="Draw this student's arm as a ghost beside "
                                            "the shared one, with their name, on the "
                                            "presenters' pages (Hide: take it away)")
            self.use = gui.add_button("Use these gains", icon=viser.Icon.COPY,
                                      hint="Copy this student's gains to the shared arm "
                                           "(checked as any gain change)")
            self.gradebook = gui.add_button(
                "Gradebook CSV", icon=viser.Icon.DOWNLOAD, visible=on_gradebook is not None,
                hint="Download one row per student: name, challenge, thresholds, best "
                     "figures, passed, time (UTC)")
        if on_gradebook is not None:
            self.gradebook.on_click(lambda e: send_download(e, on_gradebook))
        self.show.on_click(lambda _e: on_show(None if self._hides() else self.picked()))
        self.use.on_click(lambda _e: self._use(on_use))
        self.pick.on_update(lambda _e: self._label_button())

    def picked(self) -> int | None:
        """Client id of the picked student, or None."""
        return self._ids.get(str(self.pick.value))

    def showing(self, client_id: int | None) -> None:
        """Student ``client_id``'s ghost shows now (None: nobody's); the button hides it
        while that student is picked."""
        self._shown = client_id
        self._label_button()

    def _hides(self) -> bool:
        return self._shown is not None and self.picked() == self._shown

    def _label_button(self) -> None:
        label = HIDE if self._hides() else SHOW
        if self.show.label != label:
            self.show.label = label

    def _use(self, on_use: Callable[[int], str]) -> None:
        cid = self.picked()
        if cid is None:
            self.client.add_notification("Pick a student", "Choose one in Student first.",
                                         auto_close_seconds=5.0)
            return
        self.client.add_notification("Gains", on_use(cid), auto_close_seconds=8.0)

    def refresh(self, rows: list[StudentRow], *, challenge: Challenge | None = None,
                columns: Mapping[str, str] | None = None) -> None:
        """Show ``rows`` with their ``columns`` of figures (sent to the page only when
        something changed)."""
        html = overview_html(rows, challenge=challenge, columns=columns)
        if self.table.content != html:
            self.table.content = html
        ids = {r.label: r.client_id for r in rows}
        options = (NOBODY, *ids)
        if tuple(self.pick.options) != options:
            keep = self.pick.value if self.pick.value in options else NOBODY
            self.pick.options = options
            self.pick.value = keep  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        self._ids = ids
        self._label_button()
