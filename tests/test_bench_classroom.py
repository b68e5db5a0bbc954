"""The classroom bench's class of loops runs both ways (batched, and the per-arm reference it
is compared with in the same run) with every arm's trajectory and push and no fault, and
its room of private hands delivers: its figures are figures of that work, never asserted
here."""

from __future__ import annotations

import math

import pytest

from armlab.app.benches.classroom import loops_ms_cost


@pytest.mark.slow
@pytest.mark.parametrize("walls", (False, True), ids=("free", "walls"))
@pytest.mark.parametrize("batched", (True, False), ids=("batched", "single_plants"))
def test_the_class_of_loops_runs_without_a_fault(batched: bool, walls: bool) -> None:
    # (raises on a fault; with walls past the lag check's 0.5 s, which stops a blocked arm)
    cost = loops_ms_cost(12, seconds=1.0 if walls else 0.2, batched=batched, walls=walls)
    assert math.isfinite(cost) and cost > 0.0


@pytest.mark.parametrize("lesson", ("hand", "quadruped"))
@pytest.mark.slow
def test_a_room_of_pages_each_with_its_own_copy_gets_frames_of_it(lesson: str) -> None:
    """Three pages choose My arm in the hand or quadruped lesson; each draws its own robot
    (the clients wait for that) and receives frames of its own lesson while the students
    play; no copy faults (the bench raises)."""
    from armlab.app.benches.classroom import private_room

    res = private_room(lesson, seconds=3.0, pages=3, settle=1.0)
    assert res[f"classroom_30_{lesson}_pose_hz"] > 0.0
    assert res[f"classroom_30_{lesson}_bytes_per_client_per_s"] > 0.0


@pytest.mark.parametrize("batched", (True, False), ids=("batched", "single_backends"))
@pytest.mark.slow
def test_the_class_of_quadrupeds_walks_without_a_fault(batched: bool) -> None:
    from armlab.app.benches.classroom import quadrupeds_cost

    cost = quadrupeds_cost(3, seconds=0.2, batched=batched)  # raises if a robot stopped
    assert math.isfinite(cost) and cost > 0.0
