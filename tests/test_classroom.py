"""Roles in a classroom (armlab/app/classroom/roles.py): only the presenter changes the shared arm.

The server refuses, it does not merely hide: these tests send what a hand-made
websocket client would (armlab/app/testing/wsclient.py speaks the page's protocol) to a real lab on
a free loopback port.
"""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import my_arm_in, wait_for

from armlab.app.classroom.roles import (
    PASSCODE_ALPHABET,
    PASSCODE_LENGTH,
    Guesses,
    new_passcode,
    normal_passcode,
    qr_svg,
)
from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.testing.wsclient import HeadlessClient
from armlab.control.params import DEFAULT
from armlab.control.runs import read_run


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_passcodes_are_random_and_readable():
    codes = {new_passcode() for _ in range(50)}
    assert len(codes) == 50
    for code in codes:
        assert len(code) == PASSCODE_LENGTH >= 6 and set(code) <= set(PASSCODE_ALPHABET)
    assert not set("O0I1l") & set(PASSCODE_ALPHABET)  # nothing to mistake on a projector
    assert normal_passcode(" abcd-efgh ") == "ABCDEFGH"


def test_wrong_guesses_are_slowed_down_and_a_right_one_clears_them():
    clock = FakeClock()
    g = Guesses(free=3, base=1.0, cap=8.0, clock=clock)
    assert [g.wrong("10.0.0.7") for _ in range(3)] == [0.0, 0.0, 0.0]
    assert g.wait_left("10.0.0.7") == 0.0
    assert [g.wrong("10.0.0.7") for _ in range(5)] == [1.0, 2.0, 4.0, 8.0, 8.0]  # capped
    assert g.wait_left("10.0.0.7") == pytest.approx(8.0)
    assert g.wait_left("10.0.0.8") == 0.0  # another address is not held back
    clock.t += 8.0
    assert g.wait_left("10.0.0.7") == 0.0
    g.right("10.0.0.7")
    assert g.wrong("10.0.0.7") == 0.0  # counting starts again


def test_qr_code_is_an_svg_of_the_url():
    svg = qr_svg("http://192.168.1.20:8080/?token=abcdefgh12345678")
    assert svg.lstrip().startswith("<svg") and "</svg>" in svg and "path" in svg


@pytest.fixture(scope="module")
def classroom():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        yield lab


def _page(lab: Lab) -> HeadlessClient:
    page = HeadlessClient(lab.local_url.replace("http://", "ws://")).connect()
    page.wait_for(lambda: _has(page, "Passcode") and _has(page, "Kp (1/s²)"), 60.0,
                  "the Passcode field and the Kp slider")
    return page


def _has(page: HeadlessClient, label: str) -> bool:
    return any(e.label == label for e in page.gui.values())


@pytest.mark.slow
def test_a_student_cannot_change_the_shared_arm_the_presenter_can(classroom):
    lab = classroom
    loop = lab.lesson.rig.loop
    kp0 = loop.params.kp
    with _page(lab) as student, _page(lab) as teacher:
        # A forged update of the shared Kp slider, as a hand-made websocket message:
        # refused, with one message, and the student's slider shows the server's value.
        student.set_value("Kp (1/s²)", kp0 + 7.0)
        body = student.wait_notification("Only the presenter changes the shared arm")
        assert "Passcode" in body
        student.wait_for(lambda: student.find("Kp (1/s²)").value == pytest.approx(kp0), 30.0,
                         "the student's slider put back")
        # Run, the lesson switcher and a drag in the shared scene are refused as well.
        student.click("Run thesis line")
        student.set_value("Lesson", "no matter")
        student.move_gizmo(lab.lesson.rig.scene.target.name, [(0.3, 0.0, 0.5)])
        wait_for(lambda: lab.roles.refused >= 4, 30, "four refusals")
        assert loop.params.kp == kp0 and lab.lesson_name == "compliance"
        assert loop.status.trajectory is None

        # A wrong passcode is refused with a message; the right one makes a presenter.
        teacher.set_value("Passcode", "WRONGCOD")
        assert "not the passcode" in teacher.wait_notification("Passcode refused")
        teacher.set_value("Passcode", lab.roles.passcode.lower())
        teacher.wait_notification("You present")
        teacher.wait_for(lambda: not _has(teacher, "Passcode"), 30.0, "the field gone")
        teacher.wait_for(lambda: _has_html(teacher, "<svg"), 30.0, "the QR code")
        teacher.set_value("Kp (1/s²)", kp0 + 7.0)
        wait_for(lambda: loop.params.kp == pytest.approx(kp0 + 7.0), 30, "the presenter's Kp")
        # Still refused from the student after that.
        student.set_value("Kp (1/s²)", kp0 + 1.0)
        wait_for(lambda: lab.roles.refused >= 5, 30, "the student refused again")
        assert loop.params.kp == pytest.approx(kp0 + 7.0)
        teacher.set_value("Kp (1/s²)", DEFAULT.kp)
        wait_for(lambda: loop.params.kp == pytest.approx(DEFAULT.kp), 30, "Kp back")


