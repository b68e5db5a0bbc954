"""The hand lesson on a real viser server (port 0), driven by a real websocket client."""

from __future__ import annotations

import time

import numpy as np
import pytest
from _helpers import client_of, served_lesson, wait_for

from armlab.app.lessons import LessonContext
from armlab.app.lessons.catalog import all_lessons
from armlab.app.lessons.hand import build
from armlab.app.page.inputs import LIMIT_TITLE
from armlab.control.experiments.hand_grip import GripOptions, run_grip
from armlab.hardware.sim.hand_plant import make_hand


@pytest.fixture
def lesson():
    with served_lesson(build, LessonContext(realtime=False)) as handle:
        yield handle


def wait_sim(lesson, seconds: float, *, timeout: float = 30.0) -> None:
    """Let the lesson's loop run ``seconds`` more simulated seconds."""
    end = lesson.loop.status.t + seconds
    deadline = time.monotonic() + timeout
    while lesson.loop.status.t < end:
        assert time.monotonic() < deadline, "the hand loop stalled"
        assert not lesson.loop.status.fault, lesson.loop.status.fault
        time.sleep(0.02)


def force_now(lesson) -> np.ndarray:
    """(3,) N, the fingertip forces of the loop's newest record row."""
    return lesson.loop.snapshot(0.05)["force"][-1]


def test_lesson_is_registered():
    module = all_lessons()["hand"]
    assert module.title and module.help and module.robots == ("receptionist_arm",)


@pytest.mark.slow
def test_force_limit_sets_the_grip_force_and_the_figures_match_the_experiment(lesson):
    with client_of(lesson.server) as client:
        client.set_value(lesson.force_slider, 0.4)
        wait_for(lambda: lesson.force.value == 0.4)
        client.click(lesson.close_button)
        wait_for(lambda: lesson.loop.status.closed_at is not None)
        wait_sim(lesson, 2.0)
        np.testing.assert_allclose(force_now(lesson), 0.4, rtol=0.10)
        # what the lesson shows is what `armlab experiment hand-grip` computes
        shown = lesson.loop.last_grasp(0.4)
        options = GripOptions(force=0.4, stiffness=1000.0, size=6.0, damping=1.0, lpf=None,
                              duration=2.0)
        expected = run_grip(options, hand_plant=make_hand)
        for key in ("steady_force_N", "peak_force_N", "time_to_grasp_s"):
            assert shown[key] == pytest.approx(expected[key], rel=1e-6, abs=1e-9), key
        lesson._plot_frame(True)
        assert f"peak {expected['peak_force_N']:.3f} N" in lesson.figures.content
        assert lesson.force_plot.updates > 0 and lesson.current_plot.updates > 0
        # "steady" only once the grasp has settled, and then the force the status shows
        # (the first grasp said "steady 0.381 N" while the status showed 0.80 N)
        wait_for(lambda: lesson._settled is not None, 60.0, "the grasp settled")
        lesson._plot_frame(True)
        steady = lesson._settled[1]["steady_force_N"]
        assert f"steady {steady:.3f} N" in lesson.figures.content
        assert steady == pytest.approx(float(np.mean(force_now(lesson))), abs=0.04)
        # a higher limit squeezes harder, read from the current alone
        client.set_value(lesson.force_slider, 1.0)
        wait_for(lambda: lesson.loop.params.force_limit == 1.0)
        wait_sim(lesson, 1.0)
        np.testing.assert_allclose(force_now(lesson), 1.0, rtol=0.10)
        assert lesson.loop.status.modes == ("holding",) * 3


@pytest.mark.slow
def test_open_releases_and_the_object_controls_change_the_object(lesson):
    with client_of(lesson.server) as client:
        client.click(lesson.close_button)
        wait_for(lambda: lesson.loop.status.closed_at is not None)
        wait_sim(lesson, 1.8)
        assert force_now(lesson).min() > 0.7
        # the size cannot change while the fingers hold the object
        client.set_value(lesson.size_slider, 8.0)
        body = client.wait_notification("Value refused")
        assert "open the hand" in body
        assert lesson.loop.obj.size == pytest.approx(0.06)
        client.click(lesson.open_button)  # handled by the server in its own time
        wait_for(lambda: lesson.loop.status.modes == ("idle",) * 3
                 and np.all(force_now(lesson) == 0.0), 30.0, "the hand open, no force")
        # open: a bigger, harder object
        client.set_value(lesson.size_slider, 8.0)
        client.set_value(lesson.presets, "hard")
        wait_for(lambda: lesson.stiffness.value == 5000.0 and lesson.size.value == 8.0)
        wait_for(lambda: lesson.loop.obj.size == pytest.approx(0.08)
                 and lesson.loop.obj.stiffness == 5000.0
                 and lesson.scene.object.radius == pytest.approx(0.04), 30.0,
                 "the bigger, harder object in the loop and the scene")


@pytest.mark.parametrize("value", [1e9, -0.3])
def test_a_typed_force_past_its_range_is_applied_as_its_end(lesson, value):
    end = lesson.force.hi if value > 0 else lesson.force.lo
    side = "above the largest" if value > 0 else "below the smallest"
    with client_of(lesson.server) as client:
        client.set_value(lesson.force_slider, value)
        body = client.wait_notification(LIMIT_TITLE)
        assert body == f"force limit: {value:g} is {side} value, {end:g}; set to {end:g}."
        wait_for(lambda: lesson.loop.params.force_limit == end, 30.0, "the end applied")
        wait_for(lambda: lesson.force_slider.value == end, 30.0, "the slider at the end")
        assert not any(t == "Value refused" for t, _ in client.notifications)
        client.set_value(lesson.force_slider, 0.8)
        wait_for(lambda: lesson.loop.params.force_limit == 0.8, 30.0, "0.8 again")


@pytest.mark.parametrize("value", [float("nan")])
def test_bad_typed_force_is_refused_and_the_lesson_goes_on(lesson, value):
    with client_of(lesson.server) as client:
        client.set_value(lesson.force_slider, value)
        body = client.wait_notification("Value refused")
        assert body.startswith("force limit")
        # the page is told first, then its slider is put back
        wait_for(lambda: lesson.force_slider.value == 0.8, 30.0, "the slider put back")
        assert lesson.loop.params.force_limit == 0.8
        # still serving: a good value goes through
        client.set_value(lesson.force_slider, 0.5)
        wait_for(lambda: lesson.loop.params.force_limit == 0.5)
        assert lesson.loop.status.fault == ""
