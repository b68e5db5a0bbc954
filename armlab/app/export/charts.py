"""Line charts of a run as inline SVG text, for the exported page (:mod:`armlab.app.export.html`).

Each chart is drawn here, in Python, to plain ``<svg>`` markup: it shows with no script
at all (and prints), and needs no chart library. Long recordings are thinned per chart
to at most ``2 * buckets`` points a series, keeping each time bucket's lowest and highest
sample of every series (a step's peak stays on the chart). Missing samples (NaN) break
a line. Every piece of text is escaped. A chart's vertical "cursor" line is moved by the
page's script to the time of its slider (``data-t0``/``data-t1`` span ``data-x0``/``data-x1``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from html import escape

import numpy as np

#: Chart size in SVG user units (scales with the page's width).
WIDTH, HEIGHT = 520.0, 220.0
#: Plot area margins: left (tick digits and the y title), right, top (title), bottom.
LEFT, RIGHT, TOP, BOTTOM = 64.0, 12.0, 26.0, 40.0


@dataclass(frozen=True)
class Series:
    """One line: its legend label, stroke colour, dash pattern ("" solid) and values (m,)."""

    label: str
    color: str
    values: np.ndarray
    dash: str = ""


def envelope_indices(columns: np.ndarray, *, buckets: int) -> np.ndarray:
    """Sorted row indices of ``columns`` (m, k) that keep its shape on a chart: every row
    when m <= 2 * buckets, else the first and last row and, in each of ``buckets`` equal
    runs of rows, the rows of each column's lowest and highest finite value."""
    m = columns.shape[0]
    if m <= 2 * buckets:
        return np.arange(m)
    keep = [np.array([0, m - 1])]
    edges = np.linspace(0, m, buckets + 1).astype(int)
    filled = np.where(np.isfinite(columns), columns, np.nan)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        block = filled[a:b]
        finite = np.isfinite(block)
        has = finite.any(axis=0)
        if not has.any():
            keep.append(np.array([a]))
            continue
        lo = np.where(finite, block, np.inf).argmin(axis=0)[has]
        hi = np.where(finite, block, -np.inf).argmax(axis=0)[has]
        keep.append(a + lo)
        keep.append(a + hi)
    return np.unique(np.concatenate(keep))


#: The most ticks an axis gets, whatever its range.
MAX_TICKS = 50


def nice_ticks(lo: float, hi: float, *, count: int = 5) -> list[float]:
    """About ``count`` round tick values (1, 2 or 5 times a power of ten apart) in [lo, hi];
    [lo] or [lo, hi] where no round ticks fit. Never more than :data:`MAX_TICKS`, and the
    ticks are counted before they are made: a range too narrow for float spacing (2⁵³ to
    2⁵³ + 2) or too wide for float64 gives its ends, never an endless loop."""
    span = hi - lo
    if not (span > 0 and math.isfinite(span)):
        return [lo]
    raw = span / max(count - 1, 1)
    if not raw > 0:
        return [lo, hi]
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(s * power for s in (1.0, 2.0, 5.0, 10.0) if s * power >= raw)
    first, last = lo / step - 1e-9, hi / step + 1e-9
    if not (step > 0 and math.isfinite(first) and math.isfinite(last)):
        return [lo, hi]
    k0, k1 = math.ceil(first), math.floor(last)
    if not 0 < k1 - k0 + 1 <= MAX_TICKS:
        return [lo, hi]
    ticks = [0.0 if abs(k * step) < step * 1e-9 else k * step for k in range(k0, k1 + 1)]
    if len(set(ticks)) != len(ticks):  # steps below float spacing: ticks coincide
        return [lo, hi]
    return ticks


def _tick_text(v: float, ticks: Sequence[float]) -> str:
    step = abs(ticks[1] - ticks[0]) if len(ticks) > 1 else 1.0
    decimals = max(0, -math.floor(math.log10(step))) if step > 0 else 0
    return f"{v:.{decimals}f}" if decimals <= 4 else f"{v:.3g}"


def _y_range(series: Sequence[Series], min_span: float) -> tuple[float, float]:
    """The y axis's extent: the finite values with a margin, at least ``min_span`` wide
    (a value steady but for rounding noise is drawn flat, not magnified)."""
    finite = np.concatenate([s.values[np.isfinite(s.values)] for s in series] or [np.empty(0)])
    if finite.size == 0:
        return -min_span / 2, min_span / 2
    lo, hi = float(finite.min()), float(finite.max())
    if hi - lo < min_span:
        mid = (hi + lo) / 2
        lo, hi = mid - min_span / 2, mid + min_span / 2
    pad = (hi - lo) * 0.06
    return lo - pad, hi + pad


