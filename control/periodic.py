"""What the batched loops share (``control.gait_loop``, ``control.grip_loop``): the thread
that runs their periods and the ring-buffer record the UI reads.

:class:`Ticker` runs one period of loop time per ``step()`` call. Real time: each tick
(``tick_s``, 10 ms) it runs the periods that are due on the wall clock, never more than
``max_catch_up`` s of them at once (a stalled machine skips time rather than racing).
Not real time (tests, headless): a tick's worth of periods after another, as fast as it
can. ``control.loop.ControlLoop`` paces differently (one period per wake-up, with jitter
statistics) and does not use it.

:class:`RowRing` keeps the newest rows of a fixed width, column 0 the time in s: one
writer appends, any thread takes a copy.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

import numpy as np


class Ticker:
    """Calls ``step()`` once per ``period`` s of loop time, in a daemon thread or now.

    Args:
        step: one period of the owner's loop.
        period: s.
        name: the thread's name.
        realtime: pace by the wall clock (False: as fast as possible).
        tick_s: wall time between batches of periods, s.
        max_catch_up: most loop time run in one tick, s.
        idle_s: pause between batches when not real time, s.
        catch: exceptions of ``step`` that end the thread (passed to ``on_exit``).
        on_exit: called in the thread as it ends, with the caught exception or None.
    """

    def __init__(self, step: Callable[[], None], *, period: float, name: str,
                 realtime: bool = True, tick_s: float = 0.01, max_catch_up: float = 0.1,
                 idle_s: float = 0.002, catch: tuple[type[Exception], ...] = (),
                 on_exit: Callable[[Exception | None], None] | None = None) -> None:
        self.step = step
        self.period = period
        self.name = name
        self.realtime = realtime
        self.tick_s = tick_s
        self.max_catch_up = max_catch_up
        self.idle_s = idle_s
        self.catch = catch
        self.on_exit = on_exit
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        """A thread was started and not stopped since."""
        return self._thread is not None

    def start(self) -> None:
        """Start the thread (nothing when it runs)."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
        self._thread.start()

    def stop(self, timeout: float) -> None:
        """Stop the thread, waiting up to ``timeout`` s for the current tick (not when
        called from the thread itself)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=timeout)
        self._thread = None

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of periods now, in the calling thread (the thread must not run)."""
        if self._thread is not None:
            raise RuntimeError("run_for: the loop thread is running")
        for _ in range(max(1, round(seconds / self.period))):
            self.step()

    def _run(self) -> None:
        error: Exception | None = None
        try:
            self._tick_until_stopped()
        except self.catch as exc:
            error = exc
        if self.on_exit is not None:
            self.on_exit(error)

    def _tick_until_stopped(self) -> None:
        start = time.perf_counter()
        done = 0
        per_tick = max(1, round(self.tick_s / self.period))
        limit = max(1, round(self.max_catch_up / self.period))
        while not self._stop.is_set():
            if self.realtime:
                due = int((time.perf_counter() - start) / self.period) - done
                if due > limit:  # fell behind: skip wall time, do not race
                    start += (due - limit) * self.period
                    due = limit
            else:
                due = per_tick
            for _ in range(due):
                self.step()
            done += due
            self._stop.wait(self.tick_s if self.realtime else self.idle_s)


class RowRing:
    """The newest rows of ``width`` floats (NaN until written); column 0 is time, s.

    Args:
        width: floats per row.
        seconds: how much history to keep, s.
        period: s between rows (keeps ``max(2, ceil(seconds / period))`` rows).
    """

    def __init__(self, width: int, *, seconds: float, period: float) -> None:
        self.capacity = max(2, math.ceil(seconds / period))
        self._rows = np.full((self.capacity, width), np.nan)
        self._count = 0  # rows ever written
        self._lock = threading.Lock()

    def append(self, row: np.ndarray) -> None:
        """Write ``row`` (width,) over the oldest one."""
        with self._lock:
            self._rows[self._count % self.capacity] = row
            self._count += 1

    def rows(self, window_s: float | None = None) -> np.ndarray:
        """(m, width) copy, oldest first: the last ``window_s`` s (None: all kept)."""
        with self._lock:
            n = min(self._count, self.capacity)
            if self._count <= self.capacity:
                rows = self._rows[:n].copy()
            else:
                k = self._count % self.capacity
                rows = np.concatenate([self._rows[k:], self._rows[:k]])
        if window_s is not None and n:
            rows = rows[rows[:, 0] >= rows[-1, 0] - window_s]
        return rows
