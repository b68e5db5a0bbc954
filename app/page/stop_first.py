"""E-STOP first on every page: the first Tab stop, the Esc key, a large button, pinned on a phone.

viser has no API for key presses or for an element's tab order (viser issue #691:
"Not currently"). :func:`install` sends each page, when it connects, the small script
:data:`PAGE_SCRIPT` (:func:`armlab.app.viser_ext.page_js.run_javascript`). viser's client is not
changed. The
script only ever *clicks* the lab's E-STOP button (whose press then reaches the server
like a mouse click, through the lab's gate and roles) or moves the keyboard focus to
it; it never sends anything of its own.

What the script does on the page:

- the first Tab after the page loads (nothing focused yet) focuses E-STOP;
- Esc presses E-STOP, wherever the focus is (but not while a dropdown is open: there
  Esc closes the dropdown, as everywhere);
- it marks E-STOP, its row, the phone's control sheet and the 3D view with
  ``data-armlab`` attributes (re-marked whenever viser re-renders them), which the
  style sheet :data:`STOP_CSS` it adds uses: E-STOP at least :data:`MIN_HEIGHT_PX`
  tall; on a phone (viewport at most :data:`PHONE_MAX_WIDTH_PX` wide, viser's own
  mobile layout) the controls fill the lower :data:`SHEET_VH` % of the screen, E-STOP
  is pinned just above them whatever they scroll to, and the 3D view takes the space
  above E-STOP, so the robot is framed there (``armlab.app.page.camera`` re-frames a page whose
  view changed shape).

If a viser release drops the message :mod:`armlab.app.viser_ext.page_js` uses, none of this happens
(the buttons
still work with the mouse); ``tests/test_browser_stop_first.py`` then fails.
"""

from __future__ import annotations

import json

import viser

from armlab.app.viser_ext.page_js import run_javascript

#: The lab's E-STOP button's label (``armlab.app.server``).
ESTOP_LABEL = "E-STOP"
#: CSS px: E-STOP's smallest height (a thumb-sized target, WCAG's 44 px).
MIN_HEIGHT_PX = 48
#: CSS px: widest viewport that gets the phone layout (viser's mobile layout: Mantine's
#: "xs" breakpoint, 36 em = 576 px, at most).
PHONE_MAX_WIDTH_PX = 576
#: % of the screen's height the phone's control sheet takes.
SHEET_VH = 52

#: The style sheet the script adds (selectors are the script's ``data-armlab`` marks).
STOP_CSS = f"""
[data-armlab="estop"] {{ min-height: {MIN_HEIGHT_PX}px !important; height: auto !important;
  font-weight: 700 !important; }}
@media (max-width: {PHONE_MAX_WIDTH_PX}px) {{
  [data-armlab="sheet"] {{ left: 0 !important; right: 0 !important; width: 100% !important;
    height: {SHEET_VH}vh !important; max-height: {SHEET_VH}vh !important; }}
  [data-armlab="sheet"] div[style*="width: 20em"] {{ width: 100% !important; }}
  [data-armlab="estop-row"] {{ position: fixed !important; left: 0; right: 0;
    bottom: {SHEET_VH}vh; z-index: 30; margin: 0 !important; padding: 6px 8px !important;
    background: var(--mantine-color-body); box-shadow: 0 -2px 6px rgba(0,0,0,0.15); }}
  [data-armlab="view"] {{ align-self: flex-start !important;
    height: calc({100 - SHEET_VH}vh - {MIN_HEIGHT_PX + 12}px) !important; }}
}}
"""

#: The script each page runs once (see the module's docstring).
PAGE_SCRIPT = """
(() => {
  if (window.armlabStopFirst) return;
  window.armlabStopFirst = true;
  const LABEL = %(label)s;
  const style = document.createElement('style');
  style.id = 'armlab-stop-first';
  style.textContent = %(css)s;
  document.head.appendChild(style);
  const estop = () => [...document.querySelectorAll('button')]
    .find(b => b.textContent.trim() === LABEL);
  const mark = (el, name) => { if (el && el.dataset.armlab !== name) el.dataset.armlab = name; };
  // (runs after DOM changes, at most once a frame: cheap while the marks are in place)
  const seen = { estop: null, view: null };
  const markAll = () => {
    if (!(seen.estop && seen.estop.isConnected)) {
      const b = estop();
      if (b) {
        seen.estop = b;
        mark(b, 'estop');
        if (!b.parentElement) return;
        mark(b.parentElement, 'estop-row');
        // viser's phone sheet: the ancestor fixed (inline) at the bottom of the screen
        let el = b.parentElement.parentElement;
        while (el && el !== document.body && el.style.position !== 'fixed') el = el.parentElement;
        if (el && el !== document.body && el.style.bottom === '0px') mark(el, 'sheet');
      }
    }
    if (!(seen.view && seen.view.isConnected)) {
      const canvas = document.querySelector('canvas[data-engine]');
      const view = canvas && canvas.closest('div[style*="flex-grow"]');
      if (view) { seen.view = view; mark(view, 'view'); }
    }
  };
  let queued = false;
  new MutationObserver(() => {
    if (queued) return;
    queued = true;
    requestAnimationFrame(() => { queued = false; markAll(); });
  }).observe(document.body, { childList: true, subtree: true });
  markAll();
  document.addEventListener('keydown', (e) => {
    const b = estop();
    if (!b) return;
    const active = document.activeElement;
    if (e.key === 'Tab' && !e.shiftKey && (!active || active === document.body)) {
      e.preventDefault();
      b.focus();
    } else if (e.key === 'Escape' && !(active && active.getAttribute('aria-expanded') === 'true')) {
      b.click();
    }
  }, true);
})();
"""


def page_script() -> str:
    """The JavaScript each page runs: :data:`PAGE_SCRIPT` with the label and style filled in."""
    return PAGE_SCRIPT % {"label": json.dumps(ESTOP_LABEL), "css": json.dumps(STOP_CSS)}


def send(client: viser.ClientHandle) -> None:
    """Run :func:`page_script` in ``client``'s page (nothing on a viser without the message)."""
    run_javascript(client, page_script(), name="stop first")


def install(server: viser.ViserServer) -> None:
    """Send the script to every page that connects to ``server`` from now on."""
    server.on_client_connect(send)