def _has_html(page: HeadlessClient, text: str) -> bool:
    return any(text in str(e.props.get("content", "")) for e in page.gui.values())


def test_a_students_estop_stops_the_shared_arm_and_the_presenter_sees_who(classroom):
    lab = classroom
    with _page(lab) as teacher, _page(lab) as student:
        teacher.set_value("Passcode", lab.roles.passcode)
        teacher.wait_notification("You present")
        student.set_value("Your name", "Ayu")
        wait_for(lambda: "Ayu" in [lab.roles.name(c) for c in lab.server.get_clients()], 30,
                 "the student's name")
        student.click("E-STOP")
        wait_for(lambda: lab.lesson.rig.loop.status.estopped, 30, "the shared arm stopped")
        assert "Ayu" in teacher.wait_notification("E-STOP")
        # Only a presenter resets.
        refused = lab.roles.refused
        student.click("Reset")
        wait_for(lambda: lab.roles.refused > refused, 30, "the student's Reset refused")
        assert lab.lesson.rig.loop.status.estopped
        teacher.click("Reset")
        wait_for(lambda: not lab.lesson.rig.loop.status.estopped, 30, "the presenter's Reset")


def test_the_presenter_link_presents_at_once_and_a_stale_one_is_refused(classroom):
    lab = classroom
    loop = lab.lesson.rig.loop
    kp0 = loop.params.kp
    # the page the link opens: a redirect to the url without the passcode, leaving it in
    # an HttpOnly cookie (tests/test_gate.py reads the HTTP side)
    assert lab.presenter_url == f"{lab.url}&presenter={lab.roles.passcode}"
    ws = lab.local_url.replace("http://", "ws://")
    name = lab.gate.presenter_cookie  # armlab_presenter_<this start>
    assert name.startswith("armlab_presenter_")
    cookie = {"Cookie": f"{name}={lab.roles.passcode}"}
    with HeadlessClient(ws, headers=cookie).connect() as teacher:
        teacher.wait_notification("You present")
        teacher.wait_for(lambda: not _has(teacher, "Passcode"), 30.0, "the field gone")
        teacher.wait_for(lambda: _has_html(teacher, "<svg"), 30.0, "the QR code")
        teacher.set_value("Kp (1/s²)", kp0 + 3.0)
        wait_for(lambda: loop.params.kp == pytest.approx(kp0 + 3.0), 30, "the presenter's Kp")
        teacher.set_value("Kp (1/s²)", kp0)
        wait_for(lambda: loop.params.kp == pytest.approx(kp0), 30, "Kp back")
    # a wrong code in this start's cookie (made by hand): refused with a message and
    # counted as a guess; no role
    forged = {"Cookie": f"{name}=WRONGCOD"}
    with HeadlessClient(ws, headers=forged).connect() as page:
        assert "not the passcode" in page.wait_notification("Presenter link refused")
        page.wait_for(lambda: _has(page, "Passcode"), 30.0, "the Passcode field kept")
        assert lab.roles.presenters() == ()
    lab.roles.guesses.right("127.0.0.1")  # the next tests start without that wrong guess
    # a link of an earlier start (another cookie name): not read at all, nothing said
    stale = {"Cookie": f"armlab_presenter_0badcafe={lab.roles.passcode}"}
    before = set(lab.server.get_clients())
    with HeadlessClient(ws, headers=stale).connect() as page:
        page.wait_for(lambda: _has(page, "Passcode"), 30.0, "the Passcode field")
        (client,) = [c for i, c in lab.server.get_clients().items() if i not in before]
        # a question the page answers after everything its welcome sent it
        client.local_storage.get_item("anything", timeout=30.0)
        assert lab.roles.presenters() == ()
        assert not any(t == "Presenter link refused" for t, _ in page.notifications)


