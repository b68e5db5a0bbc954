"""Collapsed side panels in a real headless Chromium: a side collapsed with one click
(viser's "Collapse panel area") frames the robot again for the space gained, stays
collapsed after a reload of the page (app.panels keeps it in the browser), and a lesson
switch with a side collapsed frames the new lesson for the view the page has.
"""

from __future__ import annotations

import json

import pytest
from _helpers import new_page_client, wait_for, wait_look_settled

from app import camera
from app.page_js import LOCAL_STORAGE_PREFIX
from app.panels import PANELS_KEY

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


def _framed_for_its_view(client, since=None) -> camera.Framing:
    """Wait until the page shows a framing (newer than ``since``) made for the shape its
    3D view has now; return it."""
    wait_for(lambda: camera.shown(client, since) is not None, FRAMED_S,
             "the page to show the robot framed for its view")
    return camera.shown(client)


def _framed_wider_than(client, aspect: float, what: str) -> camera.Framing:
    """Wait until the page shows the robot framed for a view wider than ``aspect`` (by
    more than app.camera.RESHAPE); return that framing."""
    def wider() -> bool:
        f = camera.shown(client)
        return f is not None and f.aspect > aspect * (1.0 + camera.RESHAPE)

    wait_for(wider, FRAMED_S, what)
    return camera.shown(client)


def test_a_collapsed_side_is_kept_on_reload_and_the_robot_reframed(browser, lab):
    first = lab.lesson_name
    known = set(lab.server.get_clients())
    pg = browser.new_page(viewport={"width": 1280, "height": 720})
    try:
        pg.goto(lab.url)
        wait_for(lambda: new_page_client(lab, known) is not None, 60, "the page to connect")
        client = new_page_client(lab, known)
        wait_look_settled(lab, known)
        pg.locator('[data-dock-region-collapse="left"]').wait_for(timeout=120_000)
        wide = _framed_for_its_view(client)
        # one click collapses the charts' side; the view is wider, the robot framed for it
        pg.locator('[data-dock-region-collapse="left"]').click()
        wait_for(lambda: _railed(pg, "left"), 60, "the left side to collapse")
        _framed_wider_than(client, wide.aspect, "the robot framed for the wider view")
        wait_for(lambda: _stored(pg) == ["left"], 60, "the page to note the collapsed side")
        # a reload: the side collapses again, and the new page frames for that view
        known = set(lab.server.get_clients())
        pg.reload()
        wait_for(lambda: new_page_client(lab, known) is not None, 60, "the reloaded page")
        client = new_page_client(lab, known)
        wait_for(lambda: _railed(pg, "left"), FRAMED_S, "the left side collapsed after the reload")
        # (the docked sides' widths may settle a little differently on a reload: the
        # view must be framed as it is now, wider than with the side open)
        again = _framed_wider_than(client, wide.aspect,
                                   "the reloaded page framed for its view with the side shut")
        assert _railed(pg, "left") and not _railed(pg, "right")
        # the controls' side collapsed too, then another lesson: framed for that view
        pg.locator('[data-dock-region-collapse="right"]').click()
        wait_for(lambda: _railed(pg, "right"), 60, "the right side to collapse")
        widest = _framed_wider_than(client, again.aspect, "the robot framed for the widest view")
        lab.switch("hand")
        _framed_for_its_view(client, widest)  # (shown: framed for the view as it is now)
        assert _railed(pg, "right")
    finally:
        pg.close()
        lab.switch(first)
