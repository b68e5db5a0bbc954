"""Fixtures shared by the tests that serve the lab (helpers: tests/_helpers.py).

Imports happen inside the fixtures, so tests that use none of them start fast.
"""

from __future__ import annotations

import pytest
from hypothesis import settings

# Property tests draw the same examples on every run (``derandomize``): the suite must
# give the same verdict on every machine and every run. (A random draw once found a
# start pose at the stretched, singular elbow that the IK reaches only to 0.25 mm; to
# explore afresh, run with ``--hypothesis-profile=explore``.)
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("ci")


@pytest.fixture(scope="module", autouse=True)
def _switch_interval():
    """Each module starts with the interpreter's thread switch interval as the run began:
    a lab and a real-time loop lower it for their process (armlab.app.server, armlab.control.loop),
    and
    a module's timing must not depend on which modules ran before it."""
    import sys

    interval = sys.getswitchinterval()
    yield
    sys.setswitchinterval(interval)


@pytest.fixture(scope="module")
def lab():
    """The whole lab on a free port (one per test module)."""
    from armlab.app.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0)) as running:
        yield running


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium (Playwright driving ``$ARMLAB_CHROMIUM``, default Debian's
    /usr/bin/chromium); the test is skipped, with a message, where it is not installed."""
    from _helpers import CHROMIUM, CHROMIUM_ARGS

    if not CHROMIUM.exists():
        pytest.skip(f"no Chromium at {CHROMIUM}: install it (apt-get install chromium) or set "
                    "ARMLAB_CHROMIUM to run the browser tests")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as pw:
        chromium = pw.chromium.launch(executable_path=str(CHROMIUM), headless=True,
                                      args=CHROMIUM_ARGS)
        try:
            yield PatientBrowser(chromium)
        finally:
            chromium.close()


#: ms a page waits for an element to be actionable (visible, enabled and standing still
#: for two animation frames) before a click fails. Playwright's 30 s ran out once on a
#: loaded machine, where a software-rendered 3D page draws a frame in seconds.
ACTION_TIMEOUT_MS = 120_000


class PatientBrowser:
    """The Chromium the tests drive, whose new pages and contexts wait
    :data:`ACTION_TIMEOUT_MS` for an element before they give up."""

    def __init__(self, chromium) -> None:
        self._chromium = chromium

    def new_page(self, **kwargs):
        page = self._chromium.new_page(**kwargs)
        page.set_default_timeout(ACTION_TIMEOUT_MS)
        return page

    def new_context(self, **kwargs):
        context = self._chromium.new_context(**kwargs)
        context.set_default_timeout(ACTION_TIMEOUT_MS)
        return context

    def __getattr__(self, name: str):
        return getattr(self._chromium, name)
