"""The redundancy lesson (seed 002) on a real viser server (port 0), driven by a real
websocket client."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _helpers import client_of, served_lesson, wait_for

from armlab.app.lessons import LessonContext
from armlab.app.lessons.catalog import all_lessons
from armlab.app.lessons.redundancy import SHOWN_MODES, build
from armlab.app.page.inputs import LIMIT_TITLE
from armlab.control.experiments.seed002 import circle
from armlab.kinematics.catalog import load_robot


@pytest.fixture(scope="module")
def lesson():
    with served_lesson(build, LessonContext(robot="redundant_planar", realtime=False)) as handle:
        yield handle


def test_lesson_is_registered():
    module = all_lessons()["redundancy"]
    assert module.title and module.help and module.robots == ("redundant_planar",)


@pytest.mark.slow
def test_run_button_produces_the_experiment_figures_and_the_paper_behaviour(lesson):
    # Before a run every ghost stands at the paper's θ(0).
    for mode in SHOWN_MODES:
        np.testing.assert_allclose(lesson.ghost_q(mode), [math.pi, -math.pi / 2, -math.pi / 2])
    with client_of(lesson.server) as client:
        client.click(lesson.run_button)
        wait_for(lambda: lesson.results is not None and not lesson.computing, timeout=60.0)
    rs = lesson.results
    # Same function underneath as `armlab experiment seed002-circle --mode M`.
    for mode in ("1", "bounded"):
        assert rs.figures[mode] == circle(mode, gain=400.0, k_a=200.0)
    table = lesson.figures_md.content
    for mode in SHOWN_MODES:
        assert f"{rs.figures[mode]['mean_manipulability']:.3f}" in table
    # The paper's findings, seen on the ghosts at t = 1 s: mode 1 has joints 2 and 3
    # outside their limits (red dots), the limit-keeping modes do not.
    lesson.hold_at(1.0)  # the publisher then shows the same instant
    assert lesson.scene.views["1"].outside == (False, True, True)
    for mode in ("2", "4", "bounded"):
        assert lesson.scene.views[mode].outside == (False, False, False)
    # Each mode is a different motion (2 and 4 coincide: docs/redundancy.md).
    assert np.linalg.norm(lesson.ghost_q("1") - lesson.ghost_q("3")) > 0.05
    assert np.linalg.norm(lesson.ghost_q("3") - lesson.ghost_q("bounded")) > 0.05
    np.testing.assert_allclose(lesson.ghost_q("2"), lesson.ghost_q("4"), atol=1e-9)
    # Sticks (every 0.1 s) and the ellipse at the hand follow the playhead.
    assert lesson.scene.views["1"].sticks_shown == 11
    ell = np.asarray(lesson.scene.views["3"].ellipse.points)[:, 0, :2]
    hand = lesson.model.fk(lesson.ghost_q("3"))[:2, 3]
    np.testing.assert_allclose(ell.mean(axis=0), hand, atol=1e-6)
    # The charts draw what was played.
    lesson._plot_frame(True)
    assert all(p.updates > 0 for p in lesson.plots.plots)


@pytest.mark.slow
def test_k_a_slider_changes_the_redundant_ghost(lesson):
    if lesson.results is None:
        lesson.run(wait=True)
    lesson.hold_at(1.0)  # the publisher then shows the same instant
    before_3 = lesson.ghost_q("3")
    before_1 = lesson.ghost_q("1")
    with client_of(lesson.server) as client:
        client.set_value(lesson.k_a_slider, 0.0)
        wait_for(lambda: lesson.k_a.value == 0.0)
        assert lesson.stale
        lesson._update_status()
        assert "press Run" in lesson.status.content
        client.click(lesson.run_button)
        wait_for(lambda: lesson.results.k_a == 0.0 and not lesson.computing, timeout=60.0)
    lesson.hold_at(1.0)  # the publisher then shows the same instant
    # Without the gradient term eq. 4 is plain J⁺ẋ: ghost 3 now moves like ghost 1.
    assert np.linalg.norm(lesson.ghost_q("3") - before_3) > 0.05
    np.testing.assert_allclose(lesson.ghost_q("3"), before_1, atol=1e-9)
    np.testing.assert_allclose(lesson.ghost_q("1"), before_1, atol=1e-12)
    plain = circle("1", gain=400.0, k_a=0.0)
    for key in ("max_error_m", "max_violation_rad", "mean_manipulability"):
        assert lesson.results.figures["3"][key] == plain[key]


def test_show_checkbox_hides_a_panel(lesson):
    box = lesson.show_boxes["3"]
    with client_of(lesson.server) as client:
        client.set_value(box, False)
        wait_for(lambda: not lesson.scene.views["3"].root.visible, timeout=30.0)
        client.set_value(box, True)
        wait_for(lambda: lesson.scene.views["3"].root.visible, timeout=30.0)


@pytest.mark.parametrize("value", [1e9, 600.0])
def test_a_typed_gain_past_its_range_is_set_to_its_end(lesson, value):
    hi = lesson.gain.hi
    with client_of(lesson.server) as client:
        client.set_value(lesson.gain_slider, value)
        body = client.wait_notification(LIMIT_TITLE)
        assert body == f"K: {value:g} is above the largest value, {hi:g}; set to {hi:g}."
        wait_for(lambda: lesson.gain.value == hi, 30.0, "the end applied")


@pytest.mark.parametrize("value", [float("nan")])
def test_bad_typed_gain_is_refused_and_the_server_goes_on(lesson, value):
    before = lesson.gain.value
    with client_of(lesson.server) as client:
        client.set_value(lesson.gain_slider, value)
        body = client.wait_notification("Value refused")
        assert body.startswith("K: ") and f"kept {before:g}" in body
        assert lesson.gain.value == before
        # The server still answers: a good value is taken.
        client.set_value(lesson.speed_slider, 0.5)
        wait_for(lambda: lesson.speed.value == 0.5, timeout=30.0)


@pytest.mark.slow
def test_the_3d_labels_fit_their_panels_at_any_zoom():
    """The five panels' labels are sized in the scene, so their room is a matter of
    metres: each title and status line fits its column (no word over a neighbour's), the
    status lies above the arm's highest point in every run, and the title below the row
    above (screen-sized labels overprinted each other: "2 · J⁺ẋ + limits" on "4 · k_a∇w")."""
    from armlab.app.lessons import redundancy as lesson_module
    from armlab.app.lessons import redundancy_scene as rs

    width = rs.LABEL_WIDTH_M
    assert width < rs.COLUMN_M  # short of the next column's words
    for mode in rs.GRID:
        assert len(rs.SCENE_TITLES[mode]) * rs.GLYPH_EM * rs.TITLE_HEIGHT_M <= width, mode
    assert rs.STATUS_CHARS * rs.GLYPH_EM * rs.STATUS_HEIGHT_M <= width
    model = load_robot("redundant_planar")
    runs = lesson_module.run_modes(model, gain=400.0, k_a=1.0)
    top = max(float(p[..., 1].max()) for p in runs.points.values())
    assert top < rs.LABEL_BOTTOM_M  # the arm never reaches its panel's words
    for mode, run in runs.runs.items():
        lines = {line for k in range(len(run.t))
                 for line in lesson_module._mode_status(model, run, k).split("\n")}
        assert max(len(line) for line in lines) <= rs.STATUS_CHARS, (mode, lines)
    status_top = rs.LABEL_BOTTOM_M + 2 * rs.LINE_EM * rs.STATUS_HEIGHT_M
    assert rs.TITLE_BOTTOM_M > status_top
    assert rs.TITLE_BOTTOM_M + rs.LINE_EM * rs.TITLE_HEIGHT_M < rs.ROW_M  # below the row above
