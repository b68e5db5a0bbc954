"""E-STOP first (armlab.app.page.stop_first), in a real headless Chromium.

At 1920x1080: the first Tab after the page loads focuses E-STOP, which is at least
44 px tall, and Esc presses it wherever the focus is. On a 390x844 phone: the robot is
framed in the 3D view above the controls (not under them), E-STOP is pinned between the
two, and after the charts are opened and the controls scrolled to their end E-STOP is
still in view, uncovered, and a tap on it stops the arm.
"""

from __future__ import annotations

import pytest
from _helpers import new_page_client as _client
from _helpers import wait_for
from test_browser_framing import _spans

from armlab.app.page import camera

pytestmark = [pytest.mark.browser, pytest.mark.timeout(400)]

#: The rectangle of an element, [x, y, width, height] in CSS px.
RECT_JS = "e => { const r = e.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; }"
#: True when the middle of the E-STOP button shows the button (nothing lies over it).
UNCOVERED_JS = """() => { const b = document.querySelector('[data-armlab=estop]');
  const r = b.getBoundingClientRect();
  return b.contains(document.elementFromPoint(r.x + r.width / 2, r.y + r.height / 2)); }"""


def _marked(pg, *names: str) -> bool:
    """The page's script has marked every one of ``names`` (``data-armlab``)."""
    return all(pg.locator(f"[data-armlab={n}]").count() == 1 for n in names)


def _focused_label(pg) -> str:
    return pg.evaluate("() => (document.activeElement.textContent || '').trim()")


def _estop_then_reset(lab, pg, press) -> None:
    """``press()`` must E-STOP the lesson's arm (the page says so); Reset brings it back."""
    loop = lab.lesson.rig.loop
    pg.get_by_role("button", name="Reset").click()
    wait_for(lambda: loop.status.torque_on and not loop.status.estopped, 60, "torque on")
    press()
    wait_for(lambda: loop.status.estopped and not loop.status.torque_on, 60, "the e-stop")
    pg.get_by_text("E-STOPPED").first.wait_for()
    pg.get_by_role("button", name="Reset").click()
    wait_for(lambda: loop.status.torque_on and not loop.status.estopped, 60, "torque back on")


def test_tab_reaches_estop_first_and_esc_presses_it(browser, lab):
    assert lab.lesson_name == "compliance"
    pg = browser.new_page(viewport={"width": 1920, "height": 1080})
    try:
        pg.goto(lab.url)
        pg.get_by_role("button", name="Run thesis line").wait_for(timeout=120_000)
        wait_for(lambda: _marked(pg, "estop"), 60, "the page's script to mark E-STOP")
        assert pg.locator("[data-armlab=estop]").evaluate(RECT_JS)[3] >= 44.0
        pg.keyboard.press("Tab")
        assert _focused_label(pg) == "E-STOP"
        pg.keyboard.press("Tab")  # the focus moves on; Esc still stops
        assert _focused_label(pg) != "E-STOP"
        _estop_then_reset(lab, pg, lambda: pg.keyboard.press("Escape"))
    finally:
        pg.close()


