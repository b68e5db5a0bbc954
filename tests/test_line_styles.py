"""Lines sharing a chart differ in dash pattern or width as well as colour.

Read from the chart configuration a page receives (a headless client of the
real lesson server): every chart of every lesson, and in particular quadruped
servo 1/2/3, hand finger 1/2/3 and the redundancy lesson's modes, whose colours
alone were hard to tell apart for colour-blind readers (magenta vs green, blue vs
purple).
"""

from __future__ import annotations

import re

import pytest
from _browser_style import chart_props
from _helpers import served_lesson, settled

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons import LessonContext, hand, quadruped, redundancy
from armlab.app.lessons.catalog import all_lessons
from armlab.app.page.plots import COLORS, distinct_styles
from armlab.app.testing.wsclient import HeadlessClient

#: Okabe-Ito (armlab.app.page.plots.COLORS) and the greys of zero and limit lines
GREYS = {"#999999", "#bbbbbb", "#777777"}


def _series_by_chart(server, pattern: str) -> list[list[dict]]:
    """Per chart, the series whose label matches ``pattern``."""
    out = []
    for chart in chart_props(server):
        lines = [s for s in chart["series"][1:] if re.fullmatch(pattern, str(s.get("label", "")))]
        if len(lines) > 1:
            out.append(lines)
    return out


@pytest.mark.parametrize(("module", "robot", "pattern"), [
    (quadruped, "quadruped", r"servo \d"),
    (hand, "receptionist_arm", r"finger \d"),
    (redundancy, "redundant_planar", r"mode \w+"),
])
def test_lines_of_one_kind_differ_in_dash(module, robot, pattern):
    servers = []

    def build(server, ctx):
        servers.append(server)
        return module.build(server, ctx)

    with served_lesson(build, LessonContext(robot=robot, realtime=False)):
        charts = _series_by_chart(servers[0], pattern)
    assert charts, "no chart with two or more such lines"
    both = 0  # charts holding mode 1 and mode bounded (the check below must not be vacuous)
    for lines in charts:
        styles = [(s["stroke"], tuple(s.get("dash") or ())) for s in lines]
        dashes = [d for _, d in styles]
        # mode 1 and 2 (blue, orange) may both be solid; any two lines of like hue may not
        assert len(set(styles)) == len(styles)
        if pattern != r"mode \w+":
            assert len(set(dashes)) == len(dashes), styles
        else:
            by_label = {s["label"]: tuple(s.get("dash") or ()) for s in lines}
            if "mode bounded" in by_label:
                both += 1
                assert by_label["mode 1"] != by_label["mode bounded"], by_label
            assert len(set(dashes)) >= len(dashes) - 1, styles
    assert both or pattern != r"mode \w+", "no chart holds mode 1 and mode bounded"


@pytest.mark.parametrize("lesson", sorted(all_lessons()))
@pytest.mark.slow
def test_every_chart_tells_its_lines_apart_without_colour(lesson):
    with Lab(ServeOptions(http_port=0, lesson=lesson, realtime=False)) as lab, \
            HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
        settled(lab.server, page)
        charts = [dict(e.props) for e in page.gui.values() if e.kind == "GuiUplotMessage"]
    for chart in charts:
        lines = chart["series"][1:]
        assert distinct_styles(lines) == [], (chart.get("title"), lines)
        colours = {str(s["stroke"]).lower() for s in lines}
        assert colours <= {c.lower() for c in COLORS} | GREYS, (chart.get("title"), colours)


def test_distinct_styles_names_lines_told_apart_by_colour_alone():
    a = {"label": "a", "stroke": COLORS[0], "width": 2}
    b = {"label": "b", "stroke": COLORS[1], "width": 2}
    assert distinct_styles([{"label": "t"}, a, b]) == [("a", "b")]
    assert distinct_styles([a, {**b, "dash": [6, 4]}]) == []
    assert distinct_styles([a, {**b, "width": 4}]) == []
    assert distinct_styles([a, {**a, "label": "a too"}]) == []  # one colour: one kind
