"""Scripts and styles aimed at the structure of viser's page (its DOM: Mantine's class
names, viser's layout, its labels), each run in one page through
:func:`armlab.app.viser_ext.page_js.run_javascript`. viser's client is not changed; a
script that finds nothing does nothing (and logs to the console).

relies on: viser 1.1.1's page: a button's text is its label; the 3D view's
``canvas[data-engine]`` inside a ``flex-grow`` div; the phone layout's sheet fixed
(inline style) at ``bottom: 0px`` holding a ``width: 20em`` div; the docked panels'
``data-dock-region``, ``data-dock-rail-root`` and ``data-dock-region-collapse``
attributes; an input's label ``<label for=UUID>`` in the same Mantine ``Flex`` row as
its ``<input>``; Mantine's ``.mantine-Paper-root`` (the control panel),
``.mantine-Notification-root``; uPlot's ``.u-title``, ``.u-legend``; seen in viser 1.1.1
"""

from __future__ import annotations

import json

#: The style sheet of E-STOP first (selectors are the script's ``data-armlab`` marks).
STOP_CSS = """
[data-armlab="estop"] {{ min-height: {min_height_px}px !important; height: auto !important;
  font-weight: 700 !important; }}
@media (max-width: {phone_max_width_px}px) {{
  [data-armlab="sheet"] {{ left: 0 !important; right: 0 !important; width: 100% !important;
    height: {sheet_vh}vh !important; max-height: {sheet_vh}vh !important; }}
  [data-armlab="sheet"] div[style*="width: 20em"] {{ width: 100% !important; }}
  [data-armlab="estop-row"] {{ position: fixed !important; left: 0; right: 0;
    bottom: {sheet_vh}vh; z-index: 30; margin: 0 !important; padding: 6px 8px !important;
    background: var(--mantine-color-body); box-shadow: 0 -2px 6px rgba(0,0,0,0.15); }}
  [data-armlab="view"] {{ align-self: flex-start !important;
    height: calc({sheet_rest}vh - {estop_room}px) !important; }}
}}
@media (min-width: {desktop_min_width_px}px) {{
  [data-armlab="estop-row"] {{ position: sticky !important; top: 0; z-index: 30;
    background: var(--mantine-color-body); padding-bottom: 4px; }}
  [data-armlab="unclip"] {{ overflow: visible !important; }}
}}
"""

#: What a page runs for E-STOP first (:mod:`armlab.app.page.stop_first` says what it does).
STOP_SCRIPT = """
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
        // on a desktop the row sticks to the top of the panel's scrolling area: the
        // boxes between them that clip (overflow hidden) would hold it, so they do not
        for (let up = b.parentElement.parentElement;
             up && !up.classList.contains('mantine-ScrollArea-viewport') && up !== document.body;
             up = up.parentElement) {
          if (getComputedStyle(up).overflowY === 'hidden' && !up.dataset.armlab) mark(up, 'unclip');
        }
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


def stop_first_script(*, label: str, min_height_px: int, phone_max_width_px: int,
                      sheet_vh: int) -> str:
    """The E-STOP-first script (:data:`STOP_SCRIPT`) for the button called ``label``: the
    first Tab focuses it, Esc presses it; its style makes it at least ``min_height_px``
    tall and, in a viewport at most ``phone_max_width_px`` wide, pins it above the
    controls, which take the lower ``sheet_vh`` % of the screen; in a wider one it sticks to
    the top of the control panel however far the panel is scrolled."""
    css = STOP_CSS.format(min_height_px=min_height_px, phone_max_width_px=phone_max_width_px,
                          desktop_min_width_px=phone_max_width_px + 1,
                          sheet_vh=sheet_vh, sheet_rest=100 - sheet_vh,
                          estop_room=min_height_px + 12)
    return STOP_SCRIPT % {"label": json.dumps(label), "css": json.dumps(css)}


#: What a page runs to keep its collapsed side panels (:mod:`armlab.app.page.panels`).
#: While restoring, each remembered side is collapsed as it appears (clicked again every
#: 2 s until it shows collapsed, then left to the person); once every remembered side is
#: done (or after ``restore_ms``), the page's collapsed sides are written down whenever
#: they change.
PANELS_SCRIPT = """
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


