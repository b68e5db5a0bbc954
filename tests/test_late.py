"""The status line's late-period count (app/late.py)."""

from app.late import LateWindow


def test_late_window_counts_overruns_of_the_last_ten_seconds_only():
    w = LateWindow()
    assert w.add(0.0, 5) == 0 and w.text() == ""
    assert w.add(1.0, 5) == 0
    assert w.add(2.0, 8) == 3
    assert w.text() == "late: 3 periods skipped in the last 10 s"
    assert w.add(11.5, 9) == 4  # baseline: the last snapshot at or before 1.5 s (1.0 s)
    assert w.add(12.5, 9) == 1  # baseline now the 2.0 s snapshot
    assert w.add(30.0, 9) == 0 and w.text() == ""


def test_recorded_rows_carry_wall_clock_time_beside_the_period_count():
    import time

    import numpy as np

    from control.recorder import Recorder

    r = Recorder(2, 10, ("a", "b"))
    before = time.time()
    r.append(0.001, {"q": np.zeros(2)})
    r.append(0.002, {"q": np.ones(2)})
    snap = r.snapshot()
    assert np.all((snap["wall"] >= before) & (snap["wall"] <= time.time()))
    lines = r.to_csv().splitlines()
    assert lines[1].startswith("t_s,wall_time_s,")
    t, wall = (float(x) for x in lines[2].split(",")[:2])
    assert t == 0.001 and abs(wall - snap["wall"][0]) < 1e-5