@pytest.mark.slow
def test_guesses_from_one_address_are_slowed_down():
    with Lab(ServeOptions(http_port=0, classroom=True, lesson="ik_accuracy")) as lab:
        # a wait no loaded machine outlasts
        lab.roles.guesses = Guesses(free=3, base=600.0, cap=600.0)
        with HeadlessClient(lab.local_url.replace("http://", "ws://")).connect() as page:
            page.wait_for(lambda: _has(page, "Passcode"), 60.0, "the Passcode field")

            def refusals() -> list[str]:
                return [b for t, b in page.notifications if t == "Passcode refused"]

            for i in range(4):  # one guess at a time, as a person types them
                page.set_value("Passcode", f"BADCODE{i}")
                page.wait_for(lambda n=i + 1: len(refusals()) == n, 30.0, f"refusal {i + 1}")
            assert "next try in 600 s" in refusals()[-1] and "next try" not in refusals()[-2]
            page.set_value("Passcode", lab.roles.passcode)  # right, but too soon: not compared
            page.wait_for(lambda: len(refusals()) == 5, 30.0, "the right code refused: too soon")
            assert "try again in" in refusals()[-1]
            assert lab.roles.presenters() == ()


def test_without_classroom_there_are_no_roles(lab):
    assert lab.roles is None
    with HeadlessClient(lab.local_url.replace("http://", "ws://")).connect() as page:
        page.wait_for(lambda: _has(page, "Kp (1/s²)"), 60.0, "the Kp slider")
        assert not _has(page, "Passcode")


def _joined(lab: Lab) -> tuple[HeadlessClient, int]:
    """A page of ``lab`` and its client id."""
    before = set(lab.server.get_clients())
    page = _page(lab)
    page.wait_for(lambda: bool(set(lab.server.get_clients()) - before), 30.0, "the client")
    (cid,) = set(lab.server.get_clients()) - before
    return page, cid


@pytest.mark.slow
def test_my_arm_is_private(classroom):
    lab = classroom
    shared = lab.lesson.rig.loop
    kp_shared = shared.params.kp
    a, a_id = _joined(lab)
    b, b_id = _joined(lab)
    with a, b:
        a.set_value("View", "My arm")
        b.set_value("View", "My arm")
        wait_for(lambda: lab.room.private_lesson(a_id) is not None
                 and lab.room.private_lesson(b_id) is not None, 60, "two private lessons")
        mine, theirs = lab.room.private_lesson(a_id), lab.room.private_lesson(b_id)
        assert mine.rig.loop is not theirs.rig.loop is not shared
        wait_for(lambda: mine.rig.loop.status.running and mine.rig.loop.status.t > 0.2, 60,
                 "the private loop running")
        # Student A's own Kp slider moves A's arm only.
        a.set_value(mine.gains.sliders["kp"].handle, kp_shared + 9.0)
        wait_for(lambda: mine.rig.loop.params.kp == pytest.approx(kp_shared + 9.0), 30,
                 "A's Kp")
        assert theirs.rig.loop.params.kp == kp_shared and shared.params.kp == kp_shared
        # A forged update of the shared slider from A's page is still refused.
        refused = lab.roles.refused
        a.set_value(lab.lesson.gains.sliders["kp"].handle, kp_shared + 3.0)
        wait_for(lambda: lab.roles.refused > refused, 30, "the forged update refused")
        assert shared.params.kp == kp_shared
        # A's step test runs on A's arm (its recorder), not the shared one.
        mine.run_step()
        wait_for(lambda: mine.measured_pd is not None, 60,
                 lambda: f"A's step measured (Tp, %OS, Ts); the loop: {mine.rig.loop.status}, "
                         f"the step: {mine.experiment}, said: {mine.last_run_text!r}")
        assert lab.lesson.measured_pd is None and theirs.measured_pd is None
        # Back to following: the private lesson closes, the arm is kept for the seat.
        a.set_value("View", "Follow the teacher")
        wait_for(lambda: lab.room.private_lesson(a_id) is None, 30, "A following again")
        assert lab.room.sandboxes.n_arms == 2
    wait_for(lambda: not lab.room.private_lesson(b_id), 30, "B's page gone")


