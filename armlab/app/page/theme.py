"""Text sizes of the lab's pages, each page its own: normal (>= 13 px) or projector
(>= 20 px at 1920x1080).

viser offers no font-size setting, so the lab adds one HTML element holding a
``<style>`` sheet (:func:`style_sheet`); the 3D scene's labels and the charts'
canvas-drawn tick digits have sizes of their own (a label's ``font_screen_scale``, a
uPlot axis's ``font``). All of them are built in the normal sizes and shared by every
page. An element whose size depends on the mode is registered with :func:`sized`
(labels through :func:`add_label`, charts in :mod:`armlab.app.page.plots`); a page whose
"Projector" switch is on is sent the projector values of those elements, to it alone
(:func:`armlab.app.viser_ext.page_js.set_props`). So the projected page can have large text while
the students' phones keep theirs, and nothing is rebuilt: the arm goes on as it was.

Each browser keeps its choice in its localStorage (:data:`PROJECTOR_KEY`), so a reload
keeps it; ``armlab serve --projector`` is the choice of a browser that has made none.
Sizes are in CSS px, so browser zoom (Ctrl +) still scales them.
"""

from __future__ import annotations

import threading
import time
import weakref
from dataclasses import dataclass
from typing import Any

import viser

from armlab.app.viser_ext.clients import server_of
from armlab.app.viser_ext.handles import is_removed, owner_of
from armlab.app.viser_ext.page_js import ask_item, held, set_props
from armlab.app.viser_ext.page_scripts import text_size_sheet
from armlab.app.viser_ext.visual_fixes import panel_style


@dataclass(frozen=True)
class TextSizes:
    """CSS px of the page's text: controls (labels, inputs, tabs, status), charts' titles
    and legends, the charts' canvas-drawn tick digits, and the room the charts' x and y
    axes take for their digits and label; and how many times its normal height a chart's
    plot is drawn (a projected chart is read from the back row: its lines need the room
    its 20 px digits take beside them)."""

    controls: int
    chart_title: int
    ticks: int
    x_axis: int
    y_axis: int
    plot_scale: float = 1.0


NORMAL = TextSizes(controls=14, chart_title=14, ticks=13, x_axis=34, y_axis=52)
#: a 170 px chart (a 136 px plot) is 266 px in Projector mode, its plot 218 px
PROJECTOR = TextSizes(controls=22, chart_title=22, ticks=20, x_axis=48, y_axis=80,
                      plot_scale=1.6)

#: viser's ``font_screen_scale`` of the lab's 3D scene labels. Scale 1 draws text about
#: 12 px tall at 1080p (the issue measured 7-8 px at 0.6): 1.75 gives >= 16 px glyph
#: height, 2.6 gives >= 24 px in projector mode.
LABEL_SCALE = {False: 1.75, True: 2.6}

#: the page's localStorage key holding its choice ("1" projector, "0" normal)
PROJECTOR_KEY = "armlab_projector"
#: s a page has to answer the question for its choice, and s between questions
ANSWER_WAIT_S = 180.0
ASK_EVERY_S = 4.0


def sizes(projector: bool) -> TextSizes:
    """The text sizes of a mode."""
    return PROJECTOR if projector else NORMAL


def chart_font(s: TextSizes, *, bold: bool = False) -> str:
    """A canvas font string for uPlot's axis ticks / labels in sizes ``s``."""
    return f"{'bold ' if bold else ''}{s.ticks}px system-ui, sans-serif"


def style_sheet(s: TextSizes) -> str:
    """The ``<style>`` element setting every text of the panel and the charts to at least ``s``.

    Every element inside viser's control panel gets ``s.controls`` px (Mantine sets
    sizes of 9-13 px on labels, inputs, slider marks and tabs); uPlot's title and
    legend get ``s.chart_title`` px. Folder titles keep clear of what is above them at
    these sizes (:func:`armlab.app.viser_ext.visual_fixes.panel_style`).
    """
    return (text_size_sheet(controls_px=s.controls, chart_title_px=s.chart_title)
            + panel_style())


# -- elements whose size depends on the page's mode -------------------------------------


@dataclass(frozen=True)
class _Sized:
    handle: weakref.ref
    normal: dict[str, Any]
    projector: dict[str, Any]


#: held while the registry changes and while a page is sent sizes, so that an element
#: registered while a page switches gets that page's new mode
_lock = threading.RLock()
#: every element registered by :func:`sized`, held weakly (dropped once removed or gone)
_sized: list[_Sized] = []
#: each server's :class:`PageStyle`, both held weakly (a PageStyle holds its server)
_styles: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def sized(handle: Any, *, normal: dict[str, Any], projector: dict[str, Any]) -> Any:
    """Register ``handle`` (a GUI element or scene node built with the ``normal``
    properties) so that projector pages show it with the ``projector`` ones; pages
    already in projector mode get them now. Returns ``handle``."""
    entry = _Sized(weakref.ref(handle), dict(normal), dict(projector))
    owner = owner_of(handle)
    server = owner if isinstance(owner, viser.ViserServer) else server_of(owner)
    with _lock:
        _sized[:] = [e for e in _sized if _alive(e)]
        _sized.append(entry)
        ref = _styles.get(server)
        style = None if ref is None else ref()
        for client in style.projector_pages() if style is not None else ():
            if owner is server or owner is client:
                set_props(client, handle, **entry.projector)
    return handle


def _alive(entry: _Sized) -> bool:
    handle = entry.handle()
    return handle is not None and not is_removed(handle)


