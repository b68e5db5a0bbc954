"""What every lesson does to the page in the same way (a helper module, not a lesson).

The fields, opening and closing every lesson handle shares (:class:`LessonBase`),
keeping a lesson's GUI elements and removing them when it closes, docking its
charts panel, turning a refused action into a notification, sending a file,
what a joint is called on the page, and the HTML of the status and warning lines.
"""

from __future__ import annotations

import html
import math
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, TypeVar

import viser

from armlab.app.lessons import Figures
from armlab.app.page.inputs import notify
from armlab.app.page.publisher import Publisher

if TYPE_CHECKING:
    from armlab.app.lessons import Gains, LessonContext
    from armlab.app.page.surface import Surface

H = TypeVar("H")

#: Place of the status line in the control panel (viser ``order``: first).
STATUS_ORDER = -80.0
#: Width of the docked charts panel, px.
CHART_PANEL_WIDTH = 430


def remove_quietly(handle: Any) -> None:
    """Remove a GUI element or scene node from every page; one already gone is ignored."""
    try:
        handle.remove()
    except (RuntimeError, KeyError, ValueError):
        pass


class LessonGui:
    """The top-level GUI elements a lesson adds, so that closing it removes them all.

    Args:
        gui: the server's GUI API (``server.gui``).
    """

    def __init__(self, gui: viser.GuiApi) -> None:
        self.gui = gui
        self._handles: list[Any] = []

    def add(self, handle: H) -> H:
        """Keep ``handle`` (already on the page) for :meth:`remove_all`; returns it."""
        self._handles.append(handle)
        return handle

    def add_status(self, *, try_this: str | None = None) -> viser.GuiHtmlHandle:
        """Add an empty status line at the top of the control panel (see :func:`status_html`)
        and, under it, the lesson's "Try this" line: its first action, one sentence."""
        status = self.add(self.gui.add_html("", order=STATUS_ORDER))
        if try_this:
            self.try_this = self.add(self.gui.add_markdown(f"**Try this:** {try_this}",
                                                           order=STATUS_ORDER + 0.5))
        return status

    @contextmanager
    def chart_panel(self, tab: str, *,
                    width: float = CHART_PANEL_WIDTH) -> Iterator[viser.GuiTabHandle]:
        """A panel with one charts tab named ``tab``, yielded (not entered) to be filled.

        When the block ends the panel is docked at the left edge of the page, ``width``
        px wide. It is kept for :meth:`remove_all`.
        """
        panel = self.add(self.gui.add_panel())
        yield panel.add_tab(tab, viser.Icon.CHART_LINE)
        panel.dock_left()
        panel.set_width(width)

    @property
    def handles(self) -> tuple[Any, ...]:
        """The kept top-level elements (status, tabs, charts panel, ...), oldest first."""
        return tuple(self._handles)

    def remove_all(self) -> None:
        """Remove every kept element from the page, newest first."""
        for handle in reversed(self._handles):
            remove_quietly(handle)
        self._handles.clear()


class LessonBase:
    """What every lesson handle shares: the page, the context, a lock, its GUI, closing once,
    and the answers of a lesson without an arm to stop, gains or figures
    (:class:`armlab.app.lessons.LessonHandle`; a lesson that has them overrides these).

    A lesson's ``__init__`` calls ``super().__init__(server, ctx)``, adds its scene and
    GUI inside ``with self.opening(...)``, then starts its frames with :meth:`publish`;
    its ``close`` does its teardown only when :meth:`mark_closed` says it is the first.

    Args:
        server: what the lesson is on: the lab's server (every page) or one page.
        ctx: what it is built for.
    """

    publisher: Publisher

    def __init__(self, server: Surface, ctx: LessonContext) -> None:
        self.server = server
        self.ctx = ctx
        self._lock = threading.RLock()
        self._closed = False
        self._gui = LessonGui(server.gui)

    def keep(self) -> object | None:
        """Nothing kept for the next opening (a lesson with measurements overrides this)."""
        return None

    @contextmanager
    def opening(self, *undo: Callable[[], object] | None) -> Iterator[None]:
        """A block that adds the lesson to the page: if it raises, each of ``undo`` (None:
        skipped) runs, then every GUI element kept so far is removed, and the error goes on."""
        try:
            yield
        except BaseException:
            close_in_turn(*undo, self._gui.remove_all)
            raise

    def publish(self, *, pose: Callable[[], None], plots: Callable[[bool], None],
                pose_hz: float, plot_hz: float,
                every: Callable[[], None] | None = None) -> None:
        """Start :attr:`publisher`: ``pose()`` at ``pose_hz``, ``plots(force)`` at ``plot_hz``
        (on the context's shared frame thread, if it has one), and ``every()`` at each of
        its ticks, with a page open or not."""
        self.publisher = Publisher(self.server, pose=pose, plots=plots, pose_hz=pose_hz,
                                   plot_hz=plot_hz, frames=self.ctx.frames, every=every)
        self.publisher.start()

    def gui_handles(self) -> tuple[Any, ...]:
        """The lesson's top-level GUI elements (hiding them hides the whole lesson panel)."""
        return self._gui.handles

    def estop(self) -> None:
        """The lab's E-STOP: nothing runs here to switch off."""

    def gain_controls(self) -> Gains | None:
        """None: no gains to read or set."""
        return None

    def run_figures(self) -> Figures:
        """No figures (the lesson declares none)."""
        return {}

    def page_only_buttons(self) -> tuple[Any, ...]:
        """None: every control of the lesson is the presenter's in a classroom."""
        return ()

    def mark_closed(self) -> bool:
        """Mark the lesson closed; True the first time (the caller tears it down), then False."""
        with self._lock:
            if self._closed:
                return False
            self._closed = True
            return True


