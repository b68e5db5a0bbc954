"""Live uPlot charts for the lab: short time windows, decimated, resent only when changed.

viser resends every array of a uPlot chart on each assignment (no append), so a
chart costs ``(series + 1) * points * 4`` bytes per update per browser: the arrays go as
float32 (the page makes a Float32Array of each; seven digits are more than a chart
shows, and half of float64's bytes). Windows are therefore short (about 10 s) and
decimated to a fixed grid of ``points`` bins; the bins are aligned to absolute time so a
curve does not shimmer as the window slides.

The x axis is time relative to the newest sample, from −window to 0 exactly,
and the chart's x scale is pinned to that range (:func:`fixed_x`). Left to
auto-scale, the x range is only queued when uPlot creates a chart; on a busy
page a data update can land before the queue is applied and replace the queued
range with the still-empty one, and the chart then shows no x range (and no
curves) for good. A pinned scale is computed from its range function every time
it is applied, so it is always [−window, 0].
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser
import viser.uplot

from armlab.app.page import theme
from armlab.app.viser_ext.handles import set_prop_uncast

#: Colours of command / reference / actual / extra series: the Okabe-Ito palette (Okabe &
#: Ito 2008, "Color Universal Design"), told apart with every common colour-vision
#: deficiency: blue, orange, black, vermillion, bluish green, reddish purple. Lines sharing
#: a chart differ in dash or width as well (:func:`distinct_styles`).
COLORS = ("#0072B2", "#E69F00", "#000000", "#D55E00", "#009E73", "#CC79A7")

#: Dash patterns (px on, px off) for lines of one kind sharing a chart (finger 1, 2, 3;
#: servo 1, 2, 3): they differ in pattern as well as colour, for colour-blind readers.
DASHES: tuple[tuple[int, ...] | None, ...] = (None, (10, 4), (2, 3), (12, 3, 2, 3))


def dash(i: int) -> tuple[int, ...] | None:
    """The dash pattern of the i-th line of a kind (0: solid)."""
    return DASHES[i % len(DASHES)]


def decimate(t: np.ndarray, ys: Sequence[np.ndarray], *, window_s: float,
             points: int, index: np.ndarray | None = None) -> tuple[np.ndarray, list[np.ndarray]]:
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
        index: :func:`decimation` of ``t`` with the same window and bins, when the caller
            has it (charts of one record share it).

    Returns:
        (t (M,), [y (M,), ...]) with M <= points + 2.
    """
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return t, [np.asarray(y, dtype=float) for y in ys]
    if index is None:
        index = decimation(t, window_s=window_s, points=points)
    tt = t[index]
    tt[0] = t[-1] - window_s
    return tt, [np.asarray(y, dtype=float)[index] for y in ys]


def decimation(t: np.ndarray, *, window_s: float, points: int) -> np.ndarray:
    """The indices of the samples of ``t`` (N,) (increasing, N >= 1) that :func:`decimate`
    keeps, the first of them twice (it is drawn again at the window's start)."""
    kept = np.flatnonzero(t > t[-1] - window_s)
    bins = np.floor(t[kept] / (window_s / max(points, 1)))
    last = kept[np.append(bins[1:] != bins[:-1], True)]
    return np.concatenate((last[:1], last))


def _flat_since(ys: Sequence[np.ndarray], fresh: np.ndarray, last: np.ndarray) -> bool:
    """True when every sample of every series in ``fresh`` equals ``last`` (one per series)."""
    for y, v in zip(ys, last, strict=True):
        new = np.asarray(y)[fresh]
        if new.size and not np.all((new == v) | (np.isnan(new) & np.isnan(v))):
            return False
    return True


