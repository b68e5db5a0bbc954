"""Every control's label tied to its field, on every page.

viser labels each control with ``<label for=UUID>``, but a text field (the classroom's
Passcode and "Your name") has no element of that id, and a slider's is a ``<div>``: the
label names nothing for a screen reader and a click on it focuses nothing.
:func:`install` sends each page :data:`armlab.app.viser_ext.page_scripts.LABELS_SCRIPT`,
which gives such a field ``aria-labelledby`` its label (so it is announced, and found, by
its label's words) and makes a click on the label focus it. viser's client is not changed.
"""

from __future__ import annotations

import viser

from armlab.app.viser_ext.page_js import run_javascript
from armlab.app.viser_ext.page_scripts import LABELS_SCRIPT


def send(client: viser.ClientHandle) -> None:
    """Run the script in ``client``'s page (nothing on a viser without the message)."""
    run_javascript(client, LABELS_SCRIPT, name="labels")


def install(server: viser.ViserServer) -> None:
    """Send the script to every page that connects to ``server`` from now on."""
    server.on_client_connect(send)