@pytest.mark.slow
def test_a_full_class_says_so():
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        lab.room.sandboxes.max_arms = 1
        a, a_id = _joined(lab)
        b, b_id = _joined(lab)
        with a, b:
            a.set_value("View", "My arm")
            wait_for(lambda: lab.room.private_lesson(a_id) is not None, 60, "A's own lesson")
            b.set_value("View", "My arm")
            assert "the class is full" in b.wait_notification("The class is full")
            b.wait_for(lambda: b.find("View").value == "Follow the teacher", 30.0,
                       "B back to following")
            assert lab.room.private_lesson(b_id) is None


@pytest.mark.slow
def test_a_disconnect_mid_drag_lets_go_of_the_students_arm(classroom):
    from armlab.kinematics.fk import fk

    lab = classroom
    page, cid = _joined(lab)
    page.set_value("View", "My arm")
    wait_for(lambda: lab.room.private_lesson(cid) is not None, 60, "the page's own lesson")
    mine = lab.room.private_lesson(cid)
    loop, model = mine.rig.loop, mine.rig.model
    wait_for(lambda: loop.status.active and len(loop.recorder.snapshot(0.1)["t"]) > 0, 60,
             "the arm held")

    def deflection() -> float:  # |θ_cmd − θ|, the most of any joint, rad
        snap = loop.recorder.snapshot(0.1)
        return float(abs(snap["error"][-1]).max())

    hand = fk(model, loop.recorder.snapshot(0.1)["q"][-1])[:3, 3]
    mine._on_drag("start", hand + [0.0, 0.0, 0.12])  # what the hand's drag callback does
    wait_for(lambda: deflection() > 0.03, 60, "the arm pulled by the drag")
    pulled = deflection()
    page.close()  # the page goes away mid-drag
    wait_for(lambda: lab.room.private_lesson(cid) is None, 60, "the page's lesson closed")
    wait_for(lambda: deflection() < pulled / 4, 60, "the arm let go of")
    assert loop.status.fault is None and loop.status.running  # kept for a reload


def test_bad_values_to_a_students_own_controls_change_nothing(classroom):
    lab = classroom
    page, cid = _joined(lab)
    with page:
        page.set_value("View", "My arm")
        wait_for(lambda: lab.room.private_lesson(cid) is not None, 60, "the page's own lesson")
        mine = lab.room.private_lesson(cid)
        kp = mine.rig.loop.params.kp
        shared_kp = lab.lesson.rig.loop.params.kp
        slider = mine.gains.sliders["kp"].handle
        for bad in (float("nan"), float("inf"), "twenty", [1, 2]):
            page.set_value(slider, bad)
        page.wait_for(lambda: sum(t == "Value refused" for t, _ in page.notifications) >= 1,
                      30.0, "the refusal")
        page.send({"type": "GuiUpdateMessage", "uuid": slider._impl.uuid,
                   "updates": {"value": kp + 1.0}})  # a good value still goes through
        wait_for(lambda: mine.rig.loop.params.kp == pytest.approx(kp + 1.0), 30, "the good Kp")
        assert lab.lesson.rig.loop.params.kp == shared_kp


