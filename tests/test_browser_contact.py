"""The Contact tab in a real headless Chromium: once the hand meets the wall, the chart of
the contact force shows the wall's force as the control loop recorded it (``f_contact``,
the plant's ground truth) beside the lab's sensorless estimate of it from τ_ext (eq.
2.21–2.23) and the disturbance and reaction-torque observers' (eq. 2.36, 2.37), with a
readable legend (a screenshot is kept in pytest's tmp dir). Skipped, with a message,
where chromium is not installed.
"""

from __future__ import annotations

import math

import pytest
from _helpers import expected_console, wait_for

pytestmark = [pytest.mark.browser, pytest.mark.timeout(400)]

TITLE = "Contact force along the wall's normal"


def _series(page) -> list[list[float | None]] | None:  # noqa: ANN001
    """The contact chart's data on the page ([t, wall, τ_ext, DOB, RTOB]); None before it
    is drawn."""
    return page.evaluate(
        """(t) => {
            const reg = (window.__viserTestpoints || {}).uplots || {};
            for (const {chart} of Object.values(reg)) {
                const title = chart.root.querySelector('.u-title');
                if (chart.root.isConnected && title && title.textContent.startsWith(t))
                    return chart.data.map(a => Array.from(a));
            }
            return null;
        }""", TITLE)


def _finite(values: list[float | None]) -> list[float]:
    return [v for v in values if v is not None and math.isfinite(v)]


def test_the_contact_chart_shows_the_recorded_force_beside_the_estimates(browser, lab,
                                                                          tmp_path):
    console: list[tuple[str, str]] = []
    page = browser.new_page(viewport={"width": 1440, "height": 900})
    page.on("console", lambda m: console.append((m.type, m.text)))
    page.on("pageerror", lambda e: console.append(("pageerror", str(e))))
    page.goto(lab.url)
    page.get_by_role("button", name="Run thesis line").wait_for()
    lesson = lab.lesson
    wait_for(lambda: lesson.rig.loop.status.active, 60, "the arm holding")
    page.get_by_role("tab", name="Contact").click()
    page.get_by_role("checkbox", name="Wall").click()
    wait_for(lambda: lesson.contact.nodes()[0] is not None, 60, "the wall placed")
    page.get_by_role("button", name="Run into the wall").click()
    wait_for(lambda: lesson.contact.figures() is not None, 180, "the run into the wall")
    touched = lesson.contact.figures()
    assert touched["touched"], touched

    def drawn() -> bool:
        data = _series(page)
        return data is not None and max(_finite(data[1]), default=0.0) > 1.0 \
            and all(max(_finite(d), default=0.0) > 0.5 for d in data[2:])

    wait_for(drawn, 120, "the contact chart with the wall's force and the three estimates")
    t, wall, estimate, dob, rtob = _series(page)
    # the recorded force: the loop's record (every period, thinned), never negative
    assert all(v >= 0.0 for v in _finite(wall))
    snap = lesson.rig.loop.recorder.snapshot(10.0)
    recorded = snap["f_contact"][snap["f_contact"] == snap["f_contact"]]
    assert max(_finite(wall)) <= float(recorded.max()) + 1e-6
    # the estimate reads the press with its sign (the compliance law estimates τ_ext)
    assert max(_finite(estimate)) > 0.0
    # the observers read the press too, each its own line (not the wall's, not τ_ext's)
    for line in (dob, rtob):
        assert max(_finite(line)) > 0.5 and line != wall and line != estimate
    legend = page.evaluate(
        """(t) => {
            const reg = (window.__viserTestpoints || {}).uplots || {};
            for (const {chart} of Object.values(reg)) {
                const title = chart.root.querySelector('.u-title');
                if (chart.root.isConnected && title && title.textContent.startsWith(t))
                    return chart.series.slice(1).map(s => s.label);
            }
            return null;
        }""", TITLE)
    assert legend == ["wall (ground truth)", "estimate from τ_ext",
                      "DOB (eq. 2.36), change from rest", "RTOB (eq. 2.37)"]
    # the legend's four entries sit inside the chart's box, none clipped
    boxes = page.evaluate(
        """(t) => {
            const reg = (window.__viserTestpoints || {}).uplots || {};
            for (const {chart} of Object.values(reg)) {
                const title = chart.root.querySelector('.u-title');
                if (!(chart.root.isConnected && title && title.textContent.startsWith(t)))
                    continue;
                const r = chart.root.getBoundingClientRect();
                return {root: [r.left, r.right],
                        items: [...chart.root.querySelectorAll('.u-legend .u-series')]
                            .filter(e => !e.textContent.startsWith('t − now'))
                            .map(e => { const b = e.getBoundingClientRect();
                                        return [b.left, b.right, b.width, b.top]; })};
            }
            return null;
        }""", TITLE)
    assert len(boxes["items"]) == 4, boxes
    for left, right, width, _ in boxes["items"]:
        assert width > 0 and left >= boxes["root"][0] - 1 and right <= boxes["root"][1] + 1, \
            boxes
    page.locator(".u-title", has_text=TITLE).scroll_into_view_if_needed()
    page.screenshot(path=str(tmp_path / "contact_chart.png"))
    print("screenshot:", tmp_path / "contact_chart.png")
    errors = [(k, m) for k, m in console if k in ("error", "pageerror")
              and not expected_console(m)]
    assert errors == []
    page.get_by_role("checkbox", name="Wall").click()
    wait_for(lambda: lesson.contact.nodes()[0] is None, 60, "the wall gone")
    page.close()


def test_pd_and_compliance_side_by_side_is_a_table_inside_the_panel(browser, lab, tmp_path):
    """Compare PD and compliance, pressed in Chromium at a 720p projector's size: the
    table of the two runs appears with its figures, each row whole inside the panel
    (nothing clipped), PD's steady force a dash (it has none)."""
    page = browser.new_page(viewport={"width": 1280, "height": 720})
    try:
        page.goto(lab.url)
        page.get_by_role("button", name="Run thesis line").wait_for()
        page.get_by_role("tab", name="Contact").click()
        page.get_by_role("button", name="Compare PD and compliance").click()
        table = page.locator("table", has_text="peak force")
        table.wait_for(timeout=240_000)
        table.scroll_into_view_if_needed()
        rows = table.locator("tr")
        texts = [rows.nth(i).inner_text() for i in range(rows.count())]
        assert any(t.startswith("peak force") and t.count("N") == 2 for t in texts), texts
        assert any(t.startswith("steady force") and "—" in t for t in texts), texts
        assert any(t.startswith("torque off") and "yes" in t for t in texts), texts
        # the markdown's own box (what overflowed it would be cut off), within the page
        panel = page.evaluate("""(el) => {
            const b = el.parentElement.getBoundingClientRect();
            return [Math.max(b.left, 0), Math.min(b.right, window.innerWidth)]; }""",
                              table.element_handle())
        for i in range(rows.count()):
            box = rows.nth(i).bounding_box()
            assert box is not None and box["width"] > 0
            assert box["x"] >= panel[0] - 1 and box["x"] + box["width"] <= panel[1] + 1, \
                (texts[i], box, panel)
        page.screenshot(path=str(tmp_path / "contact_compare.png"))
        print("screenshot:", tmp_path / "contact_compare.png")
    finally:
        page.close()
