"""The lab in a real headless Chromium (Playwright driving Debian's /usr/bin/chromium).

What a person sees and does: the page loads without console errors, gets the plain
look (headless Chromium draws WebGL in software: armlab.app.page.look), the 3D view shows the arm,
moving the Kp slider changes the controller, Run fills the charts, one click on Step
shows its Tp and %OS beside the button, the CSV download
arrives with the recorded rows, the preset picker restores the
gains, dragging the hand with the mouse pulls the arm, and the E-STOP button
switches every servo off. Skipped, with a message, where chromium is not
installed (``apt-get install chromium``).
"""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from _helpers import chart_x_ranges, expected_console, view_png, wait_for

from armlab.app.page import camera
from armlab.app.page.plots import ANGLE_SPAN_DEG
from armlab.control.params import DEFAULT

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]


@pytest.fixture(scope="module")
def page(browser, lab, tmp_path_factory):
    console: list[tuple[str, str]] = []
    pg = browser.new_page(viewport={"width": 1440, "height": 900}, accept_downloads=True)
    pg.on("console", lambda m: console.append((m.type, m.text)))
    pg.on("pageerror", lambda e: console.append(("pageerror", str(e))))
    pg.goto(lab.url)
    pg.get_by_role("button", name="Run thesis line").wait_for()
    pg.console_log = console  # type: ignore[attr-defined]
    pg.shots = tmp_path_factory.mktemp("shots")  # type: ignore[attr-defined]
    yield pg
    pg.close()


def test_page_loads_without_console_errors(page):
    # a few frames of updates: 20 animation frames of the page
    page.evaluate("""() => new Promise(done => {
        let n = 0;
        const frame = () => (++n >= 20 ? done() : requestAnimationFrame(frame));
        requestAnimationFrame(frame);
    })""")
    errors = [(k, t) for k, t in page.console_log
              if k in ("error", "pageerror") and not expected_console(t)]
    assert errors == []
    assert page.get_by_role("button", name="E-STOP").is_visible()


def test_a_software_webgl_page_gets_the_plain_look(page, lab):
    """Headless Chromium draws WebGL with SwiftShader: the page names it and is drawn plain."""
    wait_for(lambda: any(lab.looks.is_plain(cid) for cid in lab.server.get_clients()), 180,
             "the page to name its WebGL renderer and get the plain look")
    (cid,) = [cid for cid in lab.server.get_clients() if lab.looks.is_plain(cid)]
    assert "swiftshader" in lab.looks.renderer(cid).lower()


def test_3d_view_renders_the_arm(page):
    from PIL import Image

    canvases = page.locator("canvas")
    sizes = [(i, canvases.nth(i).bounding_box()) for i in range(canvases.count())]
    i, box = max(((i, b) for i, b in sizes if b), key=lambda ib: ib[1]["width"] * ib[1]["height"])
    assert box["width"] > 500 and box["height"] > 800  # the view between the two panels
    shot = page.shots / "scene.png"

    def arm_pixels() -> tuple[float, int, int]:
        """(grey spread, orange pixels, blue pixels) of the 3D view now."""
        shot.write_bytes(view_png(page, box))
        img = np.asarray(Image.open(shot).convert("RGB")).astype(int)
        # The URDF's colours: the blue upper arm (38, 89, 191) and orange forearm
        # (242, 140, 38), lit and shaded, so look for pixels near those hues.
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        orange = (r > 150) & (g > 70) & (g < 170) & (b < 90)
        blue = (b > 120) & (r < 90) & (g < 140)
        return float(img.std()), int(orange.sum()), int(blue.sum())

    seen: list[tuple[float, int, int]] = []  # the meshes load in their own time

    def drawn() -> bool:
        seen.append(arm_pixels())
        spread, orange, blue = seen[-1]
        return spread > 10 and orange > 200 and blue > 200  # not blank; both links

    wait_for(drawn, 180, lambda: f"the arm's blue and orange links in the 3D view (grey "
             f"spread, orange, blue pixels: {seen[-3:]})", every=0.5)


def _labelled(page, label: str):  # noqa: ANN001, ANN202
    """The control that the <label for=...> reading ``label`` names."""
    target = page.locator("label", has_text=label).first.get_attribute("for")
    return page.locator(f"[id='{target}']")


def _slider(page, label: str):  # noqa: ANN001, ANN202
    """The thumb of the slider labelled ``label``."""
    return _labelled(page, label).locator("[role=slider]")


