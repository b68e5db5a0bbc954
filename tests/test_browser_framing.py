"""The robot is the picture, in a real headless Chromium at a projector's 1920x1080 and
1280x720: every lesson's camera frames its robot (the framed scene nodes, projected
with the camera and canvas the page itself reports) over at least 40 % of the 3D view's
height and inside it; after the user orbits, "Frame" brings that view back.
"""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import new_page_client as _client
from _helpers import project, wait_for

from armlab.app.lessons import all_lessons
from armlab.app.page import camera

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

SIZES = ((1920, 1080), (1280, 720))


def _height_span(client, framing: camera.Framing, up) -> tuple[float, float]:
    """(half the vertical span of the framed points in the page's view, as a fraction of
    the view's height; the largest |x| or |y|, 1 at the view's edges)."""
    cam = client.camera
    x, y, _ = project(framing.points, cam.position, cam.look_at, up, cam.fov, cam.aspect)
    return float(y.max() - y.min()) / 2.0, float(max(np.abs(x).max(), np.abs(y).max()))


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_every_lesson_frames_its_robot_and_frame_restores_it(browser, lab, size):
    width, height = size
    first = lab.lesson_name
    known = set(lab.server.get_clients())
    pg = browser.new_page(viewport={"width": width, "height": height})
    try:
        pg.goto(lab.url)
        pg.locator("canvas").first.wait_for()
        wait_for(lambda: _client(lab, known) is not None, 60, "the page to connect")
        client = _client(lab, known)
        framing = None
        for name in sorted(all_lessons()):
            before = camera.last_framing.get(client)
            lab.switch(name)
            wait_for(lambda before=before: camera.shown(client, before) is not None, 90,
                     f"{name}: the page to show its framed view")
            framing = camera.shown(client)
            up = camera._views[lab.server.scene].up
            span, reach = _height_span(client, framing, up)
            assert span >= 0.4, (name, size, span, client.camera.aspect)
            assert reach <= 1.0 + 1e-6, (name, size, reach)
        # orbit with the mouse, then "Frame"
        box = pg.locator("canvas").first.bounding_box()
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        pg.mouse.move(cx, cy)
        pg.mouse.down()
        pg.mouse.move(cx + 200, cy + 80, steps=10)
        pg.mouse.up()
        wait_for(lambda: camera.shown(client) is None, 60, "the orbit to move the camera")
        pg.get_by_role("button", name="Frame").click()
        wait_for(lambda: camera.shown(client, framing) is not None, 60,
                 "Frame to bring the view back")
    finally:
        pg.close()
        lab.switch(first)
