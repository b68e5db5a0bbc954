"""Nothing clipped in the docked panels, in real headless Chromium: for the compliance
lesson in normal and Projector mode at 1920x1080 and 1280x720, on every tab, and for the
IK-accuracy lesson's table, no text of a panel lies outside it (a wide table used to
push the whole Teach tab's "measured" column off a projected panel) and every number
field shows its whole value (a slider's field cut "-20" to "-2" in Projector mode). A
table of six columns or more (the paper's Table 1) scrolls sideways inside its panel,
its numbers whole: its box must fit the panel."""

from __future__ import annotations

import pytest
from _helpers import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

#: What of the panel does not fit: [why, tag, text, ...] per element ("off-panel": its box
#: leaves the panel's; "clipped": a number field narrower than its value).
MISFITS_JS = """() => {
  const panels = [...document.querySelectorAll(
    '[data-dock-region] .mantine-ScrollArea-viewport')];
  if (!panels.length) return [['no panel']];
  const out = [];
  for (const v of panels) {
  const P = v.getBoundingClientRect();
  if (P.width < 50) continue;  // a collapsed side
  for (const e of v.querySelectorAll('*')) {
    const r = e.getBoundingClientRect();
    if (r.width === 0 || r.height === 0 || e.children.length > 0 && e.tagName !== 'INPUT') continue;
    const text = (e.value || e.textContent || '').trim().slice(0, 40);
    if (!text) continue;
    // a table of six columns or more scrolls sideways inside the panel: its cells may
    // lie past the panel's edge, within the table's own scrolling box
    const scroller = e.closest('table');
    if (scroller && getComputedStyle(scroller).overflowX === 'auto') {
      const S = scroller.getBoundingClientRect();
      if (S.right > P.right + 1 || S.left < P.left - 1) out.push(['off-panel', 'TABLE', text]);
      continue;
    }
    if (r.right > P.right + 1 || r.left < P.left - 1) {
      out.push(['off-panel', e.tagName, text, Math.round(r.left), Math.round(r.right)]);
    } else if (e.classList.contains('mantine-NumberInput-input')
               && e.scrollWidth > e.clientWidth + 1) {
      out.push(['clipped', e.tagName, text, e.scrollWidth, e.clientWidth]);
    }
  }
  }
  return out;
}"""
#: the px of the panel's text in each mode (armlab.app.page.theme)
TEXT_PX = {False: "14px", True: "22px"}


def _page(browser, lab, size: tuple[int, int], *, projector: bool):  # noqa: ANN001, ANN202
    """A page of ``lab`` at ``size`` (px) with its Projector switch as asked."""
    pg = browser.new_page(viewport={"width": size[0], "height": size[1]})
    pg.goto(lab.url)
    box = pg.get_by_role("checkbox", name="Projector")
    box.wait_for(timeout=120_000)
    if box.is_checked() != projector:
        box.click()
    return pg


@pytest.mark.parametrize("size", [(1920, 1080), (1280, 720)], ids=["1920x1080", "1280x720"])
@pytest.mark.parametrize("projector", [False, True], ids=["normal", "projector"])
def test_nothing_in_the_panel_is_clipped_on_any_tab(browser, lab, size, projector):
    assert lab.lesson_name == "compliance"
    pg = _page(browser, lab, size, projector=projector)
    try:
        pg.get_by_role("button", name="Run thesis line").wait_for(timeout=120_000)

        def sized() -> bool:  # the page's style sheet for its mode has arrived
            return pg.evaluate("() => { const e = document.querySelector("
                               "'.mantine-Paper-root label'); "
                               "return e && getComputedStyle(e).fontSize; }"
                               ) == TEXT_PX[projector]

        wait_for(sized, 60, f"the panel's text at {TEXT_PX[projector]}", every=0.5)
        tabs = [t.strip() for t in pg.get_by_role("tab").all_inner_texts()]
        assert {"Run", "Gains", "Teach"} <= set(tabs), tabs
        seen: dict[str, list] = {}
        for tab in tabs:
            pg.get_by_role("tab", name=tab, exact=True).first.click()
            # (a tab's panel lays out over a frame or two: give it a few looks)
            try:
                wait_for(lambda: not pg.evaluate(MISFITS_JS), 5, f"the {tab} tab to fit",
                         every=0.5)
            except AssertionError:
                seen[tab] = pg.evaluate(MISFITS_JS)
        assert not seen, seen
    finally:
        pg.close()


@pytest.fixture(scope="module")
def ik_lab():
    from armlab.app.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, robot="planar_servo_arm")) as running:
        yield running


@pytest.mark.parametrize(("size", "projector"), [((1920, 1080), True), ((1280, 720), False)],
                         ids=["1920x1080-projector", "1280x720-normal"])
def test_the_ik_accuracy_table_fits_its_panel(browser, ik_lab, size, projector):
    assert ik_lab.lesson_name == "ik_accuracy"
    pg = _page(browser, ik_lab, size, projector=projector)
    try:
        pg.get_by_role("button", name="Run the paper's table").click()  # its 24 rows
        pg.get_by_text("Out of range (14 rows)").first.wait_for(timeout=120_000)
        wait_for(lambda: not pg.evaluate(MISFITS_JS), 60,
                 lambda: f"the panels to fit: {pg.evaluate(MISFITS_JS)}", every=0.5)
    finally:
        pg.close()
