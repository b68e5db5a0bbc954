"""Styles that keep viser's control panel readable at the lab's text sizes (projector
mode included): a folder's title stays one line on its folder's top border, and its
folder stands far enough below the element above that the title never covers it.

relies on (viser 1.1.1's client, components/Folder.tsx and Folder.css.ts):
- a folder is a Mantine ``Paper`` drawn ``withBorder`` (``data-with-border``) whose first
  child is the title, another ``Paper``, lifted half its height above the border
  (``position: absolute; transform: translateY(-50%)``);
- a uPlot chart's ``Paper`` also has ``data-with-border`` and is told apart by its class
  ``uplot-container`` (components/UplotComponent.tsx);
- CSS ``:has()`` (Chromium 105+, Firefox 121+, Safari 15.4+).
"""

from __future__ import annotations

#: a folder's box in viser's panel (not a chart's, which shares its look)
FOLDER = ".mantine-Paper-root[data-with-border]:not(.uplot-container)"
#: a folder's title
FOLDER_TITLE = f"{FOLDER} > .mantine-Paper-root:first-child"


def panel_style() -> str:
    """A ``<style>`` element for the lab's style sheet (:func:`armlab.app.page.theme.style_sheet`):
    a folder's title on one line, cut with "…" if wider than its folder (the lab's titles
    are short enough not to be), and each titled folder's top margin at least the
    title's half height (0.65 line at line-height 1.3) plus a gap."""
    return (
        "<style>"
        f"{FOLDER_TITLE} {{white-space:nowrap;overflow:hidden;text-overflow:ellipsis;"
        "max-width:calc(100% - 1em)}}"
        f"{FOLDER}:has(> .mantine-Paper-root:first-child) {{"
        "margin-top:max(var(--mantine-spacing-xs), calc(0.7em + 4px)) !important}}"
        "</style>"
    )