def guarded(event: viser.GuiEvent | viser.TransformControlsEvent, action: Callable[[], object], *,
            undo: Callable[[], object] | None = None) -> None:
    """Run a GUI callback's ``action``; a ValueError it raises is never passed on.

    Instead the browser that sent ``event`` shows a "Not done" notification with the
    message, and ``undo`` (e.g. putting a dropdown back) is called.
    """
    try:
        action()
    except ValueError as exc:
        notify(event.client, "Not done", str(exc))
        if undo is not None:
            undo()


def send_download(event: viser.GuiEvent, make: Callable[[], tuple[str, bytes]]) -> None:
    """Send the file ``make()`` returns, (name, bytes), to the browser that clicked.

    A ValueError from ``make`` (nothing to send yet) becomes a "Nothing to download"
    notification in that browser; a click from Python (no client) does nothing.
    """
    if event.client is None:
        return
    try:
        name, data = make()
    except ValueError as exc:
        notify(event.client, "Nothing to download", str(exc))
        return
    event.client.send_file_download(name, data, save_immediately=True)


def joint_label(name: str) -> str:
    """What the page calls the model's joint ``name``: "theta2" -> "θ2" (other names
    unchanged)."""
    return name.replace("theta", "θ")


def esc(text: str) -> str:
    """``text`` safe inside HTML (``&``, ``<`` and ``>`` escaped; quotes kept)."""
    return html.escape(text, quote=False)


#: CSS inset of an HTML element of the panel from its edges, as viser insets its controls
INSET = "padding:0 var(--mantine-spacing-xs)"


def status_html(state: str, color: str, detail: str, *, extra: str = "") -> str:
    """The status line at the top of the panel (inset from its edges as the controls are).

    Args:
        state: what the lesson is doing (escaped), after a dot in ``color``.
        color: CSS colour of the dot and the state.
        detail: HTML of the small grey line under it.
        extra: HTML appended below (a note, a figure).
    """
    return (f"<div style='font-size:0.95em;{INSET}'>"
            f"<b style='color:{color}'>● {esc(state)}</b>"
            f"<div style='color:#555;font-size:0.85em'>{detail}</div>{extra}</div>")


def warning_html(title: str, message: str, *, color: str = "#b00020") -> str:
    """A warning box: bold ``title`` after a ⚠, then ``message`` (escaped), in ``color``."""
    return (f"<div style='border-left:4px solid {color};padding:4px 8px;background:#fff4e5'>"
            f"<b style='color:{color}'>⚠ {title}</b> "
            f"<span style='font-size:0.9em'>{esc(message)}</span></div>")


def set_content(handle: Any, text: str) -> None:
    """Show ``text`` in an HTML or markdown element; sent to the pages only if it changed."""
    if handle.content != text:
        handle.content = text


class Every:
    """A chart frame's slower chore (a table of the last 10 s, a grasp's figures): due at
    most once every ``period_s`` s of wall time, or when the frame is forced (a fresh page)."""

    def __init__(self, period_s: float) -> None:
        self.period_s = float(period_s)
        self._at = -math.inf  #: monotonic time it was last due

    def due(self, *, force: bool = False) -> bool:
        """Whether the chore is to be done now (and, if so, it counts as done)."""
        now = time.monotonic()
        if not force and now - self._at < self.period_s:
            return False
        self._at = now
        return True


def close_in_turn(*steps: Callable[[], object] | None) -> None:
    """Call each step in order (None: skipped), every one even after another raised.

    The same as nested ``try``/``finally`` blocks: an exception propagates once every
    later step has run.
    """
    if not steps:
        return
    first, rest = steps[0], steps[1:]
    try:
        if first is not None:
            first()
    finally:
        close_in_turn(*rest)
