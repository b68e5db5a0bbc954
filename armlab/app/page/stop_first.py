"""E-STOP first on every page: the first Tab stop, the Esc key, a large button, always in view.

viser has no API for key presses or for an element's tab order (viser issue #691:
"Not currently"). :func:`install` sends each page, when it connects, the small script
:func:`page_script` (:func:`armlab.app.viser_ext.page_js.run_javascript`; the script and
its style, aimed at viser's page, are in :mod:`armlab.app.viser_ext.page_scripts`).
viser's client is not changed. The script only ever *clicks* the lab's E-STOP button
(whose press then reaches the server like a mouse click, through the lab's gate and
roles) or moves the keyboard focus to it; it never sends anything of its own.

What the script does on the page:

- the first Tab after the page loads (nothing focused yet) focuses E-STOP;
- Esc presses E-STOP, wherever the focus is (but not while a dropdown is open: there
  Esc closes the dropdown, as everywhere);
- it marks E-STOP, its row, the phone's control sheet and the 3D view with
  ``data-armlab`` attributes (re-marked whenever viser re-renders them), which the
  style sheet it adds uses: E-STOP at least :data:`MIN_HEIGHT_PX`
  tall; on a phone (viewport at most :data:`PHONE_MAX_WIDTH_PX` wide, viser's own
  mobile layout) the controls fill the lower :data:`SHEET_VH` % of the screen, E-STOP
  is pinned just above them whatever they scroll to, and the 3D view takes the space
  above E-STOP, so the robot is framed there (``armlab.app.page.camera`` re-frames a page whose
  view changed shape); on a wider page E-STOP's row sticks to the top of the control
  panel however far the panel is scrolled (the boxes between it and the panel's
  scrolling area stop clipping it).

If a viser release drops the message :mod:`armlab.app.viser_ext.page_js` uses, none of this happens
(the buttons still work with the mouse); ``tests/test_browser_stop_first.py`` then fails.
"""

from __future__ import annotations

import viser

from armlab.app.viser_ext.page_js import run_javascript
from armlab.app.viser_ext.page_scripts import stop_first_script

#: The lab's E-STOP button's label (``armlab.app.lab.server``).
ESTOP_LABEL = "E-STOP"
#: CSS px: E-STOP's smallest height (a thumb-sized target, WCAG's 44 px).
MIN_HEIGHT_PX = 48
#: CSS px: widest viewport that gets the phone layout (viser's mobile layout: Mantine's
#: "xs" breakpoint, 36 em = 576 px, at most).
PHONE_MAX_WIDTH_PX = 576
#: % of the screen's height the phone's control sheet takes.
SHEET_VH = 52

def page_script() -> str:
    """The JavaScript each page runs, for the lab's E-STOP and the sizes above
    (:func:`armlab.app.viser_ext.page_scripts.stop_first_script`)."""
    return stop_first_script(label=ESTOP_LABEL, min_height_px=MIN_HEIGHT_PX,
                             phone_max_width_px=PHONE_MAX_WIDTH_PX, sheet_vh=SHEET_VH)


def send(client: viser.ClientHandle) -> None:
    """Run :func:`page_script` in ``client``'s page (nothing on a viser without the message)."""
    run_javascript(client, page_script(), name="stop first")


def install(server: viser.ViserServer) -> None:
    """Send the script to every page that connects to ``server`` from now on."""
    server.on_client_connect(send)
