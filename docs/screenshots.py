"""Take the README's pictures of every lesson from the real page (``make screenshots``).

Starts the lab on a free loopback port (simulated arm), opens it in Debian's headless
Chromium (the Chromium and flags of the browser tests) at 1280x720, opens each lesson
in turn, waits until the page shows the lesson's framed view (``armlab.app.page.camera.shown``)
and its controls ("Try this"), closes the browser's "software WebGL" notice and saves
``docs/img/<lesson>.png``; then ``docs/img/phone.png``, the first lesson on a 390x844
phone. Run: ``python docs/screenshots.py [--out DIR] [LESSON ...]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the browser tests' Chromium (_helpers)

from _helpers import CHROMIUM, CHROMIUM_ARGS, new_page_client  # noqa: E402

from armlab.app.lab.server import Lab, ServeOptions  # noqa: E402
from armlab.app.lessons.catalog import all_lessons  # noqa: E402
from armlab.app.page import camera  # noqa: E402

#: (width, height) of the lesson pictures, CSS px (a 720p projector).
SIZE = (1280, 720)
#: (width, height) of the phone picture.
PHONE = (390, 844)
#: s to wait for the page to show a lesson (software WebGL on a busy machine is slow).
PATIENCE = 180.0


def _until(predicate: Callable[[], object], what: str) -> None:
    """Poll ``predicate`` until true; RuntimeError naming ``what`` after :data:`PATIENCE`."""
    deadline = time.monotonic() + PATIENCE
    while not predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f"gave up after {PATIENCE:.0f} s waiting for {what}")
        time.sleep(0.1)


def _picture(lab: Lab, browser, size: tuple[int, int], path: Path) -> None:
    """Open the lab's page at ``size``, wait for its framed view and charts, save ``path``."""
    known = set(lab.server.get_clients())
    page = browser.new_page(viewport={"width": size[0], "height": size[1]})
    page.set_default_timeout(PATIENCE * 1000)  # a click, a screenshot: Playwright's 30 s
    try:
        page.goto(lab.url)
        _until(lambda: new_page_client(lab, known) is not None, "the page to connect")
        client = new_page_client(lab, known)
        _until(lambda: camera.shown(client) is not None, "the lesson's framed view")
        _until(lambda: page.get_by_text("Try this").count() > 0, "the lesson's controls")
        notice = page.locator(".mantine-Notification-root", has_text="WebGL")
        if notice.count():
            notice.first.locator("button").click()
            _until(lambda: notice.count() == 0, "the WebGL notice to close")
        page.screenshot(path=str(path))
    finally:
        page.close()


def take(out: Path, lessons: Sequence[str] = ()) -> list[Path]:
    """Save a picture of each of ``lessons`` (default: all, in the switcher's order) and
    one on a phone into ``out``; returns the files written."""
    from playwright.sync_api import sync_playwright

    names = list(lessons) or [m.name for m in
                              sorted(all_lessons().values(), key=lambda m: m.sort_key)]
    out.mkdir(parents=True, exist_ok=True)
    written = []
    # (the full look: the pictures show what a page drawing on a GPU shows, armlab.app.page.look)
    with Lab(ServeOptions(http_port=0, lesson=names[0], plain_on_software=False)) as lab, \
            sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), headless=True,
                                     args=CHROMIUM_ARGS)
        try:
            for name in names:
                lab.switch(name)
                written.append(out / f"{name}.png")
                _picture(lab, browser, SIZE, written[-1])
            lab.switch(names[0])
            written.append(out / "phone.png")
            _picture(lab, browser, PHONE, written[-1])
        finally:
            browser.close()
    return written


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("lessons", nargs="*", help="lesson names (default: every lesson)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "img")
    args = parser.parse_args(argv)
    if not CHROMIUM.exists():
        print(f"no Chromium at {CHROMIUM}: apt-get install chromium", file=sys.stderr)
        return 1
    for path in take(args.out, args.lessons):
        print(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