@pytest.mark.timeout(900)  # five lessons and a third worker process
@pytest.mark.slow
def test_my_arm_in_the_other_arm_lessons_is_private_too():
    """The IK-accuracy, redundancy, any-arm, hand and quadruped lessons offer My arm as
    well: a student's control moves their own copy, never the shared one."""
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        page, cid = _joined(lab)
        with page:
            mine = my_arm_in(lab, page, cid, "ik_accuracy")
            page.set_value(mine.x_input, 5.0)
            wait_for(lambda: mine.target[0] == pytest.approx(0.05), 30, "the own target X")
            assert lab.lesson.target[0] == pytest.approx(0.02)

            mine = my_arm_in(lab, page, cid, "redundancy")
            k_a = lab.lesson.k_a.handle.value
            page.set_value(mine.k_a.handle, k_a + 100.0)
            wait_for(lambda: mine.k_a.handle.value == pytest.approx(k_a + 100.0), 30,
                     "the own k_a")
            assert lab.lesson.k_a.handle.value == k_a

            mine = my_arm_in(lab, page, cid, "arm")
            shared = lab.lesson.loop
            assert mine.loop is not shared and mine.loop is lab.room.sandboxes.loop_of(
                lab.room._pages[cid].seat)
            page.set_value(mine.sliders[0], 20.0)
            wait_for(lambda: abs(_q(mine.loop)[0] - np.radians(20.0)) < np.radians(2.0), 60,
                     "the own arm's first joint at 20°")
            assert abs(_q(shared)[0]) < np.radians(2.0)

            mine = my_arm_in(lab, page, cid, "hand")  # the class's hands, one loop for all
            shared = lab.lesson.loop
            page.set_value(mine.force.handle, 0.5)
            wait_for(lambda: mine.loop.params.force_limit == 0.5, 30, "the own force limit")
            page.click(mine.close_button)
            wait_for(lambda: mine.loop.status.modes != ("idle",) * 3, 30, "the own hand closing")
            assert shared.params.force_limit == 0.8 and shared.status.closed_at is None
            assert mine.loop is not shared and lab.room.sandboxes.n_arms == 1

            # the class's quadrupeds, one clock for all
            mine = my_arm_in(lab, page, cid, "quadruped")
            shared = lab.lesson.loop
            page.click(mine.direction_buttons["forward"])
            wait_for(lambda: mine.loop.status.walking, 60, "the own robot walking")
            wait_for(lambda: len(mine.loop.snapshot(1.0)["t"]) > 10, 60, "its record")
            assert not mine.loop.status.fault and mine.has_servos
            assert not shared.status.walking and mine.loop is not shared


@pytest.mark.slow
def test_a_lesson_without_a_private_copy_keeps_the_page_following(monkeypatch):
    """A lesson without a private copy (``private`` False: a lesson added later) says so
    and keeps the page following the teacher."""
    from dataclasses import replace

    from armlab.app.lessons import catalog

    monkeypatch.setattr(catalog, "LESSONS", tuple(
        replace(lesson, private=False) if lesson.name == "redundancy" else lesson
        for lesson in catalog.LESSONS))
    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        page, cid = _joined(lab)
        with page:
            lab.switch("redundancy")
            page.wait_for(lambda: page.find("View").value == "Follow the teacher", 30.0,
                          "the page following the redundancy lesson")
            page.set_value("View", "My arm")
            assert "no private arm" in page.wait_notification("No private arm here")
            page.wait_for(lambda: page.find("View").value == "Follow the teacher", 30.0,
                          "following again")
            assert lab.room.private_lesson(cid) is None


def _q(loop) -> np.ndarray:  # noqa: ANN001
    """The newest joint angles a loop recorded (NaN before its first period)."""
    snap = loop.recorder.snapshot(0.5)
    return snap["q"][-1] if len(snap["t"]) else np.full(loop.model.n, np.nan)


@pytest.mark.slow
def test_a_page_with_its_own_arm_is_not_sent_the_shared_stream_and_catches_up(classroom):
    """While a page shows My arm the shared lesson's updates are held back from it (the
    server does not serialise them for it); following again, it is sent the latest."""
    lab = classroom
    shared_kp = lab.lesson.gains.sliders["kp"].handle
    kp0 = lab.lesson.rig.loop.params.kp
    student, cid = _joined(lab)
    teacher, witness = _page(lab), _page(lab)  # witness: a page that follows
    uuid = shared_kp._impl.uuid
    with student, teacher, witness:
        teacher.set_value("Passcode", lab.roles.passcode)
        teacher.wait_notification("You present")
        student.set_value("View", "My arm")
        wait_for(lambda: lab.room.private_lesson(cid) is not None, 60, "the page's own lesson")
        assert lab.room.stream.installed and lab.room.stream.is_held(cid)
        teacher.set_value(shared_kp, kp0 + 5.0)
        witness.wait_for(lambda: witness.gui[uuid].value == kp0 + 5.0, 30.0,
                         "a following page shown the new Kp")
        student.wait_for(lambda: student.frames_received > 0, 30.0, "frames")
        frames = student.frames_received
        student.wait_for(lambda: student.frames_received > frames + 10, 30.0,
                         "ten more frames of the student's own lesson")
        assert student.gui[uuid].value == pytest.approx(kp0)  # held back, not sent
        assert lab.room.stream.held > 0
        student.set_value("View", "Follow the teacher")
        student.wait_for(lambda: student.gui[uuid].value == kp0 + 5.0, 30.0,
                         "the student's page caught up with the shared Kp")
        # the catch-up goes out just before the hold is dropped
        wait_for(lambda: not lab.room.stream.is_held(cid), 30, "the page's hold dropped")
        teacher.set_value(shared_kp, kp0)
        student.wait_for(lambda: student.gui[uuid].value == kp0, 30.0, "the stream live again")


