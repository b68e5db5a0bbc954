"""Collapsed side panels in a real headless Chromium: a side collapsed with one click
(viser's "Collapse panel area") frames the robot again for the space gained, stays
collapsed after a reload of the page (armlab.app.page.panels keeps it in the browser), and a lesson
switch with a side collapsed frames the new lesson for the view the page has.
"""

from __future__ import annotations

import json

import pytest
from _helpers import new_page_client, wait_for, wait_look_settled

from armlab.app.page import camera
from armlab.app.page.panels import PANELS_KEY
from armlab.app.viser_ext.page_js import LOCAL_STORAGE_PREFIX

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]

#: s a page may take to show a new framing: a page drawing in software on a loaded
#: machine draws a frame every few seconds, and handles the server's messages between them
FRAMED_S = 240.0

RAILED_JS = """(edge) =>
  !!document.querySelector(`[data-dock-region="${edge}"] [data-dock-rail-root]`)"""


def _railed(pg, edge: str) -> bool:
    return bool(pg.evaluate(RAILED_JS, edge))


def _stored(pg) -> list[str]:
    raw = pg.evaluate("(k) => localStorage.getItem(k)", LOCAL_STORAGE_PREFIX + PANELS_KEY)
    return json.loads(raw) if raw else []


def _view_aspect(pg) -> float:
    """Width / height of the 3D view as the page draws it now."""
    box = pg.locator("canvas").first.bounding_box()
    return box["width"] / box["height"]


def _framed_as_drawn(client, pg, what: str, *, since=None, wider_than: float = 0.0
                     ) -> camera.Framing:
    """Wait until the page shows a framing (newer than ``since``; for a view wider than
    ``wider_than`` by more than armlab.app.page.camera.RESHAPE) made for its 3D view as the page
    draws it now (the canvas's box, not a shape the page had while its panels were still
    docking); return it."""
    def framed() -> bool:
        f = camera.shown(client, since)
        return (f is not None and abs(f.aspect / _view_aspect(pg) - 1.0) <= camera.RESHAPE
                and f.aspect > wider_than * (1.0 + camera.RESHAPE))

    def seen() -> str:
        last = camera.last_framing.get(client)
        return (f"{what} (the page draws {_view_aspect(pg):.3f}, reported "
                f"{client.camera.aspect:.3f}; last framing for "
                f"{None if last is None else round(last.aspect, 3)}; wanted wider than "
                f"{wider_than:.3f})")

    wait_for(framed, FRAMED_S, seen)
    return camera.shown(client)


def _docked(pg) -> bool:
    """Both sides are docked (collapsed or not): the page's layout is complete."""
    return all(pg.locator(f'[data-dock-region="{edge}"]').count() > 0
               for edge in ("left", "right"))


def test_a_collapsed_side_is_kept_on_reload_and_the_robot_reframed(browser, lab):
    first = lab.lesson_name
    known = set(lab.server.get_clients())
    pg = browser.new_page(viewport={"width": 1280, "height": 720})
    try:
        pg.goto(lab.url)
        wait_for(lambda: new_page_client(lab, known) is not None, 60, "the page to connect")
        client = new_page_client(lab, known)
        wait_look_settled(lab, known)
        wait_for(lambda: _docked(pg), FRAMED_S, "both sides docked")
        wide = _framed_as_drawn(client, pg, "the robot framed between both sides")
        # one click collapses the charts' side; the view is wider, the robot framed for it
        pg.locator('[data-dock-region-collapse="left"]').click()
        wait_for(lambda: _railed(pg, "left"), 60, "the left side to collapse")
        _framed_as_drawn(client, pg, "the robot framed for the wider view",
                         wider_than=wide.aspect)
        wait_for(lambda: _stored(pg) == ["left"], 60, "the page to note the collapsed side")
        # a reload: the side collapses again, and the new page frames for that view
        known = set(lab.server.get_clients())
        pg.reload()
        wait_for(lambda: new_page_client(lab, known) is not None, 60, "the reloaded page")
        client = new_page_client(lab, known)
        wait_for(lambda: _docked(pg) and _railed(pg, "left"), FRAMED_S,
                 "the left side collapsed after the reload")
        again = _framed_as_drawn(client, pg, "the reloaded page framed with the side shut",
                                 wider_than=wide.aspect)
        assert _railed(pg, "left") and not _railed(pg, "right")
        # the controls' side collapsed too, then another lesson: framed for that view
        pg.locator('[data-dock-region-collapse="right"]').click()
        wait_for(lambda: _railed(pg, "right"), 60, "the right side to collapse")
        widest = _framed_as_drawn(client, pg, "the robot framed for the widest view",
                                  wider_than=again.aspect)
        lab.switch("hand")
        _framed_as_drawn(client, pg, "the next lesson framed for the view", since=widest)
        assert _railed(pg, "right")
    finally:
        pg.close()
        lab.switch(first)
