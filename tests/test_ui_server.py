"""The lab around the lessons: lesson registry, switching lessons from the page, E-STOP."""

from __future__ import annotations

import time

import pytest

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons.catalog import all_lessons, default_lesson
from armlab.app.testing.wsclient import HeadlessClient

pytestmark = pytest.mark.realtime  # a served lab whose loop runs on the wall clock


def test_every_lesson_declares_what_the_switcher_needs():
    lessons = all_lessons()
    assert "compliance" in lessons
    for name, lesson in lessons.items():
        assert lesson.name == name
        assert lesson.title and lesson.help and lesson.first_step and lesson.robots
    assert default_lesson("receptionist_arm") == "compliance"
    with pytest.raises(ValueError, match="no lesson for 'no_such_robot'"):
        default_lesson("no_such_robot")


def test_every_lesson_module_is_in_the_one_list():
    """A module of the lessons' folder that declares a ``LESSON`` is listed in
    ``catalog.LESSONS`` (a lesson written but not listed would never open)."""
    import importlib
    import pkgutil

    import armlab.app.lessons as package
    from armlab.app.lessons import Lesson
    from armlab.app.lessons.catalog import LESSONS

    declared = []
    for info in pkgutil.iter_modules(package.__path__):
        lesson = getattr(importlib.import_module(f"{package.__name__}.{info.name}"),
                         "LESSON", None)
        if isinstance(lesson, Lesson):
            declared.append(lesson)
    assert len(declared) >= 6
    assert sorted(map(id, declared)) == sorted(map(id, LESSONS))  # the modules' own values


def test_bad_serve_options_name_the_option():
    with pytest.raises(ValueError, match="backend"):
        ServeOptions(backend="usb")
    with pytest.raises(ValueError, match="port"):
        ServeOptions(backend="serial")
    with pytest.raises(ValueError, match="lesson"):
        Lab(ServeOptions(http_port=0, lesson="no_such_lesson"))


def test_a_switch_made_by_the_lab_shows_in_every_pages_switcher():
    with Lab(ServeOptions(http_port=0)) as lab:
        with HeadlessClient(lab.url.replace("http://", "ws://")) as page:
            page.wait_for(lambda: any(e.label == "Lesson" for e in page.gui.values()),
                          what="the lesson switcher")
            lab.switch("arm")
            title = all_lessons()["arm"].title
            page.wait_for(lambda: any(e.label == "Lesson" and e.value == title
                                      for e in page.gui.values()),
                          30.0, "the page's switcher to name the arm lesson")
            assert lab.lesson_dropdown.value == title and lab.lesson_name == "arm"


def test_switching_lessons_from_the_page_stops_the_old_one():
    with Lab(ServeOptions(http_port=0)) as lab:
        compliance = lab.lesson
        loop = compliance.rig.loop
        with HeadlessClient(lab.url.replace("http://", "ws://")) as page:
            page.wait_for(lambda: any(e.label == "Lesson" for e in page.gui.values()),
                          what="the lesson switcher")
            others = [m for n, m in all_lessons().items() if n != "compliance"]
            for module in others:
                page.set_value("Lesson", module.title)
                deadline = time.monotonic() + 30
                while lab.lesson_name != module.name and time.monotonic() < deadline:
                    time.sleep(0.05)
                assert lab.lesson_name == module.name
            if others:
                assert not loop.status.running  # the compliance loop was shut down
                page.wait_for(lambda: not any(
                    e.label == "Run thesis line" or str(e.props.get("title", "")).startswith(
                        "Joint angle") for e in page.gui.values()), 60.0,
                    "the compliance controls and charts to go")
            page.set_value("Lesson", all_lessons()["compliance"].title)
            page.wait_for(lambda: any(e.label == "Run thesis line" for e in page.gui.values()),
                          30.0, "the compliance controls back")
            deadline = time.monotonic() + 30
            while lab.lesson_name != "compliance" and time.monotonic() < deadline:
                time.sleep(0.05)
            assert lab.lesson_name == "compliance" and lab.lesson is not compliance
            assert lab.lesson.rig.loop.status.running
            page.click("E-STOP")
            deadline = time.monotonic() + 60
            while not lab.lesson.rig.loop.status.estopped and time.monotonic() < deadline:
                time.sleep(0.05)
            assert lab.lesson.rig.loop.status.estopped


def test_a_lessons_gains_and_measurements_survive_a_switch_away_and_back():
    """Switching to another lesson and back keeps the compliance lesson as it was left:
    its gains, its measured step (the Teach tab's measured column) and chapter 4's
    figures; they used to be lost with the lesson."""
    from armlab.app.lessons.compliance_teach import design_table

    with Lab(ServeOptions(http_port=0, realtime=False)) as lab:
        lesson = lab.lesson
        lesson.gains.sliders["kp"].set(24.0)
        deadline = time.monotonic() + 60
        while lesson.rig.loop.params.kp != 24.0 and time.monotonic() < deadline:
            time.sleep(0.02)
        lesson.run_step(joint=2, step_deg=10.0)
        deadline = time.monotonic() + 120
        while lesson.measured_pd is None and time.monotonic() < deadline:
            time.sleep(0.05)
        measured = lesson.measured_pd
        assert measured is not None and measured.params.kp == 24.0
        text = lesson.step_result.content
        lab.switch("arm")
        lab.switch("compliance")
        back = lab.lesson
        assert back is not lesson and back.rig.loop.params.kp == 24.0
        assert back.gains.params.kp == 24.0 and back.gains.sliders["kp"].handle.value == 24.0
        assert back.measured_pd == measured and back.step_result.content == text
        assert "PD measured on: step of θ2" in design_table(back.gains.params, back.measured_pd,
                                                            back.measured_env)
