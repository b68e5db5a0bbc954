"""What a person types into a number field, in real headless Chromium: the page's one
rule (armlab.app.page.inputs.typed_value) seen from the keyboard. "1e9" typed into Kp used
to become "19" without a word (Mantine's field drops the "e") and the lab applied 19; now
the exponent is shown under the field as it is typed, Tab sets the field to 1000000000,
and the lab applies the end of Kp's range, 200, telling the page so. A key no number
takes is named under the field, which keeps its value."""

from __future__ import annotations

import pytest
from _helpers import wait_for

from armlab.app.page.inputs import LIMIT_TITLE

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

KP = "Kp (1/s²)"
#: Marks the number field in the row of the label given (data-testid="typed").
MARK_JS = """(label) => {
  const l = [...document.querySelectorAll('label')].find(e => e.textContent.trim() === label);
  if (!l) return false;
  for (let row = l.parentElement; row; row = row.parentElement) {
    const f = row.querySelector('.mantine-NumberInput-input');
    if (f) { f.dataset.testid = 'typed'; return true; }
  }
  return false;
}"""
NOTE_JS = """() => { const n = document.querySelector('[data-armlab="number-note"]');
  return n ? n.textContent : null; }"""


def _kp_field(browser, lab):  # noqa: ANN001, ANN202
    pg = browser.new_page(viewport={"width": 1280, "height": 900})
    pg.goto(lab.url)
    pg.get_by_role("tab", name="Gains").click(timeout=120_000)
    wait_for(lambda: pg.evaluate(MARK_JS, KP), 60, "the Kp field", every=0.5)
    return pg, pg.locator('[data-testid="typed"]')


def _loop(lab):  # noqa: ANN001, ANN202
    return lab.lesson.rig.loop


def _done(pg, lab, kp0: float) -> None:  # noqa: ANN001
    """Close the page and put Kp back as the test found it."""
    pg.close()
    lab.lesson.gains.sliders["kp"].set(kp0)
    wait_for(lambda: _loop(lab).params.kp == kp0, 30, "Kp back")


def test_an_exponent_typed_is_shown_then_applied_as_the_range_allows(browser, lab):
    loop = _loop(lab)
    kp0 = loop.params.kp
    pg, field = _kp_field(browser, lab)
    try:
        field.click()
        field.press("Control+a")
        field.press_sequentially("1e9")
        wait_for(lambda: pg.evaluate(NOTE_JS) == "1e9 = 1000000000: Enter sets it, Esc drops it",
                 30, "the exponent shown under the field", every=0.2)
        assert field.input_value() == "1"  # (the field never saw "e9": never "19")
        field.press("Tab")
        wait_for(lambda: loop.params.kp == 200.0, 60, "Kp 200 in the loop", every=0.2)
        note = pg.get_by_text("Kp: 1e+09 is above the largest value, 200; set to 200.")
        note.wait_for(timeout=60_000)
        assert pg.get_by_text(LIMIT_TITLE).first.is_visible()
        wait_for(lambda: field.input_value() == "200", 30, "the field showing 200", every=0.2)
        assert pg.evaluate(NOTE_JS) is None
        assert loop.params.kp != 19.0
    finally:
        _done(pg, lab, kp0)


def test_esc_drops_an_exponent_and_a_key_no_number_takes_is_named(browser, lab):
    loop = _loop(lab)
    kp0 = loop.params.kp
    pg, field = _kp_field(browser, lab)
    try:
        field.click()
        field.press("Control+a")
        field.press_sequentially("3e2")
        field.press("Escape")
        wait_for(lambda: pg.evaluate(NOTE_JS) is None, 30, "the exponent dropped", every=0.2)
        assert field.input_value() == "3"
        wait_for(lambda: loop.params.kp == 3.0, 60, "Kp 3 in the loop", every=0.2)
        field.press_sequentially("x")
        wait_for(lambda: (pg.evaluate(NOTE_JS) or "").startswith("“x” cannot be typed"),
                 30, "the key named", every=0.2)
        assert field.input_value() == "3"
    finally:
        _done(pg, lab, kp0)


def test_digits_typed_past_the_range_give_one_message_naming_the_last(browser, lab):
    """"999999" typed sends 999, 9999, ... as it goes: one message, updated, naming the
    value the lab applied for the last (not six, nor "kept 19")."""
    loop = _loop(lab)
    kp0 = loop.params.kp
    pg, field = _kp_field(browser, lab)
    try:
        field.click()
        field.press("Control+a")
        field.press_sequentially("999999", delay=120)
        wait_for(lambda: loop.params.kp == 200.0, 60, "Kp 200 in the loop", every=0.2)
        last = pg.get_by_text("Kp: 999999 is above the largest value, 200; set to 200.")
        last.wait_for(timeout=60_000)
        assert pg.get_by_text(LIMIT_TITLE).count() == 1
        assert pg.get_by_text("Value refused").count() == 0
    finally:
        _done(pg, lab, kp0)
