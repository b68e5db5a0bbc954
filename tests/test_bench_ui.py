"""The UI bench measures the lab at work: the arm moves, the charts update, the loop runs.

A bench that monkeypatched the recorder with a stale signature once faulted the
loop on its first period and reported 0 Hz of motion and 43 s of latency; this
test runs the bench's own instrumentation and client process briefly and checks
that what it measures is a working lab. Counts only, no rates: a busy machine.
"""

import math

import pytest

from armlab.app.benches import ui

pytestmark = pytest.mark.realtime  # a served lab whose loop runs on the wall clock


def test_ui_bench_sees_the_arm_move_and_the_angle_chart_update():
    lab = ui._Instrumented()
    try:
        lab.keep_running_the_line()
        figures = ui._clients(lab.ws_url, 1, seconds=3.0)
        lab.check()  # the loop is still active, no fault
    finally:
        lab.close()
    assert figures["samples"] > 0  # probe frames arrived
    assert figures["arm_pose_hz"] > 0  # frames in which an arm joint turned
    assert figures["plot_hz"] > 0  # frames carrying new joint-angle data
    assert math.isfinite(figures["latency_p95_ms"])


def test_the_drag_figures_time_drags_that_hold_and_let_go_of_the_arm():
    lab = ui._Instrumented()
    try:
        hold, let_go = lab.drag_ms(3)
        lab.check()
        assert lab.lesson._drag_anchor is None  # the last drag let go
    finally:
        lab.close()
    assert len(hold) == len(let_go) == 3
    assert all(math.isfinite(x) and x > 0 for x in hold + let_go)