def test_closing_a_class_while_its_clock_steps_frees_every_arm():
    """The class closing (the lab closing, or a test ending) while its clock is stepping:
    every arm is freed after the clock stopped, never while a tick steps its plant."""
    from armlab.app.workers.class_arms import ClassArms
    from armlab.kinematics import load_robot

    model = load_robot("receptionist_arm", preset="18.5/25")
    arms = ClassArms(realtime=True)
    held: list = []
    try:
        held += [arms.add(model, DEFAULT, preset="18.5/25", q0=np.array([0.0, 0.3, 0.3]),
                          history_s=1.0) for _ in range(12)]
        steps = arms.clock.steps
        wait_for(lambda: arms.clock.steps > steps + 20, 30, "the clock stepping the arms")
    except BaseException:
        arms.close(held)  # no real-time clock left running into the tests after this one
        raise
    seen = []  # per freed arm: (the clock still running, the class's lock held)
    free = arms.free

    def watched(arm) -> None:  # noqa: ANN001
        seen.append((arms.clock.alive, arms.lock._is_owned()))
        free(arm)

    arms.free = watched
    arms.close(held)
    assert len(seen) == 12 and not any(alive for alive, _ in seen)
    assert all(locked for _, locked in seen)
    assert not arms.clock.alive
    assert all(not arm.loop.status.running and not arm.loop.status.torque_on for arm in held)


@pytest.mark.slow
def test_a_seat_stays_open_while_any_page_shows_it_and_is_freed_when_idle():
    """A reload: the new page takes the seat before the old page's goodbye. The late
    goodbye must not start the idle timer under the new page (its arm would be freed
    while shown); once no page shows it, the arm is kept ``idle_s`` s, then freed."""
    from armlab.app.classroom.sandboxes import Sandboxes
    from armlab.kinematics import load_robot

    now = [0.0]
    boxes = Sandboxes(realtime=False, idle_s=600.0, clock=lambda: now[0])
    try:
        model = load_robot("receptionist_arm", preset="18.5/25")
        boxes.seat("k", page=1).arm_for(model, DEFAULT, preset="18.5/25",
                                        q0=np.array([0.0, 0.3, 0.3]), history_s=1.0)
        boxes.seat("k", page=2)  # the reloaded page, before the old one has gone
        boxes.leave("k", page=1)  # ... whose goodbye comes late
        now[0] += 3600.0
        assert boxes.sweep() == 0 and boxes.has("k") and boxes.n_arms == 1
        boxes.leave("k", page=2)
        now[0] += 599.0
        assert boxes.sweep() == 0 and boxes.has("k")  # kept for a reload
        now[0] += 2.0
        assert boxes.sweep() == 1 and not boxes.has("k") and boxes.n_arms == 0
    finally:
        boxes.close()


