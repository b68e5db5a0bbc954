"""Each browser's collapsed side panels, kept across a reload.

viser's page lets a person collapse either docked side (the charts on the left, the
controls on the right) to a thin rail with one click ("Collapse panel area"), and
``armlab.app.page.camera`` frames the robot again for the space gained. viser keeps that state in
the page alone: the server is not told, and a reload brings both sides back. So
:func:`install` sends each page, when it connects, the small script
:func:`page_script` (:func:`armlab.app.viser_ext.page_js.run_javascript`): it notes in the browser's
localStorage which sides are collapsed, and after a reload collapses them again by
clicking the same control a person clicks. It changes nothing on the server, on the
arm, or on any other page. On a phone (viser's bottom sheet, no docked sides) it finds
nothing to do.
"""

from __future__ import annotations

import viser

from armlab.app.viser_ext.page_js import LOCAL_STORAGE_PREFIX, run_javascript
from armlab.app.viser_ext.page_scripts import panels_script

#: the page's localStorage key: a JSON list of the collapsed sides ("left", "right")
PANELS_KEY = "armlab_collapsed_panels"
#: ms after the page loads during which each remembered side is collapsed again once it
#: appears (a lesson's chart panel comes after the page's first messages, late on a busy
#: machine or a page drawing in software)
RESTORE_MS = 300_000

def page_script() -> str:
    """The JavaScript each page runs (:func:`armlab.app.viser_ext.page_scripts.panels_script`
    with the lab's key)."""
    return panels_script(key=LOCAL_STORAGE_PREFIX + PANELS_KEY, restore_ms=RESTORE_MS)


def send(client: viser.ClientHandle) -> None:
    """Run :func:`page_script` in ``client``'s page (nothing on a viser without the message)."""
    run_javascript(client, page_script(), name="panels")


def install(server: viser.ViserServer) -> None:
    """Send the script to every page that connects to ``server`` from now on."""
    server.on_client_connect(send)
