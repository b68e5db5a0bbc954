"""Charts that tell the truth about size: an axis never spans less than its quantity's
smallest span, so an arm at rest shows its position steps as the small ripple they are.

``fit_range`` is the rule; a :class:`~armlab.app.page.plots.LivePlot` on a real viser server shows
what a page receives (a headless client): the pinned y range at rest, after a step,
and back at rest once the step has left the window.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import viser
from _helpers import client_of
from hypothesis import given
from hypothesis import strategies as st

from armlab.app.page.plots import (
    ANGLE_SPAN_DEG,
    HEADROOM,
    SHRINK,
    TICK_ROOM,
    LivePlot,
    SeriesSpec,
    fit_range,
    nice_step,
)
from armlab.hardware.servos.servo_spec import RX24F

RX24F_STEP_DEG = math.degrees(RX24F.position_unit)  # 0.29°


@given(st.floats(-1e4, 1e4), st.floats(0.0, 1e3), st.floats(1e-3, 1e3))
def test_fit_range_holds_the_data_and_spans_at_least_the_minimum(lo, width, min_span):
    hi = lo + width
    r = fit_range(lo, hi, min_span=min_span)
    assert r is not None
    assert r[0] <= lo and hi <= r[1]
    assert r[1] - r[0] >= min_span
    # not wider than the span needed, its headroom and one round step on each side
    need = max(width, min_span)
    rounded = need * (1 + 2 * HEADROOM) + nice_step(need * (1 + 2 * HEADROOM))
    assert r[1] - r[0] <= rounded * (1 + 2 * TICK_ROOM) + 1e-9 * max(1.0, abs(lo))


@given(st.floats(-1e3, 1e3), st.floats(0.0, 1e2), st.floats(-1e3, 1e3), st.floats(1e-2, 1e3))
def test_a_new_range_from_a_pinned_one_holds_the_data(lo, width, c_lo, c_width):
    hi = lo + width
    r = fit_range(lo, hi, min_span=4.0, current=(c_lo, c_lo + c_width))
    if r is None:  # kept: the data is inside it
        assert c_lo <= lo and hi <= c_lo + c_width
    else:
        assert r[0] <= lo and hi <= r[1] and r[1] - r[0] >= 4.0


def test_fit_range_keeps_a_range_that_still_fits_and_narrows_one_far_too_wide():
    r = fit_range(29.8, 30.1, min_span=4.0)
    assert r is not None and r[0] <= 28.0 and r[1] >= 32.0 and r[1] - r[0] < 8.0
    assert fit_range(29.5, 30.4, min_span=4.0, current=r) is None  # still inside: kept
    moved = fit_range(29.5, 45.0, min_span=4.0, current=r)  # left it: re-pinned
    assert moved is not None and moved[1] >= 45.0
    assert fit_range(29.8, 30.1, min_span=4.0, current=moved) is not None  # too wide now
    assert fit_range(0.0, 1.0, min_span=4.0, current=(-2.0, 2.0 + 4.0 * SHRINK)) is not None


@pytest.mark.parametrize(("span", "step"), [(4.0, 1.0), (1.0, 0.5), (0.5, 0.2), (30.0, 10.0),
                                            (7.0, 2.0)])
def test_nice_step_is_one_two_or_five_times_a_power_of_ten(span, step):
    assert nice_step(span) == pytest.approx(step)


def _resting(t: np.ndarray, level: float) -> np.ndarray:
    """An arm at rest near ``level`` °: a reading that flickers between two position steps."""
    return level + RX24F_STEP_DEG * (np.arange(len(t)) % 2)


def test_a_resting_angle_chart_spans_the_minimum_and_a_step_widens_it():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        plot = LivePlot(server.gui, title="Joint angle", y_label="angle (°)", window_s=2.0,
                        points=50, series=(SeriesSpec("actual θ", "#000000"),),
                        y_span=ANGLE_SPAN_DEG)
        with client_of(server) as page:
            t = np.arange(0.0, 2.0, 0.01)
            plot.update(t, [_resting(t, 30.0)])

            def y_range():
                charts = [e for e in page.gui.values() if e.kind == "GuiUplotMessage"]
                return tuple(charts[0].props["scales"]["y"].get("range") or ()) if charts else ()

            page.wait_for(lambda: y_range() == plot.ranges["y"], what="the pinned range")
            lo, hi = y_range()
            assert hi - lo >= ANGLE_SPAN_DEG and lo <= 30.0 and 30.0 + RX24F_STEP_DEG <= hi
            # the ripple fills less than a tenth of the chart's height
            assert RX24F_STEP_DEG / (hi - lo) < 0.1

            # a step to 60° over the next second: the axis widens to hold it, in a few
            # re-pins, not one per update
            pins = [plot.ranges["y"]]
            for k in range(1, 21):
                t2 = np.arange(0.0, 2.0 + 0.05 * k, 0.01)
                y = np.where(t2 < 2.0, _resting(t2, 30.0), 30.0 + 30.0 * np.minimum(
                    (t2 - 2.0) / 1.0, 1.0))
                plot.update(t2, [y])
                if plot.ranges["y"] != pins[-1]:
                    pins.append(plot.ranges["y"])
            page.wait_for(lambda: y_range() == plot.ranges["y"], what="the widened range")
            lo, hi = y_range()
            assert lo <= 30.0 and hi >= 60.0
            assert 2 <= len(pins) <= 6, pins

            # at rest at 60° once the step has left the window: narrow again
            t3 = np.arange(10.0, 12.0, 0.01)
            plot.update(t3, [_resting(t3, 60.0)])
            page.wait_for(lambda: y_range() == plot.ranges["y"], what="the narrowed range")
            lo, hi = y_range()
            assert lo <= 60.0 <= hi and ANGLE_SPAN_DEG <= hi - lo < 2 * ANGLE_SPAN_DEG
    finally:
        server.stop()


def test_an_axis_without_a_span_scales_to_its_data_alone():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        plot = LivePlot(server.gui, title="w", y_label="w", series=(SeriesSpec("w", "#000000"),))
        t = np.arange(0.0, 2.0, 0.01)
        plot.update(t, [_resting(t, 30.0)])
        assert plot.ranges == {} and plot.handle.scales["y"] == {"auto": True}
    finally:
        server.stop()


def test_a_chart_update_reaches_the_page_as_float32_arrays_of_its_window():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        plot = LivePlot(server.gui, title="Joint angle", y_label="angle (°)", window_s=2.0,
                        points=50, series=(SeriesSpec("actual θ", "#000000"),))
        with client_of(server) as page:
            t = np.arange(0.0, 4.0, 0.01)
            y = 30.0 + 10.0 * np.sin(t)
            plot.update(t, [y])

            def data():
                charts = [e for e in page.gui.values() if e.kind == "GuiUplotMessage"]
                d = charts[0].props.get("data") if charts else None
                return d if d is not None and len(d[0]) > 2 else None

            page.wait_for(lambda: data() is not None, what="the chart's data")
            x, shown = data()
            # 4 bytes a value: half of float64's, at the precision the chart draws
            assert x.dtype == np.float32 and shown.dtype == np.float32
            assert x[0] == -2.0 and x[-1] == 0.0 and np.all(np.diff(x) > 0)
            assert len(x) <= 52
            np.testing.assert_allclose(shown, np.interp(x + t[-1], t, y), atol=0.2)
    finally:
        server.stop()
