"""What a person sees, measured in a real headless Chromium (issue 34, item 10): at
1920x1080 with the Projector switch on, every chart's axis titles lie whole inside their
chart, the "Step test" folder's title keeps clear of the Reset button above it, and
every lesson's name fits the lesson picker; a URDF arm's joint sliders end on round
numbers inside the joint's limits; on a 390x844 phone the arm's shapes (its top
included) lie inside the 3D view, with the framing's margin.

Each test polls for its condition: the page arrives in pieces (and projector sizes,
rebuilt charts and a reshaped 3D view come after it).
"""

from __future__ import annotations

import math
import re

import pytest
from _helpers import new_page_client, wait_for, wait_look_settled

from armlab.app.lab.server import CONTROLS_PX
from armlab.app.lessons.catalog import all_lessons
from armlab.app.page import camera

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]

#: For every uPlot chart on the page: its title and, per labelled axis, the label, the
#: extent of its text along the axis and the extent of the canvas it is drawn on (canvas
#: px; uPlot centres a label on the plot's extent along its axis).
AXIS_TITLES_JS = """() => Object.values((window.__viserTestpoints || {}).uplots || {})
  .filter(({chart}) => chart.root.isConnected)
  .map(({chart}) => {
    const ctx = chart.ctx, box = chart.bbox, out = [];
    for (const ax of chart.axes) {
      if (!ax.show || !ax.label) continue;
      ctx.save(); ctx.font = ax.labelFont[0]; const w = ctx.measureText(ax.label).width;
      ctx.restore();
      const vertical = ax.side % 2 === 1;
      const mid = vertical ? box.top + box.height / 2 : box.left + box.width / 2;
      const end = vertical ? ctx.canvas.height : ctx.canvas.width;
      out.push([ax.label, ax.labelFont[0], mid - w / 2, mid + w / 2, end]);
    }
    return [(chart.root.querySelector('.u-title') || {}).textContent || '', out];
  })"""

#: px (CSS) of the font each chart's canvas last drew its axes with
TICK_PX_JS = """() => [...document.querySelectorAll('.uplot canvas')].map(c => {
  const m = /(\\d+(?:\\.\\d+)?)px/.exec(c.getContext('2d').font);
  return m ? parseFloat(m[1]) / devicePixelRatio : 0;
})"""

#: Every titled folder's title (text, box, scrollWidth, clientWidth) and every button's
#: box in the control panel (box: left, top, right, bottom, CSS px).
FOLDERS_AND_BUTTONS_JS = """() => {
  const box = e => { const r = e.getBoundingClientRect();
                     return [r.left, r.top, r.right, r.bottom]; };
  const titles = [...document.querySelectorAll(
      '.mantine-Paper-root[data-with-border]:not(.uplot-container)'
      + ' > .mantine-Paper-root:first-child')]
    .filter(e => e.getBoundingClientRect().width > 0)
    .map(e => [e.textContent.trim(), box(e), e.scrollWidth, e.clientWidth]);
  const buttons = [...document.querySelectorAll('button')]
    .filter(e => e.getBoundingClientRect().width > 0 && e.textContent.trim())
    .map(e => [e.textContent.trim(), box(e)]);
  return [titles, buttons];
}"""

#: The lesson picker's input: its width for text (CSS px: inside its padding, less the
#: chevron drawn at its right), its font size, the width of each of ``titles`` in its
#: font, and the width of the control panel it is in.
PICKER_JS = """(titles) => {
  const label = [...document.querySelectorAll('label')]
    .find(l => l.textContent.trim() === 'Lesson');
  const input = label && document.getElementById(label.htmlFor);
  if (!input) return null;
  const cs = getComputedStyle(input), ctx = document.createElement('canvas').getContext('2d');
  ctx.font = cs.font;
  const right = input.parentElement.querySelector('[data-position="right"]');
  const chevron = right ? right.getBoundingClientRect().width : 0;
  const room = input.clientWidth - parseFloat(cs.paddingLeft)
    - Math.max(parseFloat(cs.paddingRight), chevron);
  const panel = input.closest('.mantine-Paper-root');
  return [room, cs.fontSize, titles.map(t => [t, ctx.measureText(t).width]),
          panel ? panel.getBoundingClientRect().width : 0];
}"""