def test_moving_the_kp_slider_changes_the_controller(page, lab):
    loop = lab.lesson.rig.loop
    page.get_by_role("tab", name="Gains").click()
    thumb = _slider(page, "Kp (1/s²)")
    assert float(thumb.get_attribute("aria-valuenow")) == pytest.approx(DEFAULT.kp)
    thumb.focus()
    for _ in range(5):
        page.keyboard.press("ArrowRight")  # 5 steps of 0.1
    wait_for(lambda: loop.params.kp == pytest.approx(DEFAULT.kp + 0.5), 30, "Kp + 0.5 in the loop")
    # ... and by mouse: drag the thumb right; the loop follows the slider.
    box = thumb.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + 60, box["y"] + box["height"] / 2, steps=5)
    page.mouse.up()
    wait_for(lambda: loop.params.kp > DEFAULT.kp + 5.0, 30, "a larger Kp from the drag")
    shown = float(thumb.get_attribute("aria-valuenow"))
    wait_for(lambda: loop.params.kp == pytest.approx(shown), 30, "the loop at the shown Kp")
    page.get_by_role("tab", name="Run").click()


def _chart_series(page, title_start: str) -> list[list[float]] | None:  # noqa: ANN001
    return page.evaluate(
        """(t) => {
            const reg = (window.__viserTestpoints || {}).uplots || {};
            for (const {chart} of Object.values(reg)) {
                const title = chart.root.querySelector('.u-title');
                if (title && title.textContent.startsWith(t))
                    return chart.data.map(a => Array.from(a));
            }
            return null;
        }""", title_start)


def _y_fit(page, title_start: str) -> tuple[float, float, float, float] | None:  # noqa: ANN001
    """(y min shown, y max shown, smallest y, largest y of the data) of the chart whose
    title starts with ``title_start``; None before it has a y range."""
    r = page.evaluate(
        """(t) => {
            const reg = (window.__viserTestpoints || {}).uplots || {};
            for (const {chart} of Object.values(reg)) {
                const title = chart.root.querySelector('.u-title');
                if (!chart.root.isConnected || !title || !title.textContent.startsWith(t))
                    continue;
                const ys = chart.data.slice(1).flatMap(a => Array.from(a));
                if (chart.scales.y.min == null || !ys.length) return null;
                return [chart.scales.y.min, chart.scales.y.max, Math.min(...ys), Math.max(...ys)];
            }
            return null;
        }""", title_start)
    return None if r is None else tuple(r)


def _shown_widths(page) -> list[float]:  # noqa: ANN001
    """The x span each chart on the page displays, s (NaN: a chart with no x range yet)."""
    return [float("nan") if lo is None or hi is None else hi - lo
            for lo, hi, _, _ in chart_x_ranges(page)]


def test_run_fills_the_charts(page, lab):
    loop = lab.lesson.rig.loop
    # At rest the angle chart spans at least ANGLE_SPAN_DEG: the servo's 0.29° steps are a
    # ripple, not a full-height oscillation (an auto-scaled axis would span 0.29°).
    def resting() -> bool:
        fit = _y_fit(page, "Joint angle")
        return fit is not None and fit[1] - fit[0] >= ANGLE_SPAN_DEG - 1e-9 \
            and fit[0] <= fit[2] and fit[3] <= fit[1]

    wait_for(resting, 60, lambda: f"a resting angle chart of at least {ANGLE_SPAN_DEG}°, "
             f"shown: {_y_fit(page, 'Joint angle')}")
    lo, hi, y_lo, y_hi = _y_fit(page, "Joint angle")
    assert y_hi - y_lo < 0.25 * (hi - lo)  # at rest: the data fills a small part of it
    page.get_by_role("button", name="Run thesis line").click()
    wait_for(lambda: loop.status.trajectory is not None, 30, "the run to start")
    wait_for(lambda: loop.status.trajectory is None, 60, "the run to end")

    def sweep() -> float:
        data = _chart_series(page, "Joint angle")
        return float(np.ptp(data[1])) if data and len(data[0]) > 50 else 0.0

    wait_for(lambda: sweep() > 40.0, 60, "the elbow's sweep in the angle chart")
    # ... and the run's sweep fits the axis (re-pinned as it grew)
    def inside() -> bool:
        fit = _y_fit(page, "Joint angle")
        return fit is not None and fit[0] <= fit[2] and fit[3] <= fit[1]

    wait_for(inside, 60, lambda: f"the sweep inside the axis: {_y_fit(page, 'Joint angle')}")
    data = _chart_series(page, "Joint angle")
    assert data[0][0] == -10.0 and data[0][-1] == 0.0  # the last 10 s, now at 0
    # ... and the page shows all of it (not a zoomed slice), also after picking a joint.
    # (uPlot applies new data to its scales on its next animation frame: wait for it)
    wait_for(lambda: _shown_widths(page) == [pytest.approx(10.0)] * 4, 30, "full-width charts")
    page.get_by_role("button", name="θ1", exact=True).click()
    wait_for(lambda: (_chart_series(page, "Joint angle θ1") or [[]])[0][:1] == [-10.0], 60,
         "the θ1 charts")
    wait_for(lambda: _shown_widths(page) == [pytest.approx(10.0)] * 4, 30, "full-width θ1 charts")
    page.screenshot(path=str(page.shots / "after_run.png"))