def panels_script(*, key: str, restore_ms: int) -> str:
    """The collapsed-panels script (:data:`PANELS_SCRIPT`) keeping its list in the
    localStorage item ``key`` (the full key, viser's prefix included)."""
    return PANELS_SCRIPT % {"key": json.dumps(key), "restore_ms": restore_ms}


#: What a page runs to make text inputs password fields: the input in the row of each
#: label for one of ``window.armlabPasswords``' ids gets ``type=password`` (the browser
#: shows dots; what is typed still reaches the server as before), now and whenever
#: viser draws it again. React (viser 1.1.1's page) removes an input's ``type`` at every
#: value it renders (each key typed), so a change of ``type`` is undone at once: the
#: observer's callback runs before the page is painted, and no typed character shows.
PASSWORD_SCRIPT = """
(() => {
  const ids = window.armlabPasswords || (window.armlabPasswords = new Set());
  ids.add(%(uuid)s);
  const mask = () => {
    for (const id of ids) {
      const label = document.querySelector(`label[for="${CSS.escape(id)}"]`);
      const row = label && label.closest('.mantine-Flex-root');
      const input = row && row.querySelector('input');
      if (input && input.type !== 'password') {
        input.type = 'password';
        input.autocomplete = 'off';
      }
    }
  };
  mask();
  if (window.armlabPasswordObserver) return;
  let queued = false;
  window.armlabPasswordObserver = new MutationObserver((records) => {
    if (records.some((r) => r.type === 'attributes')) { mask(); return; }
    if (queued) return;
    queued = true;
    requestAnimationFrame(() => { queued = false; mask(); });
  });
  window.armlabPasswordObserver.observe(document.body, {
    childList: true, subtree: true, attributes: true, attributeFilter: ['type'] });
})();
"""


def password_script(uuid: str) -> str:
    """The script (:data:`PASSWORD_SCRIPT`) making the text input ``uuid`` a password
    field."""
    return PASSWORD_SCRIPT % {"uuid": json.dumps(uuid)}


def text_size_sheet(*, controls_px: int, chart_title_px: int) -> str:
    """A ``<style>`` element setting every text of viser's control panel and its
    notifications to ``controls_px`` px (Mantine sets sizes of 9-13 px on labels, inputs,
    slider marks and tabs), and uPlot's chart titles and legends to ``chart_title_px``."""
    c, t = controls_px, chart_title_px
    return (
        "<style>"
        f".mantine-Paper-root *:not(svg):not(path):not(canvas) {{font-size:{c}px !important;"
        "line-height:1.3 !important}"
        # nothing wider than the panel: its scrolling content is as wide as the panel (not
        # as its widest table), a table shares that width out and wraps its cells
        ".mantine-Paper-root .mantine-ScrollArea-content {display:block !important;"
        "min-width:0 !important}"
        # a folder's body (viser: a one-row grid that animates its opening) as wide as
        # its folder, not as its widest table
        ".mantine-Paper-root [style*='display: grid'][style*='grid-template-rows'] {"
        "grid-template-columns:minmax(0, 1fr)}"
        ".mantine-Paper-root [style*='display: grid'][style*='grid-template-rows'] > * {"
        "min-width:0}"
        # a table of up to five columns shares the panel's width out and wraps its cells
        # (a word is broken only where it cannot fit); a wider one (the paper's Table 1)
        # scrolls sideways inside the panel, its numbers whole
        ".mantine-Paper-root table:not(.u-legend) :is(td, th) {padding-left:0.25em !important;"
        "padding-right:0.25em !important}"
        ".mantine-Paper-root table:not(.u-legend):not(:has(tr > :nth-child(6))) {"
        "table-layout:fixed;width:100%}"
        ".mantine-Paper-root table:not(.u-legend):not(:has(tr > :nth-child(6))) :is(td, th) {"
        "overflow-wrap:break-word;white-space:normal !important}"
        ".mantine-Paper-root table:not(.u-legend):has(tr > :nth-child(6)) {display:block;"
        "overflow-x:auto;max-width:100%}"
        ".mantine-Paper-root table:not(.u-legend):has(tr > :nth-child(6)) :is(td, th) {"
        "white-space:nowrap !important}"
        # a slider's number field (viser: 3rem wide) holds its value at any text size
        ".mantine-Paper-root .mantine-NumberInput-root[style*='width: 3rem'] {"
        "width:3.7em !important}"
        f".u-title, .u-legend, .u-legend * {{font-size:{t}px !important;"
        "line-height:1.3 !important}"
        f".mantine-Notification-root * {{font-size:{c}px !important}}"
        "</style>"
    )


