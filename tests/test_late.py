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
