"""Live uPlot charts for the lab: short time windows, decimated, resent only when changed.

viser resends every array of a uPlot chart on each assignment (float64, no
append), so a chart costs ``(series + 1) * points * 8`` bytes per update per
browser. Windows are therefore short (about 10 s) and decimated to a fixed
grid of ``points`` bins; the bins are aligned to absolute time so a curve does
not shimmer as the window slides.

The x axis is time relative to the newest sample, from −window to 0 exactly,
and the chart's x scale is pinned to that range (:func:`fixed_x`). Left to
auto-scale, the x range is only queued when uPlot creates a chart; on a busy
page a data update can land before the queue is applied and replace the queued
range with the still-empty one, and the chart then shows no x range (and no
curves) for good. A pinned scale is computed from its range function every time
it is applied, so it is always [−window, 0].
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import viser
import viser.uplot

from app import theme

#: Colours used for command / reference / actual / extra series (readable on a projector).
COLORS = ("#1f5eea", "#e8820c", "#222222", "#c2185b", "#2e7d32", "#6a1b9a")

#: Dash patterns (px on, px off) for lines of one kind sharing a chart (finger 1, 2, 3;
#: servo 1, 2, 3): they differ in pattern as well as colour, for colour-blind readers.
DASHES: tuple[tuple[int, ...] | None, ...] = (None, (10, 4), (2, 3), (12, 3, 2, 3))


def dash(i: int) -> tuple[int, ...] | None:
    """The dash pattern of the i-th line of a kind (0: solid)."""
    return DASHES[i % len(DASHES)]


def decimate(t: np.ndarray, ys: Sequence[np.ndarray], *, window_s: float,
             points: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """The last ``window_s`` seconds of (t, ys), one sample per time bin, spanning the window.

    Bins are ``window_s / points`` wide and aligned to t = 0, and each keeps its
    last sample, so successive calls on a growing record pick the same samples.
    A first sample at exactly t[-1] − window_s repeats the oldest kept values, so
    the result always spans exactly ``window_s``.

    Args:
        t: (N,) sample times, s, increasing.
        ys: arrays of shape (N,).
        window_s: window length, s.
        points: number of bins (the result has at most ``points + 2`` samples).

    Returns:
        (t (M,), [y (M,), ...]) with M <= points + 2.
    """
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return t, [np.asarray(y, dtype=float) for y in ys]
    start = t[-1] - window_s
    keep = t > start
    t = t[keep]
    ys = [np.asarray(y, dtype=float)[keep] for y in ys]
    width = window_s / max(points, 1)
    bins = np.floor(t / width)
    last = np.append(bins[1:] != bins[:-1], True)
    t, ys = t[last], [y[last] for y in ys]
    t = np.concatenate([[start], t])
    ys = [np.concatenate([y[:1], y]) for y in ys]
    return t, ys


def _flat_since(ys: Sequence[np.ndarray], fresh: np.ndarray, last: np.ndarray) -> bool:
    """True when every sample of every series in ``fresh`` equals ``last`` (one per series)."""
    for y, v in zip(ys, last, strict=True):
        new = np.asarray(y)[fresh]
        if new.size and not np.all((new == v) | (np.isnan(new) & np.isnan(v))):
            return False
    return True


def fill_gaps(ys: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Series without NaN, for a chart that cannot show gaps.

    The page's arrays are float64 and uPlot treats NaN as a number (its autoscale
    breaks), so each NaN takes the nearest earlier finite value (the first finite
    value before it); a series with no finite value at all copies the first series
    that has one (drawn underneath it, so it does not show).
    """
    out: list[np.ndarray | None] = []
    for y in ys:
        y = np.asarray(y, dtype=float)
        ok = np.isfinite(y)
        if ok.all():
            out.append(y)
            continue
        if not ok.any():
            out.append(None)
            continue
        idx = np.where(ok, np.arange(len(y)), 0)
        np.maximum.accumulate(idx, out=idx)
        first = int(np.argmax(ok))
        idx[:first] = first
        out.append(y[idx])
    backup = next((y for y in out if y is not None), None)
    return [y if y is not None else (backup.copy() if backup is not None
                                     else np.zeros(len(ys[0]))) for y in out]


def fixed_x(lo: float, hi: float) -> dict:
    """A uPlot x scale that always shows [lo, hi] (numbers, not dates).

    viser pins an x scale whose ``range`` is a tuple: the chart opens at
    [lo, hi], data updates never move it, and a double click returns to it
    (a user's drag-zoom is kept until then).
    """
    return {"time": False, "range": (float(lo), float(hi))}


