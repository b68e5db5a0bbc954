"""A classroom in real Chromium: a teacher's page and a student's page (two browsers, as
on two machines) on one lab served with roles (armlab/app/classroom)."""

from __future__ import annotations

import pytest
from _helpers import ACTION_TIMEOUT_MS, wait_for

from armlab.app.lab.server import Lab, ServeOptions
from armlab.control.params import DEFAULT

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]

KP = "Kp (1/s²)"
#: s to wait for what a page did to reach the server: as long as a page waits for an
#: element (software WebGL on a loaded 2-core machine draws a frame in seconds)
PAGE_S = ACTION_TIMEOUT_MS / 1000


@pytest.fixture(scope="module")
def classroom():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        yield lab


def _open(browser, lab: Lab):  # noqa: ANN001, ANN202
    context = browser.new_context(viewport={"width": 1440, "height": 900})
    page = context.new_page()
    page.goto(lab.local_url)
    page.get_by_role("button", name="Run thesis line").wait_for()
    page.get_by_text("Following the teacher").first.wait_for()
    return context, page


def _labelled(page, label: str):  # noqa: ANN001, ANN202
    """The shown control labelled ``label`` (a page showing its own arm keeps the shared
    lesson's controls, hidden)."""
    target = page.locator("label:visible", has_text=label).first.get_attribute("for")
    return page.locator(f"[id='{target}']")


def _text_field(page, label: str):  # noqa: ANN001, ANN202
    """The text input in the row labelled ``label`` (viser's text rows carry no input id)."""
    return page.locator(f"xpath=//label[normalize-space()='{label}']"
                        "/ancestor::div[.//input][1]//input").first


def _pick(page, label: str, option: str) -> None:  # noqa: ANN001
    page.get_by_label(label).first.click()
    page.get_by_role("option", name=option, exact=True).click()


def test_a_class_teacher_and_student_pages(browser, other_browser, classroom):
    lab = classroom
    loop = shared = lab.lesson.rig.loop
    teacher_ctx, teacher = _open(browser, lab)
    student_ctx, student = _open(other_browser, lab)  # the student's machine
    try:
        # A wrong passcode is refused with a message; the right one makes a presenter.
        _text_field(teacher, "Passcode").fill("WRONGCOD")
        teacher.get_by_text("that is not the passcode").first.wait_for()
        _text_field(teacher, "Passcode").fill(lab.roles.passcode)
        teacher.get_by_text("You present.").first.wait_for()
        wait_for(lambda: len(lab.roles.presenters()) == 1, PAGE_S, "one presenter")
        assert teacher.locator("label", has_text="Passcode").count() == 0

        # The student moves the shared Kp slider: refused, told, and put back on the page.
        kp0 = loop.params.kp
        student.get_by_role("tab", name="Gains").click()
        thumb = _labelled(student, KP).locator("[role=slider]")
        thumb.focus()
        for _ in range(5):
            student.keyboard.press("ArrowRight")
        student.get_by_text("Only the presenter changes the shared arm").first.wait_for()
        wait_for(lambda: float(thumb.get_attribute("aria-valuenow")) == pytest.approx(kp0), PAGE_S,
                 "the student's slider back at the shared value")
        assert loop.params.kp == kp0

        # The teacher's move of the same slider reaches the shared arm.
        teacher.get_by_role("tab", name="Gains").click()
        t_thumb = _labelled(teacher, KP).locator("[role=slider]")
        t_thumb.focus()
        teacher.keyboard.press("ArrowRight")
        wait_for(lambda: loop.params.kp == pytest.approx(kp0 + 0.1), PAGE_S, "the teacher's Kp")

        # Any page may press E-STOP: the student's stops the shared arm; the teacher is
        # told who; only the teacher's Reset goes through.
        _text_field(student, "Your name").fill("Ayu")
        wait_for(lambda: "Ayu" in [lab.roles.name(c) for c in lab.server.get_clients()], PAGE_S,
                 "the student's name")
        student.get_by_role("button", name="E-STOP").click()
        wait_for(lambda: loop.status.estopped and not loop.status.torque_on, PAGE_S, "the e-stop")
        teacher.get_by_text("pressed by Ayu").first.wait_for()
        student.get_by_role("tab", name="Run").click()
        student.get_by_role("button", name="Reset").click()
        wait_for(lambda: lab.roles.refused >= 2, PAGE_S, "the student's Reset refused")
        assert loop.status.estopped
        teacher.get_by_role("tab", name="Run").click()
        teacher.get_by_role("button", name="Reset").click()
        wait_for(lambda: loop.status.torque_on and not loop.status.estopped, PAGE_S, "reset")

        # "My arm": the student's own lesson, on the student's page only.
        _pick(student, "View", "My arm")
        wait_for(lambda: len(lab.room.private_lessons()) == 1, PAGE_S, "the student's own lesson")
        ((sid, mine),) = lab.room.private_lessons().items()
        student.get_by_text("My arm.").first.wait_for()
        kp_shared, kp_mine = shared.params.kp, mine.rig.loop.params.kp  # (its own start)
        student.get_by_role("tab", name="Gains").click()
        thumb = _labelled(student, KP).locator("[role=slider]")
        thumb.focus()
        for _ in range(5):
            student.keyboard.press("ArrowRight")
        wait_for(lambda: mine.rig.loop.params.kp == pytest.approx(kp_mine + 0.5), PAGE_S,
                 "the student's own Kp")
        assert shared.params.kp == kp_shared  # the teacher's arm did not move

        # The presenter's overview lists the student; "Use these gains" copies them.
        teacher.get_by_text("Ayu").first.wait_for()
        _pick(teacher, "Student", f"Ayu (#{sid})")
        teacher.get_by_role("button", name="Use these gains").click()
        wait_for(lambda: shared.params.kp == pytest.approx(kp_mine + 0.5), PAGE_S,
                 "the shared arm at the student's Kp")
        teacher_ctx.close()  # done with: the reload need not share the CPU with its page

        # A reload of the student's page returns to the same arm, gains kept.
        # (The reloaded page is a new client: until the server has seen the old one go,
        # the old page's lesson still holds the arm, so the wait names the new page.)
        own = mine.rig.loop
        student.reload()
        wait_for(lambda: any(cid != sid and lesson.rig is not None and lesson.rig.loop is own
                             for cid, lesson in lab.room.private_lessons().items()), 240,
                 lambda: f"the same private arm after the reload; pages: {lab.room.pages()}")
        student.get_by_text("My arm.").first.wait_for()
        assert own.params.kp == pytest.approx(kp_mine + 0.5)
    finally:
        teacher_ctx.close()
        student_ctx.close()
    lab.lesson.gains.set_params(DEFAULT)





