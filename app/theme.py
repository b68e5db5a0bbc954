"""Text sizes of the lab's page: normal (>= 13 px) or projector (>= 20 px at 1920x1080).

viser offers no font-size setting, so the lab adds one HTML element holding a
``<style>`` sheet (:func:`add_style`); its content is swapped when the
"Projector" switch changes. Sizes are in CSS px, so browser zoom (Ctrl +)
still scales them. uPlot draws its tick digits on a canvas with the font given
when the chart is built, so charts read :func:`chart_font` at creation: a
chart built after the switch changed (a lesson opened or re-opened) uses the
new size.
"""

from __future__ import annotations

from dataclasses import dataclass

import viser


@dataclass(frozen=True)
class TextSizes:
    """CSS px of the page's text: controls (labels, inputs, tabs, status), charts' titles
    and legends, and the charts' canvas-drawn tick digits."""

    controls: int
    chart_title: int
    ticks: int


NORMAL = TextSizes(controls=14, chart_title=14, ticks=13)
PROJECTOR = TextSizes(controls=22, chart_title=22, ticks=20)

_state = {"projector": False}


def projector() -> bool:
    """True while the page is in projector mode."""
    return _state["projector"]


def set_projector(on: bool) -> None:
    """Switch projector mode for charts built from now on (:func:`chart_font`)."""
    _state["projector"] = bool(on)


def sizes() -> TextSizes:
    """The text sizes of the current mode."""
    return PROJECTOR if projector() else NORMAL


def label_scale() -> float:
    """viser's ``font_screen_scale`` for the lab's 3D scene labels in the current mode.

    Scale 1 draws text about 12 px tall at 1080p (the issue measured 7-8 px at 0.6):
    1.75 gives >= 16 px glyph height, 2.6 gives >= 24 px in projector mode.
    """
    return 2.6 if projector() else 1.75


def chart_font(*, bold: bool = False) -> str:
    """A canvas font string for uPlot's axis ticks / labels in the current mode."""
    return f"{'bold ' if bold else ''}{sizes().ticks}px system-ui, sans-serif"


def style_sheet(s: TextSizes) -> str:
    """The ``<style>`` element setting every text of the panel and the charts to at least ``s``.

    Every element inside viser's control panel gets ``s.controls`` px (Mantine sets
    sizes of 9-13 px on labels, inputs, slider marks and tabs); uPlot's title and
    legend get ``s.chart_title`` px.
    """
    c, t = s.controls, s.chart_title
    return (
        "<style>"
        f".mantine-Paper-root *:not(svg):not(path):not(canvas) {{font-size:{c}px !important;"
        "line-height:1.3 !important}}"
        f".u-title, .u-legend, .u-legend * {{font-size:{t}px !important;"
        "line-height:1.3 !important}}"
        f".mantine-Notification-root * {{font-size:{c}px !important}}"
        "</style>"
    )


class PageStyle:
    """The lab's text-size sheet on every page, and a "Projector" switch for it.

    Args:
        gui: the server's GUI (the sheet and the switch go into the control panel).
        projector: start in projector mode.
        order: place of the switch in the panel.
        on_change: called with the new mode after the switch changed (the lab
            re-opens the lesson so its charts take the new tick size).
    """

    def __init__(self, gui: viser.GuiApi, *, projector: bool = False, order: float = -80.0,
                 on_change=None) -> None:
        set_projector(projector)
        self.sheet = gui.add_html(style_sheet(sizes()), order=-1000.0)
        self.switch = gui.add_checkbox(
            "Projector", initial_value=projector, order=order,
            hint="Large text for a classroom projector (every page)")
        self._on_change = on_change

        @self.switch.on_update
        def _(_event: viser.GuiEvent) -> None:
            self.set(bool(self.switch.value))

    def set(self, on: bool) -> None:
        """Projector mode on or off on every page."""
        if on == projector():
            return
        set_projector(on)
        self.sheet.content = style_sheet(sizes())
        if self.switch.value != on:
            self.switch.value = on
        if self._on_change is not None:
            self._on_change(on)
