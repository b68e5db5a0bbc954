"""Each browser's collapsed side panels, kept across a reload.

viser's page lets a person collapse either docked side (the charts on the left, the
controls on the right) to a thin rail with one click ("Collapse panel area"), and
``armlab.app.page.camera`` frames the robot again for the space gained. viser keeps that state in
the page alone: the server is not told, and a reload brings both sides back. So
:func:`install` sends each page, when it connects, the small script
:data:`PAGE_SCRIPT` (:func:`armlab.app.viser_ext.page_js.run_javascript`): it notes in the browser's
localStorage which sides are collapsed, and after a reload collapses them again by
clicking the same control a person clicks. It changes nothing on the server, on the
arm, or on any other page. On a phone (viser's bottom sheet, no docked sides) it finds
nothing to do.
"""

from __future__ import annotations

import json

import viser

from armlab.app.viser_ext.page_js import LOCAL_STORAGE_PREFIX, run_javascript

#: the page's localStorage key: a JSON list of the collapsed sides ("left", "right")
PANELS_KEY = "armlab_collapsed_panels"
#: ms after the page loads during which each remembered side is collapsed again once it
#: appears (a lesson's chart panel comes after the page's first messages, late on a busy
#: machine or a page drawing in software)
RESTORE_MS = 300_000

#: What each page runs once. While restoring, each remembered side is collapsed as it
#: appears (clicked again every 2 s until it shows collapsed, then left to the person);
#: once every remembered side is done (or after RESTORE_MS), the page's collapsed sides
#: are written down whenever they change.
PAGE_SCRIPT = """
(() => {
  const KEY = %(key)s;
  const EDGES = ['left', 'right'];
  const railed = (edge) =>
    !!document.querySelector(`[data-dock-region="${edge}"] [data-dock-rail-root]`);
  const collapse = (edge) => document.querySelector(`[data-dock-region-collapse="${edge}"]`);
  let pending = [];
  try { pending = JSON.parse(localStorage.getItem(KEY) || '[]').filter(e => EDGES.includes(e)); }
  catch (e) { pending = []; }
  const started = Date.now();
  const clicked = {};  // edge -> ms of the last click (a click during a re-layout may not take)
  let written = localStorage.getItem(KEY);
  setInterval(() => {
    const now = Date.now();
    if (pending.length && now - started < %(restore_ms)d) {
      pending = pending.filter((edge) => {
        if (railed(edge)) return false;  // done: from now on it is the person's
        const button = collapse(edge);
        if (button && now - (clicked[edge] || 0) > 2000) { button.click(); clicked[edge] = now; }
        return true;
      });
      return;
    }
    pending = [];
    const shown = JSON.stringify(EDGES.filter(railed));
    if (shown !== written) { localStorage.setItem(KEY, shown); written = shown; }
  }, 500);
})();
"""


def page_script() -> str:
    """The JavaScript each page runs: :data:`PAGE_SCRIPT` with its key filled in."""
    return PAGE_SCRIPT % {"key": json.dumps(LOCAL_STORAGE_PREFIX + PANELS_KEY),
                          "restore_ms": RESTORE_MS}


def send(client: viser.ClientHandle) -> None:
    """Run :func:`page_script` in ``client``'s page (nothing on a viser without the message)."""
    run_javascript(client, page_script(), name="panels")


def install(server: viser.ViserServer) -> None:
    """Send the script to every page that connects to ``server`` from now on."""
    server.on_client_connect(send)
