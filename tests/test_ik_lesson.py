"""The IK-accuracy lesson (seed 004) on a real viser server (port 0), driven by a real client."""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
import pytest
from _helpers import client_of, served_lesson, wait_for

from armlab.app.commands.cli import main
from armlab.app.lessons import LessonContext
from armlab.app.lessons.ik_accuracy import BAD_RGB, OK_RGB, TARGET_LIMIT_CM, build
from armlab.app.page.inputs import LIMIT_TITLE
from armlab.control.experiments.seed004_data import TABLE1
from armlab.kinematics.planar_ik import fk

IN_RANGE_ROWS = [*range(1, 6), *range(20, 25)]


@pytest.fixture
def lesson():
    with served_lesson(build, LessonContext(robot="planar_servo_arm")) as handle:
        yield handle


def shown(lesson, X_cm: float, Y_cm: float) -> bool:
    """The readout (updated last) shows target (X, Y) cm."""
    return f"<b>target</b> ({X_cm:.2f}, {Y_cm:.2f}) cm" in lesson.readout.content


def arm_tip(lesson) -> tuple[float, float]:
    """Where the drawn arm's end effector is, from the angles it is drawn at."""
    x, y, _ = fk(tuple(lesson.view.q), lesson.arm)
    return x, y


def arc_rgb(handle) -> tuple[int, ...]:
    return tuple(int(c) for c in np.asarray(handle.colors)[0, 0])


def test_typed_and_dragged_targets_move_the_arm(lesson):
    with client_of(lesson.server) as client:
        client.set_value(lesson.x_input, 12.0)
        client.set_value(lesson.y_input, 8.0)
        wait_for(lambda: shown(lesson, 12.0, 8.0))
        tip = arm_tip(lesson)
        assert math.dist(tip, (0.12, 0.08)) < 0.005  # whole-degree commands: mm off
        assert tip == pytest.approx(lesson.result.position, abs=1e-12)
        client.move_gizmo(lesson.gizmo.name, [(0.10, 0.10, 0.0), (0.05, 0.16, 0.0)])
        wait_for(lambda: shown(lesson, 5.0, 16.0))
        assert math.dist(arm_tip(lesson), (0.05, 0.16)) < 0.005
        assert lesson.x_input.value == pytest.approx(5.0)  # the inputs follow the drag
        assert lesson.y_input.value == pytest.approx(16.0)


def test_rounding_and_elbow_change_the_solution(lesson):
    lesson.set_target(0.04, 0.19)  # row 5
    assert math.dist(arm_tip(lesson), (0.0333, 0.1922)) < 1e-4  # the paper's X1/Y1
    lesson.rounding_input.value = "none (exact angles)"
    assert lesson.rounding == "none"
    assert math.dist(arm_tip(lesson), (0.04, 0.19)) < 1e-9
    down = lesson.result.angles[1]
    lesson.elbow_input.value = "elbow up"
    assert down < 0 < lesson.result.angles[1]
    assert math.dist(arm_tip(lesson), (0.04, 0.19)) < 1e-9


def test_servo_ranges_turn_red_when_the_solution_leaves_them(lesson):
    lesson.set_target(0.04, 0.19)  # row 5: in range
    assert [arc_rgb(a) for a in lesson.arcs] == [OK_RGB] * 3
    assert not lesson.ghost.root.visible
    lesson.set_target(0.10, 0.13)  # row 11: theta2 = -113.5 deg, servo 2 beyond 180
    assert [arc_rgb(a) for a in lesson.arcs] == [OK_RGB, BAD_RGB, OK_RGB]
    assert arc_rgb(lesson.needles[1]) == BAD_RGB
    # the lab's in-range alternative is drawn as a ghost and explained
    assert lesson.ghost.root.visible and lesson.alternative is not None
    x, y, _ = fk(tuple(lesson.ghost.q), lesson.arm)
    assert math.dist((x, y), (0.10, 0.13)) < 0.002
    assert "servo angle outside 0–180°" in lesson.readout.content


