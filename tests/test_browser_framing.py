"""The robot is the picture, in a real headless Chromium at a projector's 1920x1080 and
1280x720: every lesson's camera frames its robot (the framed scene nodes, projected
with the camera the page itself reports, once the lab has framed for the shape of the
3D view the page lays out) over at least 40 % of the 3D view's height, or of its width
where the view is narrower than the robot (at 1280x720, between the docked charts and
controls, the view is taller than wide), and inside it; after the user orbits, "Frame"
brings that view back.
"""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import new_page_client as _client
from _helpers import project, wait_for

from armlab.app.lessons.catalog import all_lessons
from armlab.app.page import camera

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

SIZES = ((1920, 1080), (1280, 720))


def _spans(framing: camera.Framing, up) -> tuple[float, float, float]:
    """(half the vertical and half the horizontal span of the framed points in the view
    the page showed them in (:func:`armlab.app.page.camera.shown`: its camera and its
    shape), as fractions of the view's height and width; the largest |x| or |y|, 1 at the
    view's edges)."""
    x, y, _ = project(framing.points, framing.position, framing.look_at, up, framing.fov,
                      framing.aspect)
    return (float(y.max() - y.min()) / 2.0, float(x.max() - x.min()) / 2.0,
            float(max(np.abs(x).max(), np.abs(y).max())))


def _view_aspect(pg) -> float:
    """Width / height of the page's 3D view as the page lays it out."""
    box = pg.locator("canvas").first.bounding_box()
    return box["width"] / box["height"]


def _framed_for_the_view(client, pg, before: camera.Framing | None) -> camera.Framing | None:
    """The framing made since ``before`` for the page's 3D view's shape, once the page shows
    it (the page reports its view's shape after it lays out its panels); else None."""
    shown = camera.shown(client, before)
    if shown is None or abs(shown.aspect / _view_aspect(pg) - 1.0) > camera.RESHAPE:
        return None
    return shown


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
            seen: list[camera.Framing] = []  # (the page may report its view again at once)

            def framed(before=before, seen=seen) -> bool:
                shown = _framed_for_the_view(client, pg, before)
                seen += [shown] if shown is not None else []
                return shown is not None

            wait_for(framed, 90, lambda name=name: f"{name}: the page to show a view framed "
                                                   f"for its shape ({_view_aspect(pg):.3f})")
            framing = seen[-1]
            up = camera._views[lab.server.scene].up
            height, width, reach = _spans(framing, up)
            # the robot fills the view's height, or its width where that is what limits it
            assert max(height, width) >= 0.4, (name, size, height, width, framing.aspect)
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
