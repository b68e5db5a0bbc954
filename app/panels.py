"""Each browser's collapsed side panels, kept across a reload.

viser's page lets a person collapse either docked side (the charts on the left, the
controls on the right) to a thin rail with one click ("Collapse panel area"), and
``app.camera`` frames the robot again for the space gained. viser keeps that state in
the page alone: the server is not told, and a reload brings both sides back. So
:func:`install` sends each page, when it connects, the small script
:data:`PAGE_SCRIPT` (:func:`app.page_js.run_javascript`): it notes in the browser's
localStorage which sides are collapsed, and after a reload collapses them again by
clicking the same control a person clicks. It changes nothing on the server, on the
arm, or on any other page. On a phone (viser's bottom sheet, no docked sides) it finds
nothing to do.
"""

from __future__ import annotations

import json

import viser

from app.page_js import LOCAL_STORAGE_PREFIX, run_javascript

#: the page's localStorage key: a JSON list of the collapsed sides ("left", "right")
PANELS_KEY = "armlab_collapsed_panels"
#: ms after the page loads during which the remembered sides are collapsed again as they
#: appear (a lesson's chart panel comes after the page's first messages)
RESTORE_MS = 60_000

#: What each page runs once. While restoring, the remembered sides are collapsed as they
#: appear; after that, the page's collapsed sides are written down whenever they change.
PAGE_SCRIPT = """
(() => {
  const KEY = %(key)s;
  const EDGES = ['left', 'right'];
  const railed = (edge) =>
    !!document.querySelector(`[data-dock-region="${edge}"] [data-dock-rail-root]`);
  const collapse = (edge) => document.querySelector(`[data-dock-region-collapse="${edge}"]`);
  let wanted = [];
  try { wanted = JSON.parse(localStorage.getItem(KEY) || '[]').filter(e => EDGES.includes(e)); }
  catch (e) { wanted = []; }
  const started = Date.now();
  let restoring = wanted.length > 0;
  let written = localStorage.getItem(KEY);
  setInterval(() => {
    if (restoring) {
      for (const edge of wanted) {
        const button = collapse(edge);
        if (button && !railed(edge)) button.click();
      }
      if (wanted.every(railed) || Date.now() - started > %(restore_ms)d) restoring = false;
      return;
    }
    const now = JSON.stringify(EDGES.filter(railed));
    if (now !== written) { localStorage.setItem(KEY, now); written = now; }
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