@dataclass(frozen=True)
class SeriesSpec:
    """One line of a chart: label, colour, dashed or not, scale ("y" or "y2")."""

    label: str
    color: str
    dash: tuple[int, ...] | None = None
    scale: str = "y"


def _series(spec: SeriesSpec) -> viser.uplot.Series:
    s: dict = {"label": spec.label, "stroke": spec.color, "width": 2, "scale": spec.scale}
    if spec.dash:
        s["dash"] = list(spec.dash)
    return s  # type: ignore[return-value]


class LivePlot:
    """A uPlot chart in the GUI showing a sliding time window.

    Data is sent when new samples arrived; while every line stays flat it is sent
    only once per ``quiet_period`` s (the window slides, nothing else changes).

    Args:
        gui: where to add it (``server.gui``).
        title: chart title.
        series: the lines (y arrays given to :meth:`update` in this order).
        y_label: left axis label (unit).
        y2_label: right axis label for series on scale "y2" (None: no right axis).
        window_s: seconds shown.
        points: decimation bins per window.
        height: chart height, px.
        order: place among its container's elements (viser's ``order``).

    Change nothing but ``data`` after creation: the page would rebuild the chart in
    place. To retitle or relabel, remove it and add a new one at the same ``order``.
    """

    def __init__(self, gui: viser.GuiApi, *, title: str, series: Sequence[SeriesSpec],
                 y_label: str, y2_label: str | None = None, window_s: float = 10.0,
                 points: int = 128, height: int = 170, order: float | None = None) -> None:
        self.window_s = window_s
        self.points = points
        self.n_series = len(series)
        scales: dict = {"x": fixed_x(-window_s, 0.0), "y": {"auto": True}}
        font, label_font = theme.chart_font(), theme.chart_font(bold=True)
        big = theme.projector()
        axes: list = [{"label": "t − now (s)", "size": 48 if big else 34,
                       "font": font, "labelFont": label_font},
                      {"label": y_label, "scale": "y", "size": 80 if big else 52,
                       "font": font, "labelFont": label_font}]
        if y2_label is not None:
            scales["y2"] = {"auto": True}
            axes.append({"label": y2_label, "scale": "y2", "side": 1,
                         "size": 80 if big else 52, "font": font, "labelFont": label_font,
                         "grid": {"show": False}})
        # Start with the window's x extent and flat zero lines.
        empty = (np.array([-window_s, 0.0]), *(np.zeros(2) for _ in range(self.n_series)))
        self.handle = gui.add_uplot(
            data=empty,
            series=({"label": "t − now (s)"}, *(_series(s) for s in series)),
            scales=scales, axes=tuple(axes), title=title, height=height,
            legend={"live": False},
            cursor={"show": False},
            order=order,
        )
        self._last_t: float | None = None
        self._last_sent = 0.0
        self._last_values: np.ndarray | None = None
        self.updates = 0  #: how many times data was sent
        #: s between updates while every line is flat (nothing to see but the window sliding)
        self.quiet_period = 1.0

    def update(self, t: np.ndarray, ys: Sequence[np.ndarray], *, force: bool = False) -> bool:
        """Show the window ending at t[-1]; does nothing if nothing new arrived.

        Args:
            t: (N,) times, s.
            ys: one (N,) array per series.
            force: send even if the newest time did not change (after a unit change).

        Returns:
            True when data was sent.
        """
        if len(ys) != self.n_series:
            raise ValueError(f"ys: expected {self.n_series} series, got {len(ys)}")
        if len(t) < 2:
            return False
        newest = float(t[-1])
        if not force and self._last_t == newest:
            return False
        now = time.monotonic()
        if not force and self._last_t is not None and self._last_values is not None \
                and now - self._last_sent < self.quiet_period:
            fresh = np.asarray(t) > self._last_t
            if _flat_since(ys, fresh, self._last_values):
                return False
        tt, yy = decimate(t, ys, window_s=self.window_s, points=self.points)
        if tt.size < 2:
            return False
        yy = fill_gaps(yy)
        x = tt - tt[-1]
        x[0], x[-1] = -self.window_s, 0.0  # the data spans the whole pinned axis
        self.handle.data = (x, *yy)
        self._last_t = newest
        self._last_sent = now
        self._last_values = np.array([y[-1] for y in yy])
        self.updates += 1
        return True

    def remove(self) -> None:
        self.handle.remove()


def rebuild_plots(plots: Iterable[LivePlot], build: Callable[[], None]) -> None:
    """Take ``plots`` off every page, then call ``build()`` to add their replacements.

    A chart whose title or labels change is replaced, never edited (see :class:`LivePlot`).
    """
    for plot in plots:
        plot.remove()
    build()