def test_a_step_from_the_run_tab_shows_tp_and_overshoot_beside_its_button(page, lab):
    """The first minute: one click on the Run tab's Step, and its measured Tp and %OS
    appear right under the button, without another click."""
    loop = lab.lesson.rig.loop
    if not loop.status.active:  # a late loop on a loaded machine can trip the tracking fault
        page.get_by_role("button", name="Reset").click()
        wait_for(lambda: loop.status.active, 30, lambda: f"the arm held again: {loop.status}")
    step = page.get_by_role("button", name="Step", exact=True)
    step.click()
    figures = page.locator("p", has_text="Measured").filter(has_text="%OS")
    wait_for(lambda: figures.count() > 0 and "Tp" in figures.first.inner_text(), 120,
             lambda: "the step's Tp and %OS beside the Step button; the lab measured "
                     f"{lab.lesson.measured_pd}, said {lab.lesson.last_run_text!r}, "
                     f"the loop {loop.status.fault=} {loop.status.active=}")
    button, text = step.bounding_box(), figures.first.bounding_box()
    assert 0.0 <= text["y"] - (button["y"] + button["height"]) < 120.0, (button, text)
    assert text["width"] > 0 and text["height"] > 0


def test_csv_download_arrives_with_the_recorded_rows(page, lab, tmp_path):
    with page.expect_download() as info:
        page.get_by_role("button", name="Download the last run (CSV)").click()
    path = tmp_path / info.value.suggested_filename
    info.value.save_as(path)
    assert path.name.startswith("armlab-") and path.suffix == ".csv"
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# armlab recording")
    assert any(ln.startswith("# kp=") for ln in lines)
    rows = list(csv.reader(io.StringIO("\n".join(ln for ln in lines if not ln.startswith("#")))))
    cols = rows[0]
    assert cols[0] == "t_s" and "q_theta2_rad" in cols
    t = np.array([float(r[0]) for r in rows[1:]])
    assert len(t) > 70 and np.all(np.diff(t) > 0)
    assert np.median(np.diff(t)) == pytest.approx(0.016, abs=1e-6)


def _on_screen(page, lab, p_world: np.ndarray) -> tuple[float, float]:  # noqa: ANN001
    """Page pixel (x, y) where the 3D view draws the world point ``p_world`` (3,), m.

    The page's camera, as it reports it to the server (viser's OpenCV convention:
    +z looks forward, +y points down the image; ``fov`` is vertical), projected
    onto the largest canvas (the 3D view).
    """
    import viser.transforms as vtf

    (client,) = lab.server.get_clients().values()
    cam = client.camera
    rot = vtf.SO3(np.asarray(cam.wxyz)).as_matrix()  # world <- camera
    p = rot.T @ (np.asarray(p_world, dtype=float) - np.asarray(cam.position))
    canvases = page.locator("canvas")
    boxes = [canvases.nth(i).bounding_box() for i in range(canvases.count())]
    box = max((b for b in boxes if b), key=lambda b: b["width"] * b["height"])
    assert cam.aspect == pytest.approx(box["width"] / box["height"], rel=0.02)
    f = box["height"] / 2 / np.tan(cam.fov / 2)
    return (box["x"] + box["width"] / 2 + f * p[0] / p[2],
            box["y"] + box["height"] / 2 + f * p[1] / p[2])


def _back_to_the_default_gains(page, loop) -> None:  # noqa: ANN001
    """Pick the well-damped preset on the Gains tab (the Kp test left a large Kp), then
    Reset on the Run tab (torque on, the arm home)."""
    page.get_by_role("tab", name="Gains").click()
    _labelled(page, "Preset").click()
    page.get_by_role("option", name="well-damped default").click()
    wait_for(lambda: loop.params == DEFAULT, 30, "the default gains in the loop")
    page.get_by_role("tab", name="Run").click()
    page.get_by_role("button", name="Reset").click()
    wait_for(lambda: loop.status.torque_on and loop.status.fault is None
             and loop.status.trajectory is None, 30, "the arm reset")