def test_the_presenter_link_presents_without_showing_the_passcode(browser, classroom):
    lab = classroom
    before = set(lab.roles.presenters())
    context = browser.new_context(viewport={"width": 1440, "height": 900})
    page = context.new_page()
    try:
        page.goto(f"{lab.local_url}&presenter={lab.roles.passcode}")  # as armlab serve prints
        page.get_by_text("You now change the shared arm").first.wait_for(timeout=180_000)
        assert "presenter=" not in page.url and lab.roles.passcode not in page.url
        wait_for(lambda: len(set(lab.roles.presenters()) - before) == 1, PAGE_S, "a presenter")
        assert page.locator("label", has_text="Passcode").count() == 0
    finally:
        context.close()


#: The url under the students' QR code: whether all of it lies inside the panel (its box
#: within the scrolling panel's, and none of its text scrolled or cut inside the box).
URL_WHOLE_JS = """(url) => {
  const el = [...document.querySelectorAll('div')].find(
    d => d.children.length === 0 && d.textContent.trim() === url);
  if (!el) return 'no url shown';
  const panel = el.closest('.mantine-ScrollArea-viewport') || document.body;
  const r = el.getBoundingClientRect(), p = panel.getBoundingClientRect();
  if (r.left < p.left - 1 || r.right > p.right + 1) {
    return `off the panel: ${r.left}..${r.right} in ${p.left}..${p.right}`;
  }
  if (el.scrollWidth > el.clientWidth + 1) return `cut: ${el.scrollWidth} > ${el.clientWidth}`;
  return '';
}"""


@pytest.mark.parametrize("size", [(1280, 720), (390, 844)], ids=["1280x720", "390x844"])
def test_a_loopback_class_tells_its_presenter_and_the_url_is_whole(browser, classroom, size):
    """Started without --host, the class listens on 127.0.0.1: the presenter's page says,
    above the QR code, that phones cannot join and what to pass; the url under the code
    is whole at every width; the page's labels name their fields."""
    lab = classroom
    assert lab.host == "127.0.0.1"
    context = browser.new_context(viewport={"width": size[0], "height": size[1]})
    page = context.new_page()
    try:
        page.goto(f"{lab.local_url}&presenter={lab.roles.passcode}")
        page.get_by_text("You now change the shared arm").first.wait_for(timeout=180_000)
        alert = page.get_by_role("alert").filter(has_text="Phones cannot join")
        alert.wait_for(timeout=60_000)  # (the folder opens itself on loopback)
        alert.scroll_into_view_if_needed()
        assert "--host 0.0.0.0" in alert.inner_text() and alert.is_visible()
        wait_for(lambda: page.evaluate(URL_WHOLE_JS, lab.url) == "", PAGE_S,
                 "the url under the QR code whole", every=0.5)
        # the page's labels are tied to their fields (viser's text rows carry no input id)
        name = page.get_by_label("Your name")
        wait_for(lambda: name.count() == 1, PAGE_S, "the name field found by its label",
                 every=0.5)
        assert name.evaluate("e => e.tagName") == "INPUT"
        page.get_by_text("Your name", exact=True).click()
        wait_for(lambda: name.evaluate("e => document.activeElement === e"), PAGE_S,
                 "a click on the label to focus its field", every=0.2)
    finally:
        context.close()