#: What a page runs so that a number field takes what a person types
#: (:mod:`armlab.app.page.number_keys`). Mantine's NumberInput drops every key but digits,
#: one decimal point and a leading minus, silently: "1e9" typed became "19". The script
#: stops such a key before the field drops it. An "e" starts an exponent, kept by the
#: script (not the field) and shown under it: Enter or Tab types mantissa × 10^exponent
#: into the field in plain digits (as if typed, so the page sends it and the lab's rule
#: applies; the focus stays, a second Tab leaves) and so does leaving the field;
#: Backspace takes the exponent back, Esc drops it. Any
#: other key the field cannot take is named under it for a few seconds.
NUMBER_KEYS_SCRIPT = """
(() => {
  if (window.armlabNumberKeys) return;
  window.armlabNumberKeys = true;
  const SAYS = %(says)s;
  const EXPONENT = %(exponent)s;
  const SHOW_MS = %(show_ms)d;
  const setValue = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, 'value').set;
  const field = (el) => el instanceof HTMLInputElement &&
    el.closest('.mantine-NumberInput-root') ? el : null;
  const rowOf = (el) => el.closest('.mantine-Flex-root') ||
    el.closest('.mantine-NumberInput-root').parentElement;
  const noteOf = (el) => {
    const row = rowOf(el);
    const next = row.nextElementSibling;
    return next && next.dataset.armlab === 'number-note' ? next : null;
  };
  const note = (el, text, ms) => {
    // a line of its own under the field's row, the panel's width: whole at any size
    let n = noteOf(el);
    if (!n) {
      n = document.createElement('div');
      n.dataset.armlab = 'number-note';
      n.setAttribute('role', 'status');
      n.style.cssText = 'font-size: 0.85em; line-height: 1.25; margin: 2px 0 4px; ' +
        'padding: 3px 6px; border-radius: 4px; color: var(--mantine-color-orange-9); ' +
        'background: var(--mantine-color-orange-0); white-space: normal; ' +
        'overflow-wrap: anywhere; max-width: 100%%; box-sizing: border-box;';
      rowOf(el).insertAdjacentElement('afterend', n);
    }
    n.textContent = text;
    clearTimeout(n.armlabTimer);
    if (ms) n.armlabTimer = setTimeout(() => n.remove(), ms);
  };
  const plain = (v) => v.toLocaleString('en-US', { useGrouping: false,
                                                   maximumFractionDigits: 20 });
  const show = (el) => {
    const v = Number(el.armlabBase + 'e' + el.armlabExp);
    note(el, EXPONENT.replace('{typed}', el.armlabBase + 'e' + el.armlabExp)
      .replace('{value}', /[0-9]/.test(el.armlabExp) && isFinite(v) ? plain(v) : '…'), 0);
  };
  const done = (el, apply) => {
    const exp = el.armlabExp;
    el.armlabExp = null;
    const v = Number(el.armlabBase + 'e' + exp);
    if (apply && /[0-9]/.test(exp) && isFinite(v)) {
      setValue.call(el, plain(v));
      el.dispatchEvent(new Event('input', { bubbles: true }));
    }
    const n = noteOf(el);
    if (n) n.remove();
  };
  document.addEventListener('keydown', (ev) => {
    const el = field(ev.target);
    if (!el || ev.ctrlKey || ev.metaKey || ev.altKey) return;
    const inExp = typeof el.armlabExp === 'string';
    if (inExp) {
      if (ev.key === 'Enter' || ev.key === 'Tab') {  // typed in, sent; a second leaves
        ev.preventDefault(); done(el, true); return; }
      if (ev.key === 'Escape') { ev.preventDefault(); ev.stopPropagation(); done(el, false);
                                 return; }
      if (ev.key === 'Backspace') {
        ev.preventDefault();
        if (el.armlabExp === '') done(el, false);
        else { el.armlabExp = el.armlabExp.slice(0, -1); show(el); }
        return;
      }
      if (ev.key.length !== 1) return;
      ev.preventDefault();
      if (/^[0-9]$/.test(ev.key) || (ev.key === '-' && el.armlabExp === '')) {
        el.armlabExp += ev.key;
        show(el);
      }
      return;
    }
    if (ev.key.length !== 1 || /^[0-9.]$/.test(ev.key) || ev.key === '-') return;
    ev.preventDefault();
    if ((ev.key === 'e' || ev.key === 'E') && /[0-9]/.test(el.value)) {
      el.armlabBase = el.value;
      el.armlabExp = '';
      show(el);
      return;
    }
    note(el, SAYS.replace('{key}', ev.key), SHOW_MS);
  }, true);
  document.addEventListener('blur', (ev) => {
    const el = field(ev.target);
    if (el && typeof el.armlabExp === 'string') done(el, true);
  }, true);
})();
"""


