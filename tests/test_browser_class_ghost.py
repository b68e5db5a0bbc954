"""A student's ghost on the presenter's page, in real Chromium (armlab/app/classroom/room.py,
``Room.show_ghost``): after **Show** the ghost's label, the student's name, is on screen
inside the presenter's 3D view, framed with the shared arm. The student is a headless
page (armlab/app/testing/wsclient.py): only the presenter's page is drawn here.

Set ``ARMLAB_GHOST_PNG`` to a path to keep the picture of the presenter's 3D view.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest
from _helpers import ACTION_TIMEOUT_MS, new_page_client, project, view_png, wait_for
from PIL import Image

from armlab.app.classroom.room import GHOST_LABEL
from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.page import camera
from armlab.app.testing.wsclient import HeadlessClient
from armlab.app.viser_ext.handles import scene_nodes

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.timeout(900)]

#: s to wait for what a page did to reach the server (software WebGL on a loaded 2-core
#: machine draws a frame in seconds)
PAGE_S = ACTION_TIMEOUT_MS / 1000


def _pick(page, label: str, option: str) -> None:  # noqa: ANN001
    page.get_by_label(label).first.click()
    page.get_by_role("option", name=option, exact=True).click()


def _on_screen(client, point: np.ndarray, view: dict) -> tuple[float, float]:  # noqa: ANN001
    """Where ``point`` (3,) world lies in the page's 3D view ``view`` (its box, CSS px),
    px from the view's top left, by the camera the page reported."""
    cam = client.camera
    x, y, depth = project(point[None, :], cam.position, cam.look_at, cam.up_direction,
                          cam.fov, cam.aspect)
    assert depth[0] > 0
    return (float(x[0]) + 1.0) / 2.0 * view["width"], (1.0 - float(y[0])) / 2.0 * view["height"]


def _shot(page, view) -> np.ndarray:  # noqa: ANN001
    return np.asarray(Image.open(io.BytesIO(view_png(page, view))).convert("L")).astype(int)


def _label_box(page, view, label, at) -> tuple[int, int, int, int]:  # noqa: ANN001
    """(left, top, right, bottom) px in the 3D view of the pixels that change when the
    scene label ``label`` is hidden, searched round ``at`` (px) where its anchor (bottom
    centre) is drawn. (A holding arm may tremble by its servos' 0.29° steps, more on a
    busy machine: only the search window must hold still, and a pixel counts as the
    label's only where the hidden picture differs from both pictures with it.)"""
    h, w = _shot(page, view).shape
    x0, x1 = max(0, int(at[0]) - 400), min(w, int(at[0]) + 400)
    y0, y1 = max(0, int(at[1]) - 150), min(h, int(at[1]) + 20)
    shots: list[np.ndarray] = []

    def steady() -> bool:  # two pictures of the window agree but for a few pixels
        shots[:] = [_shot(page, view)[y0:y1, x0:x1], _shot(page, view)[y0:y1, x0:x1]]
        return int(np.count_nonzero(np.abs(shots[0] - shots[1]) > 40)) < 30

    wait_for(steady, PAGE_S, "a still picture round the label", every=0.5)
    found: list[tuple[int, int, int, int]] = []
    label.visible = False
    try:
        def gone() -> bool:
            now = _shot(page, view)[y0:y1, x0:x1]
            diff = (np.abs(now - shots[0]) > 40) & (np.abs(now - shots[1]) > 40)
            ys, xs = np.nonzero(diff)
            if len(xs) < 30:
                return False
            found[:] = [(x0 + int(xs.min()), y0 + int(ys.min()),
                         x0 + int(xs.max()), y0 + int(ys.max()))]
            return True

        wait_for(gone, PAGE_S, "the label to disappear", every=0.5)
    finally:
        label.visible = True
    return found[0]


def test_show_puts_the_students_named_ghost_in_the_presenters_view(browser):
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        before = set(lab.server.get_clients())
        with HeadlessClient(lab.local_url.replace("http://", "ws://")).connect() as ayu:
            ayu.wait_for(lambda: ayu.shows("Your name") and ayu.shows("View"), PAGE_S,
                         "the student's fields")
            (a_id,) = set(lab.server.get_clients()) - before
            ayu.set_value("Your name", "Ayu")
            ayu.set_value("View", "My arm")
            wait_for(lambda: lab.room.private_lesson(a_id) is not None
                     and lab.roles.name(a_id) == "Ayu", PAGE_S, "Ayu's own arm")

            known = set(lab.server.get_clients())
            context = browser.new_context(viewport={"width": 1920, "height": 1080})
            page = context.new_page()
            try:
                page.goto(f"{lab.local_url}&presenter={lab.roles.passcode}")
                page.get_by_text("You now change the shared arm").first.wait_for()
                wait_for(lambda: new_page_client(lab, known) is not None, PAGE_S,
                         "the presenter's page")
                client = new_page_client(lab, known)
                _pick(page, "Student", f"Ayu (#{a_id})")
                page.get_by_role("button", name="Show", exact=True).click()
                page.get_by_role("button", name="Hide", exact=True).wait_for()
                wait_for(lambda: GHOST_LABEL in scene_nodes(client.scene), PAGE_S,
                         "the ghost's label on the presenter's page")

                # the camera the page shows frames the shared arm and the ghost with its
                # label, for the page's own 3D view
                wait_for(lambda: camera.shown(client) is not None
                         and len(camera.shown(client).points)
                         == len(camera.page_framing(client)[1]), PAGE_S,
                         lambda: f"the page on its framing with the ghost; "
                                 f"{camera.last_framing.get(client)}")
                framing = camera.shown(client)
                up = camera._views[lab.server.scene].up
                x, y, _ = project(framing.points, framing.position, framing.look_at, up,
                                  framing.fov, framing.aspect)
                assert max(np.abs(x).max(), np.abs(y).max()) <= 1.0 + 1e-6
                assert len(camera.node_points(client.scene, (GHOST_LABEL,))) == 1

                # and the label is drawn inside the 3D view, whole: the pixels that change
                # when it is hidden, round where the page's own camera puts it
                view = page.locator("canvas").first.bounding_box()
                labels = scene_nodes(client.scene)
                assert labels[GHOST_LABEL].text == "Ayu's arm"
                at = _on_screen(client, camera.node_points(client.scene, (GHOST_LABEL,))[0],
                                view)
                assert 0.0 <= at[0] <= view["width"] and 0.0 <= at[1] <= view["height"], at
                box = _label_box(page, view, labels[GHOST_LABEL], at)
                assert box[0] > 0 and box[1] > 0, box  # clear of the view's left and top
                assert box[2] < view["width"] - 1 and box[3] < view["height"] - 1, box
                assert box[2] - box[0] >= 40 and box[3] - box[1] >= 10, box  # text, not a dot
                png = view_png(page, view)
                keep = os.environ.get("ARMLAB_GHOST_PNG")
                if keep:
                    Path(keep).write_bytes(png)
            finally:
                context.close()