@pytest.mark.timeout(600)  # up to three presses on a slow software-drawn page
def test_dragging_the_hand_with_the_mouse_pulls_the_arm(page, lab):
    lesson = lab.lesson
    loop, model = lesson.rig.loop, lesson.rig.model
    _back_to_the_default_gains(page, loop)

    def recent(seconds: float) -> np.ndarray:
        return loop.recorder.snapshot(seconds)["q"]

    def settled() -> bool:  # the arm at rest at home: under 2° of motion in 0.5 s (a loop
        q = recent(0.5)  # made late by a busy machine keeps a holding arm wobbling by ~1°)
        if len(q) < 10 or not np.all(np.isfinite(q)):
            return False
        return bool(np.all(np.ptp(q, axis=0) < np.radians(2.0)))

    wait_for(settled, 60, lambda: f"the arm to settle at home (moving "
             f"{np.degrees(np.ptp(recent(0.5), axis=0)).round(2)}° in 0.5 s; {loop.status})")
    q0 = recent(0.5).mean(axis=0)  # (the wobble averaged out, here and after the pull)
    tip = model.base_pose @ model.fk(q0)  # hand (grab sphere centre), world frame
    # Press on the hand's sphere and pull it 80 px to the left on the screen, then hold.
    # A press may miss on a loaded machine (the page's view moved after it reported its
    # camera), and the pull then orbits the view: let go, "Frame" the view again, wait
    # for the page to show it, and press again, as a person would.
    (client,) = lab.server.get_clients().values()
    tries = []
    for attempt in range(3):
        x, y = _on_screen(page, lab, tip[:3, 3])
        tries.append((round(x), round(y)))
        page.mouse.move(x, y)
        page.mouse.down()
        page.mouse.move(x - 80, y, steps=8)
        if attempt == 2:
            break  # the last press stays down for the wait below
        try:  # (a press that hit may take a slow page and server a while to report)
            wait_for(lambda: lesson._drag_anchor is not None, 30, "the spring")
            break
        except AssertionError:
            page.mouse.up()
            before = camera.last_framing.get(client)
            page.get_by_role("button", name="Frame").click()
            wait_for(lambda before=before: camera.shown(client, before) is not None, 60,
                     "the view framed again")
    wait_for(lambda: lesson._drag_anchor is not None, 60,
             lambda: f"the spring from the mouse drag (pressed at {tries})")
    anchor = lesson._drag_anchor
    p0 = model.fk(q0)[:3, 3]
    assert np.linalg.norm(anchor - p0) > 0.02  # the pointer went centimetres away
    t0 = loop.status.t
    wait_for(lambda: loop.status.t > t0 + 1.5, 30, "1.5 s of pulling")
    p1 = model.fk(recent(0.3).mean(axis=0))[:3, 3]
    pull = (anchor - p0) / np.linalg.norm(anchor - p0)
    assert float(pull @ (p1 - p0)) > 0.01  # the hand gave way more than 1 cm towards the pointer
    page.mouse.up()
    wait_for(lambda: lesson._drag_anchor is None, 30, "the spring to let go on release")


def test_estop_button_switches_every_servo_off(page, lab):
    loop, plant = lab.lesson.rig.loop, lab.lesson.rig.backend.plant
    # (On a loaded machine a late loop can trip the tracking fault during the drag: Reset.)
    page.get_by_role("button", name="Reset").click()
    wait_for(lambda: all(r.torque_enable for r in plant.reports()), 30, "torque on")
    page.get_by_role("button", name="E-STOP").click()
    wait_for(lambda: loop.status.estopped and not loop.status.torque_on, 30, "the e-stop")
    assert not any(r.torque_enable for r in plant.reports())
    shown = page.get_by_text("E-STOPPED")
    wait_for(lambda: shown.count() > 0 and shown.first.is_visible(), 120,  # the page says so
             lambda: f"the page to say E-STOPPED; the lab's status says "
                     f"{lab.lesson.status.content[:300]!r}, frames {lab.lesson.publisher.stats}")
    page.get_by_role("button", name="Reset").click()
    wait_for(lambda: loop.status.torque_on and not loop.status.estopped, 30, "torque back on")