def number_keys_script(*, says: str, exponent: str, show_ms: int) -> str:
    """The number fields' script (:data:`NUMBER_KEYS_SCRIPT`): a key a number field would
    drop is stopped and ``says`` (``{key}``: that key) shown under it for ``show_ms``; an
    exponent being typed is shown as ``exponent`` (``{typed}``, ``{value}``)."""
    return NUMBER_KEYS_SCRIPT % {"says": json.dumps(says), "exponent": json.dumps(exponent),
                                 "show_ms": int(show_ms)}


#: What a page runs to tie every control's label to its input (:mod:`armlab.app.page.labels`).
#: viser writes ``<label for=UUID>`` for every control, but a text field's ``<input>`` (the
#: Passcode, "Your name") carries no such id, and a slider's id is on a ``<div>``: the label
#: then names nothing for a screen reader, a click on it focuses nothing, and a test cannot
#: find the field by its label. The script gives such a field ``aria-labelledby`` (and its
#: label an id), and a label click focuses it; re-done, at most once a frame, as viser
#: re-renders.
LABELS_SCRIPT = """
(() => {
  if (window.armlabLabels) return;
  window.armlabLabels = true;
  const labelable = (el) => el && ['INPUT', 'SELECT', 'TEXTAREA'].includes(el.tagName);
  const fieldOf = (label) => {
    for (let row = label.parentElement, up = 0; row && up < 4; row = row.parentElement, up++) {
      const f = row.querySelector('input:not([type=hidden]), textarea, select');
      if (f) return f;
    }
    return null;
  };
  const tie = () => {
    for (const label of document.querySelectorAll('label[for]')) {
      if (labelable(document.getElementById(label.htmlFor))) continue;
      const field = fieldOf(label);
      if (!field || field.getAttribute('aria-labelledby')) continue;
      if (!label.id) label.id = 'armlab-label-' + label.htmlFor;
      field.setAttribute('aria-labelledby', label.id);
      if (!label.dataset.armlabTied) {
        label.dataset.armlabTied = '1';
        label.addEventListener('click', () => { const f = fieldOf(label); if (f) f.focus(); });
      }
    }
  };
  let queued = false;
  new MutationObserver(() => {
    if (queued) return;
    queued = true;
    requestAnimationFrame(() => { queued = false; tie(); });
  }).observe(document.body, { childList: true, subtree: true });
  tie();
})();
"""
