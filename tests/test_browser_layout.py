"""Nothing clipped, nothing overprinted, in real headless Chromium: for every lesson, on
every tab, in normal and Projector mode, at 1920x1080, 1280x720 and a 390x844 phone, no
text of a panel lies outside it (a wide table used to push the whole Teach tab's
"measured" column off a projected panel), every number field shows its whole value (a
slider's field cut "-20" to "-2" in Projector mode) and no two texts of a panel overprint
each other (the E-STOP's icon on its "E"; on a phone the pinned E-STOP passes over the
controls scrolled under it, by design). A table of six columns or more (the paper's
Table 1) scrolls sideways inside its panel, its numbers whole: its box must fit the
panel. (The 3D labels are drawn in WebGL, not the page: tests/test_lesson_redundancy.py
places the one lesson's labels that share a view apart.)"""

from __future__ import annotations

import pytest
from _helpers import wait_for

from armlab.app.lessons.catalog import LESSONS

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]

#: What of the panel does not fit: [why, tag, text, ...] per element ("off-panel": its box
#: leaves the panel's; "clipped": a number field narrower than its value).
MISFITS_JS = """() => {
  let panels = [...document.querySelectorAll(
    '[data-dock-region] .mantine-ScrollArea-viewport')];
  if (!panels.length)  // a phone: the controls are a sheet under the 3D view
    panels = [...document.querySelectorAll('.mantine-Paper-root .mantine-ScrollArea-viewport')]
      .filter(v => !v.closest('.mantine-Popover-dropdown'));
  panels = panels.filter(v => v.getBoundingClientRect().width >= 50);
  if (!panels.length) return [['no panel']];
  const out = [];
  const pinned = e => { for (let x = e; x; x = x.parentElement) {
    const p = getComputedStyle(x).position; if (p === 'sticky' || p === 'fixed') return true; }
    return false; };
  for (const v of panels) {
  const P = v.getBoundingClientRect();
  const texts = [];  // [element, box, pinned] of each text leaf in view
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
    if (r.bottom > P.top && r.top < P.bottom && e.tagName !== 'INPUT' && !e.closest('canvas'))
      texts.push([e, r, pinned(e)]);
  }
  // two texts of the panel over each other (by more than a 2 px antialiasing edge)
  for (let i = 0; i < texts.length; i++) for (let j = i + 1; j < texts.length; j++) {
    const [a, A, pa] = texts[i], [b, B, pb] = texts[j];
    if (pa !== pb || a.contains(b) || b.contains(a)) continue;
    const w = Math.min(A.right, B.right) - Math.max(A.left, B.left);
    const h = Math.min(A.bottom, B.bottom) - Math.max(A.top, B.top);
    if (w > 2 && h > 2) out.push(['overprinted', (a.textContent || '').trim().slice(0, 30),
                                  (b.textContent || '').trim().slice(0, 30)]);
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


#: the page sizes a lesson is laid out at: a projector, a laptop, a phone
SIZES = {"1920x1080": (1920, 1080), "1280x720": (1280, 720), "390x844": (390, 844)}


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("lesson", [lesson.name for lesson in LESSONS])
def test_nothing_is_clipped_or_overprinted_in_any_lesson_tab_mode_or_size(browser, lab,
                                                                          lesson, size):
    lab.switch(lesson)
    pg = browser.new_page(viewport=dict(zip(("width", "height"), SIZES[size], strict=True)))
    try:
        pg.goto(lab.url)
        box = pg.get_by_role("checkbox", name="Projector")
        box.wait_for(timeout=120_000)
        seen: dict[str, list] = {}
        for projector in (False, True):
            if box.is_checked() != projector:
                box.click()
            wait_for(lambda p=projector: box.is_checked() == p, 60, "the Projector switch")

            def sized(projector: bool = projector) -> bool:  # its mode's sheet has arrived
                return pg.evaluate("() => { const e = document.querySelector("
                                   "'.mantine-Paper-root label'); "
                                   "return e && getComputedStyle(e).fontSize; }"
                                   ) == TEXT_PX[projector]

            wait_for(sized, 60, f"the panel's text at {TEXT_PX[projector]}", every=0.5)
            # (a lesson without tabs, the IK-accuracy one, is its one panel)
            tabs = [t.strip() for t in pg.get_by_role("tab").all_inner_texts()] or [""]
            for tab in tabs:
                if tab:
                    pg.get_by_role("tab", name=tab, exact=True).first.click(timeout=60_000)
                # (a tab's panel lays out over a frame or two: give it a few looks)
                try:
                    wait_for(lambda: not pg.evaluate(MISFITS_JS), 5, f"the {tab} tab to fit",
                             every=0.5)
                except AssertionError:
                    seen[f"{'projector' if projector else 'normal'} {tab}"] = \
                        pg.evaluate(MISFITS_JS)
        assert not seen, seen
    finally:
        pg.close()


@pytest.fixture(scope="module")
def ik_lab():
    from armlab.app.lab.server import Lab, ServeOptions

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