def test_on_a_phone_the_robot_is_above_the_controls_and_estop_stays_in_view(browser, lab):
    assert lab.lesson_name == "compliance"
    known = set(lab.server.get_clients())
    pg = browser.new_page(viewport={"width": 390, "height": 844}, has_touch=True)
    try:
        pg.goto(lab.url)
        pg.get_by_role("button", name="Run thesis line").wait_for(timeout=120_000)
        wait_for(lambda: _marked(pg, "estop", "estop-row", "sheet", "view"), 60,
                 "the page's script to mark E-STOP, the control sheet and the 3D view")
        view = pg.locator("[data-armlab=view]").evaluate(RECT_JS)
        row = pg.locator("[data-armlab=estop-row]").evaluate(RECT_JS)
        sheet = pg.locator("[data-armlab=sheet]").evaluate(RECT_JS)
        assert view[1] + view[3] <= row[1] + 1.0  # the 3D view ends where E-STOP starts
        assert row[1] + row[3] <= sheet[1] + 1.0  # and E-STOP above the controls
        assert sheet[1] + sheet[3] >= 844 - 1.0 and sheet[2] >= 390 - 1.0
        assert pg.locator("[data-armlab=estop]").evaluate(RECT_JS)[3] >= 44.0
        # the robot framed in that view: the camera was fitted to the view's shape
        wait_for(lambda: _client(lab, known) is not None, 60, "the page to connect")
        client = _client(lab, known)
        aspect = view[2] / view[3]
        seen: list[camera.Framing] = []

        def framed_for_view() -> bool:
            framing = camera.shown(client)
            if framing is None or abs(framing.aspect / aspect - 1.0) > 0.05:
                return False
            seen[:] = [framing]
            return True

        wait_for(framed_for_view, 90,
                 "the page to show the view framed for the space above the controls")
        span, _, reach = _spans(seen[0], camera._views[lab.server.scene].up)
        assert span >= 0.4 and reach <= 1.0 + 1e-6, (span, reach)
        # open the charts and scroll the controls to their end: E-STOP stays, uncovered
        pg.get_by_text("Live charts", exact=True).first.click()
        scroller = pg.locator("[data-armlab=sheet] .mantine-ScrollArea-viewport").first
        wait_for(lambda: pg.locator(".u-title").count() > 0, 60, "the charts to draw")

        def last_chart_in_view() -> bool:  # (the opened section grows while it unfolds)
            scroller.evaluate("e => { e.scrollTop = e.scrollHeight; }")
            chart = pg.locator(".u-title").last.evaluate(RECT_JS)
            return sheet[1] <= chart[1] and chart[1] + chart[3] <= 844

        wait_for(last_chart_in_view, 60, "the last chart to scroll into view", every=0.5)
        estop = pg.locator("[data-armlab=estop]").evaluate(RECT_JS)
        assert 0 <= estop[1] and estop[1] + estop[3] <= 844, estop
        assert pg.evaluate(UNCOVERED_JS)
        _estop_then_reset(lab, pg, lambda: pg.locator("[data-armlab=estop]").tap())
    finally:
        pg.close()


@pytest.mark.parametrize("size", [(1280, 720), (1600, 600)])
def test_on_a_desktop_estop_stays_in_view_when_the_controls_scroll(browser, lab, size):
    """The Gains tab is longer than the panel: scrolled to its end, E-STOP is still on
    screen, uncovered, and a click on it stops the arm."""
    assert lab.lesson_name == "compliance"
    width, height = size
    pg = browser.new_page(viewport={"width": width, "height": height})
    try:
        pg.goto(lab.url)
        pg.get_by_role("button", name="Run thesis line").wait_for(timeout=120_000)
        wait_for(lambda: _marked(pg, "estop", "estop-row"), 60, "the page's script to mark E-STOP")
        pg.get_by_role("tab", name="Gains").click()
        scroller = pg.locator("[data-armlab=estop-row]").evaluate_handle(
            "e => e.closest('.mantine-ScrollArea-viewport')")

        def scrolled_far() -> bool:  # (the tab's fields may still be arriving)
            return bool(scroller.evaluate(
                "s => { if (!s) return false; s.scrollTop = s.scrollHeight; "
                "return s.scrollTop > 100; }"))

        wait_for(scrolled_far, 60, "the controls to scroll", every=0.5)
        estop = pg.locator("[data-armlab=estop]").evaluate(RECT_JS)
        assert 0 <= estop[1] and estop[1] + estop[3] <= height, estop
        assert pg.evaluate(UNCOVERED_JS)
        loop = lab.lesson.rig.loop
        pg.locator("[data-armlab=estop]").click()  # from where the Gains tab is scrolled
        wait_for(lambda: loop.status.estopped and not loop.status.torque_on, 60, "the e-stop")
        pg.get_by_role("tab", name="Run").click()
        pg.get_by_role("button", name="Reset").click()
        wait_for(lambda: loop.status.torque_on and not loop.status.estopped, 60, "torque on")
    finally:
        pg.close()
