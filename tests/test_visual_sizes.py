"""The sizes behind what a person sees (issue 34, item 10; measured in a browser by
tests/test_browser_visuals.py): a chart is tall enough for its y labels in both text
sizes, a slider's ends are round and inside its range, folder titles stay on one line,
and lesson names are short."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from armlab.app.lessons.catalog import all_lessons
from armlab.app.page import plots, theme
from armlab.app.page.inputs import inward_range


def test_a_chart_is_tall_enough_for_its_longest_y_label_in_both_sizes():
    label = "torque (kgf·cm)"
    for s in (theme.NORMAL, theme.PROJECTOR):
        h = plots.chart_height(s, height=130, y_labels=("error (°)", label, None))
        plot = h - s.x_axis - plots.LABEL_ROOM
        assert plot >= plots.LABEL_CHAR_EM * s.ticks * len(label)
        assert h >= 130 + s.x_axis - theme.NORMAL.x_axis  # the plot never shrinks
    # a projected chart's plot is 1.6 times its normal height: 136 px become 218 px
    normal = plots.chart_height(theme.NORMAL, height=170, y_labels=("angle (°)",))
    projected = plots.chart_height(theme.PROJECTOR, height=170, y_labels=("angle (°)",))
    assert (normal, projected) == (170, 218 + theme.PROJECTOR.x_axis)
    axes = plots.chart_axes(theme.PROJECTOR, y_label="a", y2_label="b", x_label="t (s)")
    assert [a["label"] for a in axes] == ["t (s)", "a", "b"]
    assert all(a["labelSize"] == plots.LABEL_ROOM for a in axes)


@given(lo=st.floats(-400.0, 400.0), span=st.floats(0.0, 500.0),
       step=st.sampled_from([0.1, 0.5, 1.0, 5.0]))
def test_slider_ends_are_round_and_inside_the_range(lo, span, step):
    hi = lo + span
    a, b = inward_range(lo, hi, step=step)
    assert lo <= a <= b <= hi
    if math.floor(hi / step) > math.ceil(lo / step):  # holds two multiples: ends on them
        for end in (a, b):
            assert abs(end / step - round(end / step)) < 1e-6
            assert len(repr(end).partition(".")[2]) <= 2


def test_folder_titles_stay_on_one_line_in_both_sheets():
    for s in (theme.NORMAL, theme.PROJECTOR):
        assert "white-space:nowrap" in theme.style_sheet(s)


def test_lesson_names_are_short_enough_for_the_picker():
    assert all(len(m.title) <= 14 for m in all_lessons().values())
