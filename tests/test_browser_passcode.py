"""The classroom's Passcode field in real Chromium: masked as a password field on every
page, and the passcode typed into it still makes a presenter (armlab/app/classroom/room.py,
armlab/app/viser_ext/page_scripts.py)."""

from __future__ import annotations

import pytest
from _helpers import wait_for

from armlab.app.lab.server import Lab, ServeOptions

pytestmark = [pytest.mark.browser, pytest.mark.timeout(1800)]

#: the passcode input: the input in the row of the label "Passcode"
FIELD = "xpath=//label[normalize-space()='Passcode']/ancestor::div[.//input][1]//input"


@pytest.fixture(scope="module")
def classroom():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        yield lab


def _open(browser, lab: Lab):  # noqa: ANN001, ANN202
    context = browser.new_context(viewport={"width": 1024, "height": 700})
    page = context.new_page()
    page.goto(lab.local_url)
    page.locator(FIELD).first.wait_for(state="attached", timeout=600_000)
    return context, page


def _masked(page) -> bool:  # noqa: ANN001
    """Whether the page's Passcode input shows dots: a password input (or one whose text
    the browser draws as discs)."""
    return bool(page.locator(FIELD).first.evaluate(
        "el => el.type === 'password' || "
        "getComputedStyle(el).webkitTextSecurity in {disc: 1, circle: 1, square: 1}"))


def _present(page, code: str) -> None:  # noqa: ANN001
    """Type ``code`` key by key into the page's Passcode field."""
    field = page.locator(FIELD).first
    field.click()
    field.press_sequentially(code)


def test_the_passcode_field_is_masked_on_every_page_and_still_works(browser, classroom):
    """Two pages, one after the other (two software-rendered pages at once are too slow
    on a loaded machine): each shows its Passcode field masked, and the passcode typed
    into it makes the page a presenter; a wrong one is refused and the field stays
    masked."""
    lab = classroom
    for k in range(2):
        context, page = _open(browser, lab)
        try:
            wait_for(lambda page=page: _masked(page), 600, "the Passcode field masked")
            if k == 0:
                _present(page, "WRONGCOD")
                page.get_by_text("that is not the passcode").first.wait_for(timeout=600_000)
                assert _masked(page)
                assert lab.roles.presenters() == ()
            before = set(lab.roles.presenters())  # (a closed page presents no more)
            _present(page, lab.roles.passcode)
            wait_for(lambda before=before: set(lab.roles.presenters()) - before, 600,
                     "the page presenting")
            page.get_by_text("You present.").first.wait_for(timeout=600_000)
        finally:
            context.close()
