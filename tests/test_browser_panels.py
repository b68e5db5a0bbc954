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

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

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
    wait_for(lambda: camera.shown(client, since) is not None, 120,
             "the page to show the robot framed for its view")
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
        wider = _framed_for_its_view(client, wide)
        assert wider.aspect > wide.aspect * 1.03
        wait_for(lambda: _stored(pg) == ["left"], 30, "the page to note the collapsed side")
        # a reload: the side collapses again, and the new page frames for that view
        known = set(lab.server.get_clients())
        pg.reload()
        wait_for(lambda: new_page_client(lab, known) is not None, 60, "the reloaded page")
        client = new_page_client(lab, known)
        wait_for(lambda: _railed(pg, "left"), 120, "the left side collapsed after the reload")
        again = _framed_for_its_view(client)
        wait_for(lambda: camera.shown(client) is not None
                 and abs(client.camera.aspect / wider.aspect - 1.0) <= camera.RESHAPE, 120,
                 "the reloaded page framed for the collapsed side's view")
        assert _railed(pg, "left") and not _railed(pg, "right")
        # the controls' side collapsed too, then another lesson: framed for that view
        pg.locator('[data-dock-region-collapse="right"]').click()
        wait_for(lambda: _railed(pg, "right"), 60, "the right side to collapse")
        widest = _framed_for_its_view(client, again)
        lab.switch("hand")
        framing = _framed_for_its_view(client, widest)
        assert _railed(pg, "right")
        assert abs(framing.aspect / client.camera.aspect - 1.0) <= camera.RESHAPE
    finally:
        pg.close()
        lab.switch(first)
