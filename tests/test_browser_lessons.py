"""Every lesson in a real headless Chromium: switch to it from the page's lesson switcher,
see its scene drawn, its charts showing their whole x range and its "Try this" line,
switch back, and no error in the browser console.

Screenshots of each lesson go to ``$ARMLAB_SCREENSHOTS`` (a directory) when it is set,
for a person to look at.
"""

from __future__ import annotations

import io
import os
import time
from pathlib import Path

import numpy as np
import pytest
from _helpers import (
    after_switch,
    chart_x_ranges,
    expected_console,
    view_png,
    wait_for,
    wait_look_settled,
)

from armlab.app.lessons.catalog import all_lessons

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]  # every lesson, drawn in software
Image = pytest.importorskip("PIL.Image")

#: Part of the 3D canvas to judge: below the notifications (fractions of the canvas
#: width and height; the lab docks its controls beside the canvas).
VIEW = (0.0, 0.22, 1.0, 1.0)


@pytest.fixture(scope="module")
def page(browser, lab):
    lab.wait_until_loadable()
    known = set(lab.server.get_clients())
    pg = browser.new_page(viewport={"width": 1400, "height": 860})
    pg.console_errors = []  # type: ignore[attr-defined]
    pg.on("console", lambda m: pg.console_errors.append(m.text)
          if m.type == "error" and not expected_console(m.text) else None)
    pg.on("pageerror", lambda e: pg.console_errors.append(f"page error: {e}"))
    pg.goto(lab.url)
    pg.locator("canvas").first.wait_for()
    wait_look_settled(lab, known)  # (pictures are compared across lesson switches)
    yield pg
    pg.close()


def view_pixels(page) -> np.ndarray:
    """(h, w, 3) the 3D view's free area as the page shows it now."""
    box = page.locator("canvas").first.bounding_box()
    x0, y0, x1, y1 = VIEW
    clip = {"x": box["x"] + x0 * box["width"], "y": box["y"] + y0 * box["height"],
            "width": (x1 - x0) * box["width"], "height": (y1 - y0) * box["height"]}
    png = view_png(page, clip)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)


def drawn_fraction(pixels: np.ndarray) -> float:
    """Fraction of pixels that differ from the background (the most common colour)."""
    flat = pixels.reshape(-1, 3)
    colours, counts = np.unique(flat.astype(np.uint8), axis=0, return_counts=True)
    background = colours[np.argmax(counts)].astype(float)
    return float(np.mean(np.abs(flat - background).sum(axis=1) > 30))


def differs(a: np.ndarray, b: np.ndarray) -> bool:
    """True when two views differ (in size, or by more than 1 grey level on average)."""
    return a.shape != b.shape or float(np.mean(np.abs(a - b))) > 1.0


def switch(page, lab, name: str, title: str) -> None:
    """Pick ``title`` in the page's Lesson select, as a person does."""
    page.get_by_label("Lesson").first.click()
    page.get_by_role("option", name=title, exact=True).click()
    wait_for(lambda: lab.lesson_name == name, 60, f"the lab to open {name}")


def settled_view(page, previous: np.ndarray | None, *, timeout: float = 90.0) -> np.ndarray:
    """The view once it changed from ``previous`` and has something drawn."""
    deadline = time.monotonic() + timeout
    while True:
        time.sleep(1.0)
        now = view_pixels(page)
        changed = previous is None or differs(now, previous)
        if changed and drawn_fraction(now) > 0.02:
            return now
        if time.monotonic() > deadline:
            return now


def charts_show_all_their_data(page) -> bool:  # noqa: ANN001
    """True when every chart on the page has an x range, and it spans exactly its data
    (the lab's charts pin their x range to their data's extent:
    ``armlab.app.page.plots.fixed_x``)."""
    return all(lo is not None and hi is not None and lo == first and hi == last
               for lo, hi, first, last in chart_x_ranges(page))


def save(pixels: np.ndarray, name: str) -> None:
    where = os.environ.get("ARMLAB_SCREENSHOTS")
    if where:
        Path(where).mkdir(parents=True, exist_ok=True)
        Image.fromarray(pixels.astype(np.uint8)).save(Path(where) / f"{name}.png")


def try_this(page) -> str:
    """The text of the page's "Try this:" line ("" while there is none)."""
    line = page.locator("p", has_text="Try this:")
    return line.first.inner_text() if line.count() else ""


def test_every_lesson_renders_and_switching_back_gives_no_console_error(lab, page):
    lessons = all_lessons()
    first = lab.lesson_name
    names = [n for n in sorted(lessons, key=lambda n: lessons[n].sort_key) if n != first]
    assert {"redundancy", "quadruped"} <= set(lessons)
    before = settled_view(page, None)
    save(before, first)
    assert drawn_fraction(before) > 0.02, f"{first}: nothing drawn"
    wait_for(lambda: len(try_this(page)) > 30, 60, f"{first}: a Try this line")
    shown = {first: before}
    for name in names:
        switch(page, lab, name, lessons[name].title)
        now = settled_view(page, before)
        save(now, name)
        assert drawn_fraction(now) > 0.02, f"{name}: the 3D view is blank"
        assert differs(now, before), f"{name}: the view did not change"
        wait_for(lambda: charts_show_all_their_data(page), 30, f"{name}: charts' x ranges")
        wait_for(lambda: len(try_this(page)) > 30, 60, f"{name}: a Try this line")
        shown[name] = before = now
        assert after_switch(page.console_errors) == [], \
            f"after opening {name}: {page.console_errors}"
    switch(page, lab, first, lessons[first].title)
    back = settled_view(page, before)
    save(back, f"{first}-again")
    assert drawn_fraction(back) > 0.02, f"{first}: blank after switching back"
    assert after_switch(page.console_errors) == [], page.console_errors