def _path(x: np.ndarray, y: np.ndarray) -> str:
    """SVG path data through the points, a new sub-path after every missing (NaN) one."""
    parts = []
    pen_down = False
    for xi, yi in zip(x.tolist(), y.tolist(), strict=True):
        if math.isfinite(yi):
            parts.append(f"{'L' if pen_down else 'M'}{xi:.1f} {yi:.1f}")
            pen_down = True
        else:
            pen_down = False
    return "".join(parts)


def line_chart(t: np.ndarray, series: Sequence[Series], *, title: str, y_label: str,
               min_span: float = 1.0, buckets: int = 600) -> str:
    """One chart as an ``<svg>`` element: ``series`` against time ``t`` (m,) s, with the
    title, axis titles, round ticks, a legend and the time cursor; all text escaped. The
    y axis spans at least ``min_span`` (in the series' unit)."""
    t = np.asarray(t, dtype=float)
    columns = np.column_stack([s.values for s in series]) if series else np.empty((t.size, 0))
    idx = envelope_indices(columns, buckets=buckets) if series else np.arange(t.size)
    t0, t1 = float(t[0]), float(t[-1])
    if not t1 > t0:
        t1 = t0 + max(1.0, abs(t0) * 1e-6)
    y0, y1 = _y_range(series, min_span)
    x_left, x_right = LEFT, WIDTH - RIGHT
    y_top, y_bottom = TOP, HEIGHT - BOTTOM

    def sx(v: np.ndarray | float) -> np.ndarray | float:
        return x_left + (np.asarray(v) - t0) / (t1 - t0) * (x_right - x_left)

    def sy(v: np.ndarray | float) -> np.ndarray | float:
        return y_bottom - (np.asarray(v) - y0) / (y1 - y0) * (y_bottom - y_top)

    out = [f'<svg class="chart" viewBox="0 0 {WIDTH:g} {HEIGHT:g}" role="img" '
           f'aria-label="{escape(title)}" data-t0="{t0!r}" data-t1="{t1!r}" '
           f'data-x0="{x_left:g}" data-x1="{x_right:g}">',
           f'<text class="title" x="{x_left:g}" y="16">{escape(title)}</text>',
           f'<rect class="plot" x="{x_left:g}" y="{y_top:g}" width="{x_right - x_left:g}" '
           f'height="{y_bottom - y_top:g}"/>']
    yt = nice_ticks(y0, y1)
    for v in yt:
        y = float(sy(v))
        out.append(f'<line class="grid" x1="{x_left:g}" x2="{x_right:g}" y1="{y:.1f}" '
                   f'y2="{y:.1f}"/><text class="tick" x="{x_left - 4:g}" y="{y + 4:.1f}" '
                   f'text-anchor="end">{escape(_tick_text(v, yt))}</text>')
    xt = nice_ticks(t0, t1, count=6)
    for v in xt:
        x = float(sx(v))
        out.append(f'<line class="grid" x1="{x:.1f}" x2="{x:.1f}" y1="{y_top:g}" '
                   f'y2="{y_bottom:g}"/><text class="tick" x="{x:.1f}" y="{y_bottom + 14:g}" '
                   f'text-anchor="middle">{escape(_tick_text(v, xt))}</text>')
    out.append(f'<text class="axis" x="{(x_left + x_right) / 2:g}" y="{HEIGHT - 6:g}" '
               f'text-anchor="middle">time (s)</text>')
    mid = (y_top + y_bottom) / 2
    out.append(f'<text class="axis" x="14" y="{mid:g}" text-anchor="middle" '
               f'transform="rotate(-90 14 {mid:g})">{escape(y_label)}</text>')
    xs = sx(t[idx])
    legend_x = x_right
    for s in reversed(series):  # the legend right-aligned above the plot, in series order
        label = escape(s.label)
        legend_x -= 7.0 * len(s.label) + 40.0
        out.append(f'<line x1="{legend_x:.1f}" x2="{legend_x + 18:.1f}" y1="12" y2="12" '
                   f'stroke="{escape(s.color)}" stroke-width="2"'
                   + (f' stroke-dasharray="{escape(s.dash)}"' if s.dash else "") + "/>"
                   f'<text class="legend" x="{legend_x + 22:.1f}" y="16">{label}</text>')
    for s in series:
        d = _path(np.asarray(xs), np.asarray(sy(s.values[idx])))
        if d:
            out.append(f'<path class="line" d="{d}" stroke="{escape(s.color)}"'
                       + (f' stroke-dasharray="{escape(s.dash)}"' if s.dash else "") + "/>")
    out.append(f'<line class="cursor" x1="{x_left:g}" x2="{x_left:g}" y1="{y_top:g}" '
               f'y2="{y_bottom:g}"/>')
    out.append("</svg>")
    return "".join(out)
