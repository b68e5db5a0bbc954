"""The classroom bench's class of loops runs both ways (batched, and the per-arm reference it
is compared with in the same run) with every arm's trajectory and push and no fault: its
figures are figures of that work, never asserted here."""

from __future__ import annotations

import math

import pytest

from app.benches.classroom import loops_ms_cost


@pytest.mark.parametrize("batched", (True, False), ids=("batched", "single_plants"))
def test_the_class_of_loops_runs_without_a_fault(batched: bool) -> None:
    cost = loops_ms_cost(12, seconds=0.2, batched=batched)  # raises if an arm faulted
    assert math.isfinite(cost) and cost > 0.0