def fill_gaps(ys: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Series without NaN, for a chart that cannot show gaps.

    The page's arrays are typed (float32) and uPlot treats NaN as a number (its autoscale
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


def set_chart_data(handle: viser.GuiUplotHandle, arrays: Sequence[np.ndarray]) -> None:
    """Send a chart's arrays to its pages as float32 and keep them as its data.

    ``handle.data = ...`` casts every array to float64 (viser's prop hint), so this sets
    the prop and queues its update itself: the same ``GuiUpdateMessage`` viser sends, at
    4 bytes a value. RuntimeError on a removed chart, as viser's own assignment."""
    data = tuple(np.array(a, dtype=np.float32) for a in arrays)  # copies: never aliased
    set_prop_uncast(handle, "data", data)


def fixed_x(lo: float, hi: float) -> dict:
    """A uPlot x scale that always shows [lo, hi] (numbers, not dates).

    viser pins an x scale whose ``range`` is a tuple: the chart opens at
    [lo, hi], data updates never move it, and a double click returns to it
    (a user's drag-zoom is kept until then).
    """
    return {"time": False, "range": (float(lo), float(hi))}


#: Smallest spans of the lessons' chart axes (:func:`fit_range`): an arm at rest shows
#: its 0.29° position steps as a ripple, not as a full-height oscillation.
ANGLE_SPAN_DEG = 4.0  #: joint angle charts, °: about 14 position steps of the RX-24F
TORQUE_SPAN_NM = 0.5  #: torque charts, N·m (a fifth of the RX-24F's stall torque)

#: A pinned y range is widened by this fraction of the span needed on each side, so a
#: curve that grows a little does not re-pin it at once.
HEADROOM = 0.15
#: ... and narrowed again once it is more than this many times the span needed.
SHRINK = 4.0
#: Data that leaves a pinned range widens it by at least this fraction of its span.
GROW = 0.5
#: A pinned range reaches this fraction of its span beyond its round ends: a tick on
#: the end would have its label cut in half by the chart's edge.
TICK_ROOM = 0.08


def nice_step(span: float) -> float:
    """A round tick step (1, 2 or 5 times a power of ten) giving about four steps in
    ``span`` (> 0)."""
    raw = span / 4.0
    base = 10.0 ** math.floor(math.log10(raw))
    return next(m * base for m in (1.0, 2.0, 5.0, 10.0) if m * base >= raw)


def fit_range(lo: float, hi: float, *, min_span: float,
              current: tuple[float, float] | None = None) -> tuple[float, float] | None:
    """The y range a chart should pin for data in [lo, hi]; None to keep ``current``.

    The range spans at least ``min_span`` (centred on the data when the data spans less),
    so a signal at rest shows as the small ripple it is instead of being stretched to
    the chart's full height (the servo's 0.29° position steps read as wild oscillation
    when auto-scaled). ``current`` is kept while the data stays inside it and it is at
    most :data:`SHRINK` times the span needed. Data leaving it widens it by at least
    :data:`GROW` of its span on that side (a rising curve re-pins a few times, not at every
    update). A new range has :data:`HEADROOM` on each side, is rounded out to multiples
    of half a :func:`nice_step` and then reaches :data:`TICK_ROOM` beyond them.

    Args:
        lo, hi: smallest and largest value shown (finite, lo <= hi).
        min_span: smallest span, in the chart's units (> 0).
        current: the pinned range now, or None.
    """
    if hi - lo < min_span:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * min_span, mid + 0.5 * min_span
    span = hi - lo
    if current is not None and current[1] - current[0] <= SHRINK * span:
        if current[0] <= lo and hi <= current[1]:
            return None
        # grow by half the old span on the side the data left: a rising curve re-pins
        grow = GROW * (current[1] - current[0])  # a few times, not at every update
        if lo < current[0]:
            lo = min(lo, current[0] - grow)
        if hi > current[1]:
            hi = max(hi, current[1] + grow)
        span = hi - lo
    step = 0.5 * nice_step(span * (1.0 + 2.0 * HEADROOM))
    lo = math.floor((lo - HEADROOM * span) / step) * step
    hi = math.ceil((hi + HEADROOM * span) / step) * step
    room = TICK_ROOM * (hi - lo)  # the end ticks' labels stay inside the chart
    return lo - room, hi + room


def chart_axes(s: theme.TextSizes, *, y_label: str, y2_label: str | None = None,
               x_label: str = "t − now (s)") -> tuple[dict, ...]:
    """uPlot axes of a chart in text sizes ``s``: ``x_label`` (time) on x, ``y_label`` on
    the left and, if given, ``y2_label`` on the right (scale "y2", no grid of its own)."""
    font, label_font = theme.chart_font(s), theme.chart_font(s, bold=True)
    room = {"labelSize": LABEL_ROOM, "font": font, "labelFont": label_font}
    axes: list[dict] = [{"label": x_label, "size": s.x_axis, **room},
                        {"label": y_label, "scale": "y", "size": s.y_axis, **room}]
    if y2_label is not None:
        axes.append({"label": y2_label, "scale": "y2", "side": 1, "size": s.y_axis,
                     "grid": {"show": False}, **room})
    return tuple(axes)


#: px a chart keeps beside (y) or below (x) an axis's ticks for the axis's label (uPlot's
#: ``labelSize``; it was cut at the top when this room plus the ticks' left too little)
LABEL_ROOM = 30
#: em: a bold label's widest average character width (system-ui measured 0.57-0.61 em on
#: the lab's labels), so the height a label needs is judged without a browser
LABEL_CHAR_EM = 0.64
#: px between a y label's ends and the chart's top and bottom edges
LABEL_MARGIN = 6


def chart_height(s: theme.TextSizes, *, height: int, y_labels: Iterable[str | None]) -> int:
    """The height (px) of a chart asked for as ``height`` px in normal sizes, in sizes
    ``s``: its plot ``s.plot_scale`` times as tall as in normal sizes (below it, the x
    axis's room for its digits), and at least tall enough that each y label, drawn
    rotated along the plot's height (centred on it), is whole between the chart's edges."""
    scaled = round((height - theme.NORMAL.x_axis) * s.plot_scale) + s.x_axis
    longest = max((len(label) for label in y_labels if label), default=0)
    label = math.ceil(LABEL_CHAR_EM * s.ticks * longest) + 2 * LABEL_MARGIN
    return max(scaled, s.x_axis + LABEL_ROOM + label)


def add_chart(gui: viser.GuiApi, *, title: str, series: Sequence[viser.uplot.Series],
              scales: dict,
              y_label: str, y2_label: str | None = None, x_label: str = "t − now (s)",
              height: int, **kwargs: Any) -> viser.GuiUplotHandle:
    """``gui.add_uplot`` with the lab's axes and height in normal sizes; a page in
    projector mode gets the projector ones (:func:`armlab.app.page.theme.sized`), so every
    axis label and tick fits its chart in both. ``kwargs`` go to ``add_uplot``."""
    look = {mode: {"axes": chart_axes(theme.sizes(mode), y_label=y_label, y2_label=y2_label,
                                      x_label=x_label),
                   "height": chart_height(theme.sizes(mode), height=height,
                                          y_labels=(y_label, y2_label))}
            for mode in (False, True)}
    handle = gui.add_uplot(series=tuple(series), scales=scales, title=title,
                           **look[False], **kwargs)  # type: ignore[arg-type]  # look's axes and sizes are add_uplot's keyword arguments
    return theme.sized(handle, normal=look[False], projector=look[True])


@dataclass(frozen=True)
class SeriesSpec:
    """One line of a chart: label, colour, dash pattern (None: solid), scale ("y" or
    "y2") and width (CSS px)."""

    label: str
    color: str
    dash: tuple[int, ...] | None = None
    scale: str = "y"
    width: float = 2.0


def uplot_series(spec: SeriesSpec) -> viser.uplot.Series:
    """The uPlot series options of one line."""
    s: dict = {"label": spec.label, "stroke": spec.color, "width": spec.width,
               "scale": spec.scale}
    if spec.dash:
        s["dash"] = list(spec.dash)
    return s  # type: ignore[return-value]  # s: a plain dict built to uplot's Series keys


def distinct_styles(series: Iterable[dict]) -> list[tuple[str, str]]:
    """Pairs of lines (labels) of one chart that differ in colour alone.

    ``series`` are uPlot series options as the page gets them (the x series, without a
    stroke, is skipped). Lines of one colour are one kind (the lower and upper limit)
    and may share their style; lines of different colours must also differ in dash
    pattern or width, so that a reader who cannot tell the colours apart still can.
    """
    lines = [s for s in series if s.get("stroke")]
    same = []
    for i, a in enumerate(lines):
        for b in lines[i + 1:]:
            if str(a["stroke"]).lower() == str(b["stroke"]).lower():
                continue
            if tuple(a.get("dash") or ()) == tuple(b.get("dash") or ()) and \
                    float(a.get("width", 1)) == float(b.get("width", 1)):
                same.append((str(a.get("label")), str(b.get("label"))))
    return same


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
        y_span, y2_span: smallest span of the left / right axis, in its units (None:
            the axis scales to the data alone); see :func:`fit_range`.
        window_s: seconds shown.
        points: decimation bins per window.
        height: chart height, px.
        order: place among its container's elements (viser's ``order``).

    Change nothing but ``data`` after creation: the page would rebuild the chart in
    place (the chart itself re-pins a spanned axis, rarely: :meth:`_fit`). To retitle or
    relabel, remove it and add a new one at the same ``order``.
    """

    def __init__(self, gui: viser.GuiApi, *, title: str, series: Sequence[SeriesSpec],
                 y_label: str, y2_label: str | None = None, window_s: float = 10.0,
                 points: int = 128, height: int = 170, order: float | None = None,
                 y_span: float | None = None, y2_span: float | None = None) -> None:
        self.window_s = window_s
        self.points = points
        self.n_series = len(series)
        #: scale -> (smallest span, the series on it): the axes pinned by :func:`fit_range`
        self._spans = {key: (span, [i for i, s in enumerate(series) if s.scale == key])
                       for key, span in (("y", y_span), ("y2", y2_span)) if span is not None}
        #: scale -> the range pinned now
        self.ranges: dict[str, tuple[float, float]] = {
            key: (-0.5 * span, 0.5 * span) for key, (span, _) in self._spans.items()}
        scales: dict = {"x": fixed_x(-window_s, 0.0), "y": {"auto": True}}
        if y2_label is not None:
            scales["y2"] = {"auto": True}
        scales.update({key: {"auto": False, "range": r} for key, r in self.ranges.items()})
        self._scales = scales
        # Start with the window's x extent and flat zero lines.
        empty = (np.array([-window_s, 0.0]), *(np.zeros(2) for _ in range(self.n_series)))
        self.handle = add_chart(
            gui, data=empty, title=title, height=height,
            series=({"label": "t − now (s)"}, *(uplot_series(s) for s in series)),
            scales=scales, y_label=y_label, y2_label=y2_label,
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

    def update(self, t: np.ndarray, ys: Sequence[np.ndarray], *, force: bool = False,
               index: np.ndarray | None = None) -> bool:
        """Show the window ending at t[-1]; does nothing if nothing new arrived.

        Args:
            t: (N,) times, s.
            ys: one (N,) array per series.
            force: send even if the newest time did not change (after a unit change).
            index: :func:`decimation` of ``t`` for this chart's window and points, when
                the caller has it (charts of one record share it).

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
        tt, yy = decimate(t, ys, window_s=self.window_s, points=self.points, index=index)
        if tt.size < 2:
            return False
        yy = fill_gaps(yy)
        x = tt - tt[-1]
        x[0], x[-1] = -self.window_s, 0.0  # the data spans the whole pinned axis
        set_chart_data(self.handle, (x, *yy))
        self._fit(yy)
        self._last_t = newest
        self._last_sent = now
        self._last_values = np.array([y[-1] for y in yy])
        self.updates += 1
        return True

    def _fit(self, ys: Sequence[np.ndarray]) -> None:
        """Re-pin each spanned axis whose data left its range (or shrank well inside it).

        A new range rebuilds the chart on the page (uPlot takes scales only when it
        creates a chart), which :func:`fit_range`'s headroom keeps rare.
        """
        changed = False
        for key, (span, members) in self._spans.items():
            values = [ys[i] for i in members]
            lo = min(float(np.min(v)) for v in values)
            hi = max(float(np.max(v)) for v in values)
            if not (math.isfinite(lo) and math.isfinite(hi)):
                continue
            new = fit_range(lo, hi, min_span=span, current=self.ranges[key])
            if new is not None:
                self.ranges[key] = new
                self._scales[key] = {"auto": False, "range": new}
                changed = True
        if changed:
            self.handle.scales = dict(self._scales)

    def remove(self) -> None:
        self.handle.remove()


def rebuild_plots(plots: Iterable[LivePlot], build: Callable[[], None]) -> None:
    """Take ``plots`` off every page, then call ``build()`` to add their replacements.

    A chart whose title or labels change is replaced, never edited (see :class:`LivePlot`).
    """
    for plot in plots:
        plot.remove()
    build()