#: NDC extent ([x min, y min], [x max, y max]) of the boxes round the meshes of the
#: given scene nodes (each node's own meshes, not those of nodes under it) through the
#: page's own camera; null until the page has its scene.
SHAPES_NDC_JS = """(names) => {
  const m = window.__viserMutable;
  if (!m || !m.camera || !m.nodeRefFromName) return null;
  const nodes = new Set(Object.values(m.nodeRefFromName));
  const cam = m.camera; cam.updateMatrixWorld();
  let lo = [Infinity, Infinity], hi = [-Infinity, -Infinity], n = 0;
  const visit = (o, top) => {
    if (o !== top && nodes.has(o)) return;
    if (o.isMesh && o.geometry) {
      if (!o.geometry.boundingBox) o.geometry.computeBoundingBox();
      const b = o.geometry.boundingBox;
      for (const x of [b.min.x, b.max.x]) for (const y of [b.min.y, b.max.y])
        for (const z of [b.min.z, b.max.z]) {
          const v = o.position.clone().set(x, y, z).applyMatrix4(o.matrixWorld).project(cam);
          lo = [Math.min(lo[0], v.x), Math.min(lo[1], v.y)];
          hi = [Math.max(hi[0], v.x), Math.max(hi[1], v.y)]; n += 1;
        }
    }
    for (const c of o.children) visit(c, top);
  };
  for (const name of names) {
    const obj = m.nodeRefFromName[name];
    if (!obj) continue;
    let shown = true;
    for (let p = obj; p; p = p.parent) if (!p.visible) shown = false;
    if (!shown) continue;
    obj.updateWorldMatrix(true, true);
    visit(obj, obj);
  }
  return n ? [lo, hi, n] : null;
}"""


def _open(browser, lab, *, width: int = 1920, height: int = 1080):
    """A page of ``lab`` at ``width`` x ``height``, its controls arrived, its look settled."""
    known = set(lab.server.get_clients())
    pg = browser.new_page(viewport={"width": width, "height": height})
    pg.goto(lab.url)
    pg.locator("canvas").first.wait_for()
    wait_look_settled(lab, known)
    pg.client = new_page_client(lab, known)  # type: ignore[attr-defined]
    return pg


def _projector_on(pg) -> None:
    """Click the page's Projector switch and wait until its charts draw at that size."""
    switch = pg.get_by_role("checkbox", name="Projector")
    switch.dispatch_event("click")  # a click event: the panel may still be settling
    wait_for(switch.is_checked, 60.0, "the Projector switch to turn on")
    wait_for(lambda: (px := pg.evaluate(TICK_PX_JS)) and min(px) >= 18.0, 120.0,
             "the charts to draw at projector size")


@pytest.fixture(scope="class")
def projector_page(browser, lab):
    """A 1920x1080 page of the lab's first lesson with its Projector switch on."""
    pg = _open(browser, lab)
    wait_for(lambda: pg.locator(".u-title").count() > 0, 120.0, "the charts to draw")
    _projector_on(pg)
    yield pg
    pg.close()


def _cut_axis_titles(pg) -> list[tuple]:
    """(chart, axis label, its text's extent, the canvas's) of every axis title that does
    not lie whole on its chart's canvas."""
    cut = []
    for title, axes in pg.evaluate(AXIS_TITLES_JS):
        for label, font, start, end, extent in axes:
            if start < 0 or end > extent:
                cut.append((title, label, font, round(start), round(end), extent))
    return cut


