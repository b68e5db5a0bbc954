"""The one pacer and the one ring buffer every loop of the lab shares
(armlab/control/periodic.py)."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from _helpers import wait_for

from armlab.control.periodic import SPIN_S, Pacer, SharedClock, sleep_until
from armlab.control.ring_buffer import RingBuffer


def test_ring_keeps_the_newest_rows_and_finds_a_window_by_time():
    ring = RingBuffer(2, 5)
    assert len(ring) == 0 and ring.rows().shape == (0, 2)
    for k in range(8):  # wraps: rows 3..7 are kept
        ring.append(np.array([0.125 * k, k]))
    np.testing.assert_allclose(ring.rows()[:, 1], [3, 4, 5, 6, 7])
    np.testing.assert_allclose(ring.rows(0.25)[:, 1], [5, 6, 7])  # t >= 0.875 - 0.25
    np.testing.assert_allclose(ring.rows(max_points=2)[:, 1], [4, 7])  # every 3rd, newest kept
    ring.append([1.0, math.nan])  # a row of Python floats (a recorder's)
    last = ring.rows()[-1]
    assert last[0] == 1.0 and np.isnan(last[1])
    ring.resize(3)
    np.testing.assert_allclose(ring.rows()[:, 0], [0.75, 0.875, 1.0])
    assert ring.capacity == 3 and RingBuffer.rows_for(1.0, 0.016) == 63
    with pytest.raises(ValueError, match=">= 2"):
        RingBuffer(2, 1)


def test_a_mirror_fed_by_since_keeps_the_same_rows_through_wraps_and_resizes():
    """A ring in another process follows one by ``since`` (the rows written after its
    bookmark) and ``extend``: after bursts larger than the ring, empty calls and a resize
    of both, it holds the same rows as the original."""
    ring, mirror = RingBuffer(3, 7), RingBuffer(3, 7)
    rng = np.random.default_rng(4)
    bookmark, k = 0, 0
    for burst in (0, 3, 5, 12, 1, 0, 7, 30, 2):  # 12 and 30: more than the ring keeps
        for _ in range(burst):
            ring.append(np.array([0.01 * k, *rng.normal(size=2)]))
            k += 1
        if burst == 1:  # the recorder resizes when the period changes: so does its mirror
            ring.resize(4)
            mirror.resize(4)
        rows, bookmark = ring.since(bookmark)
        assert len(rows) == min(burst, ring.capacity) and bookmark == k
        mirror.extend(rows)
        np.testing.assert_array_equal(mirror.rows(), ring.rows())
    assert ring.since(bookmark)[0].shape == (0, 3) and len(mirror) == len(ring) == 4


def test_pacer_runs_periods_headless_and_in_batches():
    calls: list[int] = []
    pacer = Pacer(lambda: calls.append(1), period=0.001, name="t", realtime=False,
                  batch_s=0.01)
    pacer.run_for(0.25)
    assert len(calls) == 250
    pacer.start()
    wait_for(lambda: len(calls) > 400, 30, "batches of periods")
    pacer.stop(timeout=5)
    assert not pacer.alive and pacer.stats().skipped == 0


@pytest.mark.realtime
def test_a_stalled_period_skips_time_instead_of_racing_and_says_so():
    """A period that takes 60 ms at a 5 ms period: the pacer drops the periods it missed
    (counted) instead of running them in a burst, and goes on at its pace."""
    stall = {"left": 1}
    starts: list[float] = []

    def step() -> None:
        starts.append(time.perf_counter())
        if len(starts) == 20 and stall["left"]:
            stall["left"] = 0
            time.sleep(0.06)

    pacer = Pacer(step, period=0.005, name="t", realtime=True)
    pacer.start()
    wait_for(lambda: len(starts) > 60, 60, "periods after the stall")
    pacer.stop(timeout=5)
    stats = pacer.stats()
    assert stats.overruns >= 1 and stats.skipped >= 8  # >= 11 periods were due at once
    assert stats.skipped_recent == stats.skipped  # all within the last 10 s
    assert stats.late_p50_ms is not None and stats.interval_mean_ms is not None
    resumed = starts[20]  # the first period after the stall (60 ms after the stalled one)
    assert resumed - starts[19] >= 0.06
    # no burst of catch-up periods: in the 20 ms after it, at most what the clock allows
    # (4 periods, +1 for phase); a burst would run the 11 missed periods at once
    assert sum(resumed < t <= resumed + 0.02 for t in starts) <= 5


def test_a_wait_without_spin_sleeps_to_its_deadline_and_burns_no_core():
    stop = threading.Event()
    for spin_s in (0.0, SPIN_S):
        deadline = time.perf_counter() + 0.05
        cpu = time.thread_time()
        sleep_until(deadline, stop, spin_s=spin_s)
        used = time.thread_time() - cpu
        assert time.perf_counter() >= deadline  # never early
        if spin_s == 0.0:  # asleep all the way: a spinning wait would use ~spin_s of CPU
            assert used < 0.005, used
    # a simulated world's clock waits that way (its ticks need no microseconds)
    assert SharedClock(lambda: None, dt=0.001)._pacer.spin_s == 0.0
    stop.set()  # a stopped loop does not wait: an hour's wait returns (sleeping costs no
    # CPU time, so only its return shows it did not sleep)
    waiter = threading.Thread(target=sleep_until, args=(time.perf_counter() + 3600.0, stop),
                              daemon=True)
    waiter.start()
    waiter.join(timeout=60)
    assert not waiter.is_alive()