def test_table_run_shows_the_paper_columns_and_matches_rows_1_5_and_20_24(lesson, capsys):
    with client_of(lesson.server) as client:
        client.click(lesson.table_button)
        wait_for(lambda: lesson.table_result is not None)
    rows = lesson.table_result["rows"]
    assert len(rows) == 24
    for no in IN_RANGE_ROWS:
        r = rows[no - 1]
        _, X, Y, X1, Y1, X2, Y2, *_ = TABLE1[no - 1]
        assert r["in_servo_range"]
        assert abs(r["computed_cm"][0] - X1) <= 0.01 and abs(r["computed_cm"][1] - Y1) <= 0.01
        # shown beside the paper's columns
        line = next(s for s in lesson.table_md.content.splitlines() if s.startswith(f"| {no} |"))
        assert line.count(f"{X1:.2f}, {Y1:.2f}") == 2, line
        assert f"{X2:g}, {Y2:g}" in line
    # the out-of-range rows are each explained with the lab's alternative
    for no in range(6, 20):
        assert not rows[no - 1]["in_servo_range"]
        assert f"- row {no} (" in lesson.out_of_range_md.content
        assert rows[no - 1]["alternative"]["error_cm"] < 0.2
    # the error chart has the 24 rows; the paper's R column is its first series
    assert lesson.error_plot.visible
    x, paper_r, *_ = lesson.error_plot.data
    np.testing.assert_allclose(x, np.arange(1, 25))
    np.testing.assert_allclose(paper_r, [r[9] * 10 for r in TABLE1])
    # the same figures as `armlab experiment seed004-table --json`
    assert main(["experiment", "seed004-table", "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert json.loads(json.dumps(lesson.table_result)) == cli
    # CSV download: the CLI's --csv columns
    name, data = lesson.csv_bytes()
    table = list(csv.DictReader(io.StringIO(data.decode())))
    assert name.endswith(".csv") and len(table) == 24
    assert float(table[0]["paper_X1"]) == -0.30 and float(table[0]["X1"]) == pytest.approx(-0.30,
                                                                                           abs=0.01)


def test_target_outside_the_workspace_gives_one_clear_message(lesson):
    with client_of(lesson.server) as client:
        client.move_gizmo(lesson.gizmo.name, [(0.20, 0.10, 0.0), (0.26, 0.12, 0.0),
                                              (0.27, 0.12, 0.0), (0.28, 0.12, 0.0)])
        wait_for(lambda: shown(lesson, 28.0, 12.0))
        # the notification goes to the dragging client's own queue, the readout to every
        # page: the two may arrive in either order, so wait for both
        client.wait_notification("Outside the workspace", timeout=60.0)
        readout = lesson.readout._impl.uuid
        client.wait_for(lambda: "(28.00, 12.00) cm" in str(
            client.gui[readout].props.get("content", "")), 60.0, "the readout on the client")
        titles = [t for t, _ in client.notifications]
        assert titles.count("Outside the workspace") == 1
        assert "outside the workspace" in lesson.readout.content
        assert not lesson.result.reachable
        # back inside: the message goes, the arm follows again
        client.move_gizmo(lesson.gizmo.name, [(0.10, 0.10, 0.0)])
        wait_for(lambda: shown(lesson, 10.0, 10.0))
        assert lesson.message == "" and "outside the workspace" not in lesson.readout.content


@pytest.mark.parametrize("value", [1e9, -1e9])
def test_a_typed_target_past_its_range_is_set_to_its_end(lesson, value):
    """The page's one rule: the nearest end is applied and the message names it."""
    end = TARGET_LIMIT_CM if value > 0 else -TARGET_LIMIT_CM
    side = "above the largest" if value > 0 else "below the smallest"
    with client_of(lesson.server) as client:
        client.set_value(lesson.x_input, value)
        body = client.wait_notification(LIMIT_TITLE)
        assert body == f"Target X (cm): {value:g} is {side} value, {end:g}; set to {end:g}."
        wait_for(lambda: lesson.target[0] == pytest.approx(end / 100), 30.0, "the end applied")
        assert lesson.x_input.value == pytest.approx(end)


@pytest.mark.parametrize("value", [float("nan")])
def test_bad_typed_target_is_refused_and_the_server_goes_on(lesson, value):
    with client_of(lesson.server) as client:
        before = lesson.target
        client.set_value(lesson.x_input, value)
        body = client.wait_notification("Value refused")
        assert body.startswith("Target X (cm)")
        # the page is told first, then its input is put back
        wait_for(lambda: lesson.x_input.value == pytest.approx(before[0] * 100), 30.0,
                 "the input put back")
        assert lesson.target == before
        client.set_value(lesson.x_input, 6.0)
        wait_for(lambda: shown(lesson, 6.0, before[1] * 100))