@pytest.mark.slow
def test_a_seat_keeps_its_students_hand_and_quadruped_and_frees_them_when_idle():
    """The hand and quadruped lessons' private copies: a reload asks the seat again and
    gets the same hand and robot, as they were left; an idle seat frees them from the
    class's worker."""
    from armlab.app.classroom.sandboxes import Sandboxes
    from armlab.control.grip import GripParams
    from armlab.control.walking import GaitSpec, plan_gait
    from armlab.hardware.sim.hand_plant import GraspObject

    now = [0.0]
    boxes = Sandboxes(realtime=False, idle_s=600.0, clock=lambda: now[0])
    try:
        seat = boxes.seat("k", page=1)
        hand = seat.hand_for(GraspObject(), GripParams(force_limit=0.6), history_s=2.0)
        robot = seat.quadruped_for(GaitSpec(gait="crawl"), speed=0.4, history_s=5.0)
        hand.close_hand()
        robot.go(robot_plan := plan_gait(GaitSpec(gait="crawl")))
        wait_for(lambda: hand.status.modes != ("idle",) * 3, 30, "the hand closing")
        wait_for(lambda: robot.status.walking, 60, "the robot walking")
        assert robot_plan.spec == robot.spec and robot.status.speed == pytest.approx(0.4)
        boxes.leave("k", page=1)
        seat = boxes.seat("k", page=2)  # the reload
        again = seat.hand_for(GraspObject(size=0.03), GripParams(), history_s=2.0)
        assert again is hand and again.params.force_limit == 0.6
        assert again.obj == GraspObject() and boxes.n_arms == 1
        assert seat.quadruped_for(GaitSpec(), speed=0.5, history_s=5.0) is robot
        assert robot.spec.gait == "crawl"
        other = boxes.seat("j", page=3).hand_for(GraspObject(), GripParams(), history_s=2.0)
        assert other is not hand and other.status.modes == ("idle",) * 3
        boxes.leave("k", page=2)
        now[0] += 601.0
        assert boxes.sweep() == 1 and boxes.n_arms == 1
        assert "freed" in hand.status.fault and not other.status.fault
        assert "freed" in robot.status.fault
    finally:
        boxes.close()


@pytest.mark.slow
def test_a_private_open_manipulator_x_has_its_x_series_servos():
    """A student's own OpenManipulator-X is simulated with its XM430-W350 firmware model,
    as the shared one is (armlab.app.arm.backends.make_backend), not with the thesis arm's RX-24F:
    it reports currents and turns to a goal; freeing it closes it."""
    from armlab.app.classroom.sandboxes import Sandboxes
    from armlab.control.commands import RunTrajectory
    from armlab.control.trajectory import minimum_jerk
    from armlab.hardware.families.xseries.sim_backend import XSimBackend
    from armlab.hardware.families.xseries.table import XM430_W350
    from armlab.kinematics import load_robot

    model = load_robot("open_manipulator_x")
    boxes = Sandboxes(realtime=False)
    try:
        backend, loop = boxes.seat("omx").arm_for(model, DEFAULT, preset="omx",
                                                  q0=model.neutral(), history_s=2.0)
        assert isinstance(backend, XSimBackend) and backend.specs[0] is XM430_W350
        wait_for(lambda: loop.status.active and len(loop.recorder.snapshot(1.0)["t"]) > 20,
                 60, "the arm's loop running on the class clock")
        start = np.asarray(backend.read().position, dtype=float)
        goal = start + np.array([0.0, 0.3, 0.0, 0.0])
        loop.post(RunTrajectory(minimum_jerk(start, goal, 1.0)))
        wait_for(lambda: abs(backend.read().position[1] - goal[1]) < np.radians(3.0), 60,
                 "the shoulder at its goal")
        assert loop.status.fault is None
        assert np.any(np.abs(backend.read().load) > 0.0)  # torque from the measured current
    finally:
        boxes.close()
    assert boxes.n_arms == 0


@pytest.mark.slow
def test_a_private_lesson_without_an_arm_hides_the_shared_panel_and_takes_an_estop():
    """The IK lesson has no arm, gains or figures, and its handle says so (the lesson
    contract, armlab.app.lessons.LessonHandle): shown as "My arm", the shared lesson's
    panel is hidden on that page, the overview lists the student, and the student's
    E-STOP there reaches the presenter."""
    from armlab.app.viser_ext.handles import uuid_of

    def joined(lab: Lab) -> HeadlessClient:
        page = HeadlessClient(lab.local_url.replace("http://", "ws://")).connect()
        page.wait_for(lambda: _has(page, "Passcode") and _has(page, "View"), 60.0,
                      "the Passcode field and the View switch")
        return page

    with Lab(ServeOptions(http_port=0, classroom=True, robot="planar_servo_arm",
                          lesson="ik_accuracy")) as lab, joined(lab) as teacher:
        teacher.set_value("Passcode", lab.roles.passcode)
        teacher.wait_notification("You present")
        before = set(lab.server.get_clients())
        with joined(lab) as student:
            student.wait_for(lambda: bool(set(lab.server.get_clients()) - before), 30.0,
                             "the student's client")
            (cid,) = set(lab.server.get_clients()) - before
            student.set_value("View", "My arm")
            wait_for(lambda: lab.room.private_lesson(cid) is not None, 60, "the own lesson")
            assert lab.lesson is not None
            shared = [uuid_of(h) for h in lab.lesson.gui_handles()]
            assert shared
            student.wait_for(lambda: all(u in student.gui and student.gui[u].props.get(
                "visible") is False for u in shared), 30.0, "the shared panel hidden")
            (row,) = lab.room.rows()
            assert row.client_id == cid and row.view == "My arm"
            assert row.figures == {}  # the IK lesson declares no FIGURES
            student.click("E-STOP")
            teacher.wait_notification("E-STOP")