def _sized_for(client: viser.ClientHandle) -> list[tuple[Any, _Sized]]:
    """The live registered elements page ``client`` shows: its server's and its own."""
    with _lock:
        entries = [e for e in _sized if _alive(e)]
    out = []
    for e in entries:
        handle = e.handle()
        owner = owner_of(handle) if handle is not None else None
        if owner is client or owner is server_of(client):
            out.append((handle, e))
    return out


def add_label(scene: viser.SceneApi, name: str, text: str, **kwargs: Any
              ) -> viser.LabelHandle:
    """``scene.add_label`` at the lab's label size: at least 16 px tall at 1080p, 24 px
    on a projector page."""
    handle = scene.add_label(name, text, font_screen_scale=LABEL_SCALE[False], **kwargs)
    return sized(handle, normal={"font_screen_scale": LABEL_SCALE[False]},
                 projector={"font_screen_scale": LABEL_SCALE[True]})


class PageStyle:
    """The lab's text-size sheet, and each page's own "Projector" switch for it.

    Args:
        server: the lab's viser server (the sheet goes into its control panel, every
            page that connects gets its switch).
        projector: the mode of a browser that has not chosen one yet.
        order: place of the switch in the panel.
    """

    def __init__(self, server: viser.ViserServer, *, projector: bool = False,
                 order: float = -80.0) -> None:
        self.default = projector
        self.order = order
        self._server = server
        self.sheet = sized(server.gui.add_html(style_sheet(NORMAL), order=-1000.0),
                           normal={"content": style_sheet(NORMAL)},
                           projector={"content": style_sheet(PROJECTOR)})
        self._lock = threading.Lock()
        self._switches: dict[int, viser.GuiCheckboxHandle] = {}
        self._projector: set[int] = set()
        self._settled: set[int] = set()
        self._chosen: set[int] = set()  #: pages whose switch was clicked
        _styles[server] = weakref.ref(self)
        server.on_client_connect(self._hello)
        server.on_client_disconnect(self._goodbye)

    def is_projector(self, client_id: int) -> bool:
        """True while page ``client_id`` shows projector sizes."""
        with self._lock:
            return client_id in self._projector

    def settled(self, client_id: int) -> bool:
        """True once page ``client_id`` has taken in the mode its browser chose (or the
        default, if it chose none): a test measuring its text waits for this."""
        with self._lock:
            return client_id in self._settled

    def projector_pages(self) -> list[viser.ClientHandle]:
        """The pages in projector mode now."""
        with self._lock:
            ids = set(self._projector)
        return [c for cid, c in self._server.get_clients().items() if cid in ids]

    def switch(self, client_id: int) -> viser.GuiCheckboxHandle | None:
        """Page ``client_id``'s Projector switch (None: not connected)."""
        with self._lock:
            return self._switches.get(client_id)

    def set(self, client: viser.ClientHandle, on: bool, *, remember: bool = True) -> None:
        """Projector mode on or off on ``client``'s page only; ``remember``: kept in its
        browser for the next visit."""
        cid = client.client_id
        with _lock:
            with self._lock:
                if cid not in self._switches:
                    return  # gone
                was = cid in self._projector
                (self._projector.add if on else self._projector.discard)(cid)
                switch = self._switches[cid]
            if on != was:
                for handle, entry in _sized_for(client):
                    set_props(client, handle, **(entry.projector if on else entry.normal))
        if switch.value != on:
            switch.value = on  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        if remember:
            client.local_storage.set_item(PROJECTOR_KEY, "1" if on else "0")

    def _hello(self, client: viser.ClientHandle) -> None:
        switch = client.gui.add_checkbox(
            "Projector", initial_value=False, order=self.order,
            hint="Large text for a classroom projector (this browser only)")
        with self._lock:
            self._switches[client.client_id] = switch
        switch.on_update(lambda _e: self._flipped(client, switch))
        threading.Thread(target=self._recall, args=(client,), daemon=True,
                         name="armlab-projector").start()

    def _flipped(self, client: viser.ClientHandle, switch: viser.GuiCheckboxHandle) -> None:
        """The page's switch changed (a click there; :meth:`set` moving it changes nothing)."""
        with self._lock:
            self._chosen.add(client.client_id)  # a click outranks what the browser held
        if bool(switch.value) != self.is_projector(client.client_id):
            self.set(client, bool(switch.value))

    def _recall(self, client: viser.ClientHandle) -> None:
        """The browser's own choice (asked of its localStorage), else the default."""
        try:
            stored = ask_item(client, PROJECTOR_KEY, every=ASK_EVERY_S, within=ANSWER_WAIT_S)
        except (TimeoutError, RuntimeError):  # no answer, the page left, no localStorage
            stored = None
        on = self.default if stored not in ("0", "1") else stored == "1"
        with self._lock:
            clicked = client.client_id in self._chosen
        if on and not clicked:
            self.set(client, True, remember=False)
            try:  # the page has taken the sizes in once it answers after they were sent
                deadline = time.monotonic() + ANSWER_WAIT_S
                while held(client) and time.monotonic() < deadline:
                    time.sleep(0.05)
                client.local_storage.get_item(PROJECTOR_KEY, timeout=ANSWER_WAIT_S)
            except (TimeoutError, RuntimeError):
                return
        with self._lock:
            if client.client_id in self._switches:
                self._settled.add(client.client_id)

    def _goodbye(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._switches.pop(client.client_id, None)
            self._projector.discard(client.client_id)
            self._settled.discard(client.client_id)
            self._chosen.discard(client.client_id)