def _boxes_meet(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _folder_problems(pg) -> list[str]:
    titles, buttons = pg.evaluate(FOLDERS_AND_BUTTONS_JS)
    out = [f"{t!r} clipped ({sw} > {cw})" for t, _, sw, cw in titles if sw > cw]
    out += [f"{t!r} covers {b!r}" for t, tb, _, _ in titles for b, bb in buttons
            if _boxes_meet(tb, bb)]
    return out


def _picker_overflow(pg, titles: list[str]) -> tuple[float, list[tuple[str, float]]]:
    got = pg.evaluate(PICKER_JS, titles)
    if got is None:
        return 0.0, [("no picker", 0.0)]
    room, _, widths, _ = got
    return room, [(t, round(w)) for t, w in widths if w > room]


class TestProjectorPage:
    """One 1920x1080 page in projector mode, closed before the other tests open theirs."""

    def test_chart_axis_titles_lie_inside_their_charts(self, projector_page):
        pg = projector_page
        wait_for(lambda: len(pg.evaluate(AXIS_TITLES_JS)) >= 4, 120.0, "the lesson's charts")
        wait_for(lambda: not _cut_axis_titles(pg), 120.0,
                 lambda: f"every axis title inside its chart; cut: {_cut_axis_titles(pg)}")
        fonts = {font for _, axes in pg.evaluate(AXIS_TITLES_JS) for _, font, *_ in axes}
        assert all("20px" in f for f in fonts), fonts  # measured at projector size

    def test_the_step_test_folder_title_keeps_clear_of_the_reset_button(self, projector_page):
        pg = projector_page
        wait_for(lambda: any(t[0].startswith("Step test")
                             for t in pg.evaluate(FOLDERS_AND_BUTTONS_JS)[0]), 120.0,
                 "the Step test folder")
        titles, buttons = pg.evaluate(FOLDERS_AND_BUTTONS_JS)
        assert any(b == "Reset" for b, _ in buttons), [b for b, _ in buttons]
        wait_for(lambda: not _folder_problems(pg), 60.0,
                 lambda: f"folder titles clear of the buttons: {_folder_problems(pg)}")

    def test_every_lesson_name_fits_the_lesson_picker_in_projector_mode(self, projector_page):
        pg = projector_page
        titles = [m.title for m in all_lessons().values()]
        wait_for(lambda: pg.evaluate(PICKER_JS, titles) is not None, 60.0, "the lesson picker")
        wait_for(lambda: pg.evaluate(PICKER_JS, titles)[1] == "22px", 60.0,
                 "the picker at projector size")
        # the docked controls keep the lab's width (viser's own default is narrower)
        wait_for(lambda: pg.evaluate(PICKER_JS, titles)[3] == CONTROLS_PX, 60.0,
                 lambda: f"the controls {CONTROLS_PX} px wide: "
                         f"{pg.evaluate(PICKER_JS, titles)[3]} px")
        wait_for(lambda: not _picker_overflow(pg, titles)[1], 120.0,
                 lambda: f"every lesson name to fit the picker: {_picker_overflow(pg, titles)}")
        # the open list shows each name unclipped as well
        pg.get_by_label("Lesson").first.click()
        options = pg.get_by_role("option")
        wait_for(lambda: options.count() >= len(titles), 60.0, "the picker's list")
        clipped = pg.evaluate("""() => [...document.querySelectorAll('[role=option]')]
            .filter(o => o.scrollWidth > o.clientWidth).map(o => o.textContent)""")
        assert not clipped
        pg.keyboard.press("Escape")


#: a slider end as viser prints it (min/max with trailing zeros cut)
NUMBER = re.compile(r"^-?\d+(\.\d+)?$")


def test_a_urdf_arms_joint_sliders_end_on_round_numbers_inside_its_limits(browser, lab):
    first = lab.lesson_name
    pg = _open(browser, lab)
    try:
        lab.switch("arm")
        model, loop = lab.lesson.model, lab.lesson.loop
        labels = pg.locator(".mantine-Slider-markLabel")
        names = [f"{j.name} °" for j in model.joints]

        def ends() -> list[list[str]]:
            return pg.evaluate("""(names) => names.map(n => {
                let row = [...document.querySelectorAll('*')]
                  .find(e => e.childElementCount === 0 && e.textContent.trim() === n);
                while (row && !row.querySelector('.mantine-Slider-markLabel'))
                  row = row.parentElement;
                return row ? [...row.querySelectorAll('.mantine-Slider-markLabel')]
                  .map(e => e.textContent.trim()) : [];
            })""", names)

        wait_for(lambda: labels.count() > 0 and all(len(e) == 2 for e in ends()), 120.0,
                 lambda: f"the joint sliders' ends: {ends()}")
        for joint, (lo_text, hi_text), lo, hi in zip(model.joints, ends(), loop.lower,
                                                     loop.upper, strict=True):
            for text in (lo_text, hi_text):
                assert NUMBER.match(text), (joint.name, text)
                assert len(text.partition(".")[2]) <= 2, (joint.name, text)
            # never a value outside the joint's limits
            assert math.radians(float(lo_text)) >= lo and math.radians(float(hi_text)) <= hi
    finally:
        pg.close()
        lab.switch(first)


def _shape_nodes(lab) -> list[str]:
    """Names of the scene nodes with shapes that the lesson's view frames (its robot's
    meshes and its task's markers; not frames, labels or gizmos)."""
    from armlab.app.viser_ext.handles import scene_nodes

    view = camera._views[lab.server.scene]
    return [name for name, handle in scene_nodes(lab.server.scene).items()
            if any(name == r or name.startswith(r + "/") for r in view.roots)
            and camera._local_box(handle) is not None]


#: how far towards the 3D view's edges (1: the edge, in NDC) the robot's shapes may reach:
#: the framing's margin (camera.FILL), and a little for an arm settling as it holds (the
#: arm's top once reached 0.98, and the view's edge before the page's shape was known)
FRAMED = camera.FILL + 0.05


@pytest.mark.parametrize("lesson", ["arm", "compliance"])
def test_the_robot_lies_inside_the_3d_view_on_a_phone(browser, lab, lesson):
    first = lab.lesson_name
    lab.switch(lesson)
    pg = _open(browser, lab, width=390, height=844)
    client = pg.client  # type: ignore[attr-defined]
    try:
        names = _shape_nodes(lab)
        assert names

        def extent():
            return pg.evaluate(SHAPES_NDC_JS, names)

        def inside() -> bool:
            got = extent()
            framing = camera.shown(client)
            if got is None or framing is None:
                return False
            (x0, y0), (x1, y1), _ = got
            return max(-x0, x1, -y0, y1) <= FRAMED

        wait_for(inside, 180.0,
                 lambda: f"the robot's shapes inside the phone's 3D view: NDC {extent()}")
    finally:
        pg.close()
        lab.switch(first)