def test_a_page_that_only_connects_is_refused_nothing_and_told_nothing(classroom):
    """On connect the server asks every page for its localStorage (projector, renderer,
    seat); the page's answers are not its person's doing and are not refused."""
    import threading

    lab = classroom
    refused = lab.roles.refused
    answered = threading.Event()  # the page sent its answer to a question of the server's

    def seen(message: dict, _t: float) -> None:
        if message.get("type") == "LocalStorageGetItemRequestMessage":
            answered.set()  # on_message runs after the page's answers went out

    before = set(lab.server.get_clients())
    page = HeadlessClient(lab.local_url.replace("http://", "ws://"), on_message=seen)
    with page.connect():
        page.wait_for(answered.is_set, 60.0, "a localStorage question answered")
        page.wait_for(lambda: bool(set(lab.server.get_clients()) - before) and
                      _has(page, "Your name"), 60.0, "the client and its name field")
        (cid,) = set(lab.server.get_clients()) - before
        # a round trip after the answers: the server has screened them by now
        page.set_value("Your name", "Quiet")
        wait_for(lambda: lab.roles.name(cid) == "Quiet", 30, "the page's name")
        assert lab.roles.refused == refused
        assert not [t for t, _ in page.notifications if "presenter" in t.lower()]


@pytest.mark.slow
def test_a_follower_saves_and_exports_the_shared_run_to_its_page_alone(classroom):
    """Save run and Export page (the Files tab) change nothing shared: a follower's press
    sends the teacher's run to that page only; Open run on the shared lesson stays the
    presenter's."""
    lab = classroom
    lesson = lab.lesson
    loop = lesson.rig.loop
    (teacher, _), (follower, fid), (other, _) = _joined(lab), _joined(lab), _joined(lab)
    with teacher, follower, other:
        teacher.set_value("Passcode", lab.roles.passcode)
        teacher.wait_notification("You present")
        teacher.click("Run thesis line")  # the teacher's demo run
        wait_for(lambda: loop.status.trajectory is not None, 30, "the demo running")
        params, refused = loop.params.as_dict(), lab.roles.refused
        assert not lab.roles.is_presenter(fid)

        follower.click(lesson.runs.save)
        follower.wait_for(lambda: any(n.endswith(".armlab-run.zip") for n in follower.downloads),
                          60.0, "the follower's run file")
        name = next(n for n in follower.downloads if n.endswith(".armlab-run.zip"))
        run = read_run(follower.downloads[name], robot=lab.lesson_ctx.robot)
        assert "RunTrajectory" in [c["kind"] for c in run.commands]  # the teacher's run
        assert run.extra["run"]["state"] == "unfinished"  # saved while the demo runs
        assert run.extra["student"] == lab.roles.name(fid)  # who saved it
        follower.click(lesson.runs.export)
        follower.wait_for(lambda: any(n.endswith(".html") for n in follower.downloads),
                          60.0, "the follower's exported page")
        # the other page got nothing: a round trip of its own (Frame) came back first
        sets = other.camera_sets
        other.click("Frame")
        other.wait_for(lambda: other.camera_sets > sets, 30.0, "the other page reframed")
        assert other.downloads == {} and teacher.downloads == {}
        assert lab.roles.refused == refused
        assert not [t for t, _ in follower.notifications if "presenter" in t.lower()]

        # Open run on the shared lesson: refused from the follower, nothing replayed
        follower.upload(lesson.runs.open, name, follower.downloads[name])
        wait_for(lambda: lab.roles.refused > refused, 30, "the follower's upload refused")
        assert lesson.runs.replay.run is None
        assert loop.params.as_dict() == params and lab.lesson is lesson
        teacher.click("Stop")
        wait_for(lambda: loop.status.trajectory is None, 30, "the demo stopped")
