"""How every loop of the lab is paced (``armlab.control.loop.ControlLoop``,
``armlab.control.gait_loop.GaitLoop``, ``armlab.control.grip_loop.GripLoop``; their
record is an :class:`armlab.control.ring_buffer.RingBuffer`).

:class:`Pacer` runs one period of loop time per ``step()`` call, in its own thread or
now. Real time: it wakes every ``batch_s`` of wall time (one period when ``batch_s`` is
the period, as the arm's control loop does) and runs the periods that are due, never
more than ``max_catch_up`` s of them at once: a stalled machine skips time, counted in
:attr:`PaceStats.skipped`, rather than racing through a burst of late periods. It
measures how late each wake-up was (jitter) and the time between wake-ups. Not real time
(tests, headless): batches of periods back to back, as fast as the machine goes.

:class:`SharedClock` steps one world (e.g. a class's ``BatchedPlant``) and the loops
attached to it in lockstep, in one thread: each loop gets a :class:`DrivenPacer` from
:meth:`SharedClock.pacer` in place of its own :class:`Pacer` (same interface as the
loops use it) and runs its periods when the world's time reaches them.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

#: s a running pacer's :meth:`Pacer.stats` is reused: it sums up the last 1000 wake-ups,
#: and every page reads it in every frame (30 private arms share one clock's statistics).
STATS_TTL_S = 0.2
#: s of each wait a control loop's pacer spends spinning (:func:`sleep_until`): a 16 ms
#: control period's start within microseconds (``loop_jitter_p99_ms``)
SPIN_S = 0.0015


@dataclass(frozen=True)
class PaceStats:
    """How well a real-time pacer kept time (None before the first wake-ups).

    Attributes:
        late_p50_ms, late_p99_ms, late_max_ms: lateness of wake-ups (jitter), ms.
        interval_mean_ms: mean wall time between wake-ups, ms.
        overruns: wake-ups so late that periods had to be skipped.
        skipped: periods skipped in all.
        skipped_recent: periods skipped in the last ``recent_s`` s of wall time.
    """

    late_p50_ms: float | None
    late_p99_ms: float | None
    late_max_ms: float | None
    interval_mean_ms: float | None
    overruns: int
    skipped: int
    skipped_recent: int


class Pacer:
    """Calls ``step()`` once per ``period`` s of loop time, in a daemon thread or now.

    Args:
        step: one period of the owner's loop.
        period: s (the owner may change :attr:`period` from ``step``; the pacer then
            re-anchors its clock at the next wake-up).
        name: the thread's name.
        realtime: pace by the wall clock (False: as fast as possible).
        batch_s: wall time between wake-ups, s (default: one period).
        max_catch_up: most loop time run at one wake-up, s (default: one batch).
        idle_s: pause between batches when not real time, s.
        catch: exceptions of ``step`` that end the thread (passed to ``on_exit``).
        on_exit: called in the thread as it ends, with the caught exception or None.
        recent_s: the window of :attr:`PaceStats.skipped_recent`, s.
        spin_s: the last part of each wait spent spinning rather than asleep, s (default
            0: sleep all the way, waking ~0.1 ms late, enough for a simulated world's clock
            and the gait and grip loops; :data:`SPIN_S` for a control loop's periods within
            microseconds, for a core's time while it spins).
    """

    def __init__(self, step: Callable[[], None], *, period: float, name: str,
                 realtime: bool = True, batch_s: float | None = None,
                 max_catch_up: float | None = None, idle_s: float = 0.002,
                 catch: tuple[type[Exception], ...] = (),
                 on_exit: Callable[[Exception | None], None] | None = None,
                 recent_s: float = 10.0, spin_s: float = 0.0) -> None:
        self.step = step
        self.period = float(period)
        self.name = name
        self.realtime = realtime
        self.batch_s = batch_s
        self.max_catch_up = max_catch_up
        self.idle_s = idle_s
        self.catch = catch
        self.on_exit = on_exit
        self.recent_s = recent_s
        self.spin_s = float(spin_s)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._late: deque[float] = deque(maxlen=1000)
        self._intervals: deque[float] = deque(maxlen=1000)
        self._skips: deque[tuple[float, int]] = deque(maxlen=1000)  # (wall time, periods)
        self._overruns = 0
        self._skipped = 0
        self._last_stats: tuple[float, PaceStats] | None = None  # (perf_counter, stats)

    @property
    def running(self) -> bool:
        """A thread was started and not stopped since."""
        return self._thread is not None

    @property
    def alive(self) -> bool:
        """The thread is running now (False after it ended on its own)."""
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start the thread (nothing when it runs)."""
        if self.alive:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
        self._thread.start()

    def stop(self, timeout: float) -> None:
        """Stop the thread, waiting up to ``timeout`` s for the current batch (not when
        called from the thread itself)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=timeout)
        self._thread = None

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of periods now, in the calling thread (the thread must not run)."""
        if self.alive:
            raise RuntimeError("run_for: the loop thread is running")
        for _ in range(max(1, round(seconds / self.period))):
            self.step()

    def stats(self) -> PaceStats:
        """The lateness and skips measured so far (real time only); while the thread runs,
        the same figures for :data:`STATS_TTL_S` s."""
        now = time.perf_counter()
        last = self._last_stats
        if last is not None and now - last[0] < STATS_TTL_S and self.alive:
            return last[1]
        with self._lock:  # copy only: the loop's thread takes this lock every wake-up
            late = np.array(self._late) if self._late else None
            gaps = np.array(self._intervals) if self._intervals else None
            skips = tuple(self._skips)
            overruns, skipped = self._overruns, self._skipped
        since = time.perf_counter() - self.recent_s
        p50 = p99 = top = None
        if late is not None:
            p50, p99 = (float(v) * 1e3 for v in np.percentile(late, (50, 99)))
            top = float(late.max() * 1e3)
        stats = PaceStats(
            late_p50_ms=p50, late_p99_ms=p99, late_max_ms=top,
            interval_mean_ms=None if gaps is None else float(gaps.mean() * 1e3),
            overruns=overruns, skipped=skipped,
            skipped_recent=sum(k for t, k in skips if t >= since))
        self._last_stats = (now, stats)
        return stats

    def _run(self) -> None:
        error: Exception | None = None
        try:
            if self.realtime:
                self._pace_until_stopped()
            else:
                while not self._stop.is_set():
                    for _ in range(self._per_wake()):
                        self.step()
                    self._stop.wait(self.idle_s)
        except self.catch as exc:
            error = exc
        if self.on_exit is not None:
            self.on_exit(error)

    def _per_wake(self) -> int:
        batch = self.period if self.batch_s is None else self.batch_s
        return max(1, round(batch / self.period))

    def _pace_until_stopped(self) -> None:
        period = self.period
        start = time.perf_counter()  # the wall time of period 0 of this anchor
        done = 0  # periods run since the anchor
        last_wake: float | None = None
        while not self._stop.is_set():
            per_wake = self._per_wake()
            wake_at = start + (done + per_wake - 1) * period
            sleep_until(wake_at, self._stop, spin_s=self.spin_s)
            if self._stop.is_set():
                break
            now = time.perf_counter()
            due = int((now - start) / period) + 1 - done  # periods whose start has passed
            limit = max(per_wake, round((self.max_catch_up or per_wake * period) / period))
            with self._lock:
                self._late.append(max(0.0, now - wake_at))
                if last_wake is not None:
                    self._intervals.append(now - last_wake)
                if due > limit:  # fell behind: skip wall time, do not race
                    self._overruns += 1
                    self._skipped += due - limit
                    self._skips.append((now, due - limit))
                    start += (due - limit) * period
                    due = limit
            last_wake = now
            for _ in range(due):
                self.step()
            done += due
            if self.period != period:  # the owner changed its period: a new anchor
                period, start, done = self.period, time.perf_counter(), 0


def sleep_until(deadline: float, stop: threading.Event, *, spin_s: float = 0.0) -> None:
    """Sleep to ``deadline`` (perf_counter s): coarse sleep, then ``spin_s`` s of spinning
    (yielding the interpreter) for precision; returns early when ``stop`` is set."""
    while True:
        left = deadline - time.perf_counter()
        if left <= 0 or stop.is_set():
            return
        if spin_s <= 0.0:
            time.sleep(left)
        elif left > spin_s + 0.0005:
            time.sleep(left - spin_s)
        elif left > 0.0002:
            time.sleep(0)
        # else spin the last 0.2 ms


class DrivenPacer:
    """A :class:`Pacer` whose periods a :class:`SharedClock` runs (made by
    :meth:`SharedClock.pacer`; the interface loops use: ``start``, ``stop``, ``alive``,
    ``running``, ``period``, ``stats``).

    Started at clock step k0, its periods are due at local times 0, P, 2P, ... (``period``
    read after each period, so a change made in ``step`` counts from the next due time).
    Period m is run at the first clock step k with (k − k0 + 0.5)·dt > its local time,
    before the world steps: the world is then where ``Plant.advance_to`` of that time
    would have put a plant of its own. k0 is the first clock step from the start that is
    a whole number of periods of class time (:func:`aligned_step`): pacers of one period
    started at different moments share their ticks, so the class's law of a tick is
    computed for all of them as one (:mod:`armlab.control.law_batch`), and it waits at
    most one period to begin. Started again after a stop, it goes on from its next local
    time, due at the next such step.

    Attributes:
        errors: exceptions ``step`` raised (the clock went on); last_error: the latest.
    """

    def __init__(self, clock: SharedClock, step: Callable[[], None], *, period: float,
                 name: str) -> None:
        if not (isinstance(period, int | float) and math.isfinite(period) and period > 0):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        self.step = step
        self.period = float(period)
        self.name = name
        self.errors = 0
        self.last_error: Exception | None = None
        self._clock = clock
        self._attached = False
        self._k0 = 0  # clock step of local time 0
        self._t_next = 0.0  # local time of the next period, s
        self._k_due = 0  # the clock step its next period runs at: the first k with
        # (k − k0 + 0.5)·dt > t_next (k0 + _steps_before(t_next, dt))
        self._last_wall: float | None = None
        self._intervals: deque[float] = deque(maxlen=1000)
        self._gap_sum = 0.0  # sum of _intervals, kept as they come and go (read every frame)
        self._stats_lock = threading.Lock()  # the clock appends, a UI thread reads

    @property
    def running(self) -> bool:
        """Attached to the clock (started and not stopped)."""
        return self._attached

    @property
    def alive(self) -> bool:
        """Attached and the clock's thread is running (False headless: as a stepped loop)."""
        return self._attached and self._clock.alive

    def start(self) -> None:
        """Attach to the clock: the next period is due at the first clock step from now
        that is a whole number of periods of class time (:func:`aligned_step`)."""
        with self._clock.lock:
            if self._attached:
                return
            due = aligned_step(self._clock.steps, self.period, self._clock.dt)
            self._k0 = due - _steps_before(self._t_next, self._clock.dt)
            self._k_due = due
            self._last_wall = None
            self._attached = True
            self._clock._attach(self)

    def stop(self, timeout: float) -> None:
        """Detach from the clock; returns after the clock's current tick (waiting up to
        ``timeout`` s for it)."""
        self._attached = False
        lock = self._clock.lock
        if lock.acquire(timeout=max(0.0, float(timeout))):
            try:
                self._clock._detach(self)
            finally:
                lock.release()

    def run_for(self, seconds: float) -> None:
        """Not for a driven pacer: its periods run when the clock's time reaches them."""
        raise RuntimeError(f"{self.name}: driven by a shared clock; use SharedClock.run_for")

    def stats(self) -> PaceStats:
        """Lateness, overruns and skips of the clock's wake-ups (the whole class's: skips in
        this loop's periods), mean wall time between this loop's periods (real time)."""
        base = self._clock.stats()
        with self._stats_lock:
            count, total = len(self._intervals), self._gap_sum
        scale = self._clock.dt / self.period
        return PaceStats(
            late_p50_ms=base.late_p50_ms, late_p99_ms=base.late_p99_ms,
            late_max_ms=base.late_max_ms,
            interval_mean_ms=total / count * 1e3 if count else None,
            overruns=base.overruns, skipped=round(base.skipped * scale),
            skipped_recent=round(base.skipped_recent * scale))

    def _fire(self) -> None:
        """One period (in the clock's thread, the lock held); never raises."""
        if self._clock.realtime and self._clock.alive:
            now = time.perf_counter()
            if self._last_wall is not None:
                gap = now - self._last_wall
                with self._stats_lock:
                    if len(self._intervals) == self._intervals.maxlen:
                        self._gap_sum -= self._intervals[0]  # about to drop out
                    self._intervals.append(gap)
                    self._gap_sum += gap
            self._last_wall = now
        try:
            self.step()
        except Exception as exc:  # one loop's failure must not stop the class
            self.errors += 1
            self.last_error = exc
        if not (math.isfinite(self.period) and self.period > 0):  # would never end the tick
            self.errors += 1
            self.last_error = ValueError(f"{self.name}: period set to {self.period!r}; "
                                         "detached from the clock")
            self._attached = False
            return
        self._t_next += self.period
        self._k_due = self._k0 + _steps_before(self._t_next, self._clock.dt)


def aligned_step(k: int, period: float, dt: float) -> int:
    """The first clock step from ``k`` on that is a whole number of periods of ``period``
    s of class time (steps of ``dt`` s; a period rounded to whole steps, at least one):
    where a :class:`DrivenPacer` started at step ``k`` runs its first period."""
    every = max(1, round(period / dt))
    return -(-k // every) * every


def _steps_before(t: float, dt: float) -> int:
    """The first m >= 0 with (m + 0.5)·dt > t: the clock steps after its local time 0 at
    which a period of local time ``t`` s is due."""
    m = max(0, int(t / dt) - 1)
    while (m + 0.5) * dt <= t:
        m += 1
    return m


#: s at most that a :class:`SharedClock` waits between two ticks for the threads waiting
#: on its :class:`HandOverLock` to have had their turn
HAND_OVER_S = 0.002


class HandOverLock:
    """A re-entrant lock that a :class:`SharedClock` hands to waiting threads between ticks.

    CPython's locks are not fair. The clock's thread releases its lock at the end of a
    tick and takes it again for the next before a thread woken to take it has run, so a
    page reading its arm (the Servos panel, the class overview) waited for a whole batch
    of ticks: 8 ms, or 50 ms of catch-up on a busy machine, for each of 30 pages. A
    thread that has to wait here counts itself (:attr:`waiting`); the clock, between two
    ticks, lets the waiters in first (:meth:`SharedClock._tick`). It is used as an RLock
    is: ``with lock:``, ``acquire()``, ``release()``.
    """

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._count = threading.Lock()
        self._waiting = 0

    @property
    def waiting(self) -> int:
        """Threads blocked in :meth:`acquire` now."""
        return self._waiting

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        """Take the lock (again, in the thread that holds it); as ``RLock.acquire``."""
        if self._lock.acquire(False):
            return True
        if not blocking:
            return False
        with self._count:
            self._waiting += 1
        try:
            return self._lock.acquire(True, timeout)
        finally:
            with self._count:
                self._waiting -= 1

    def release(self) -> None:
        """Release it once (as ``RLock.release``)."""
        self._lock.release()

    def _is_owned(self) -> bool:
        """Whether the calling thread holds it (as ``RLock._is_owned``, which
        ``threading.Condition`` uses)."""
        return self._lock._is_owned()  # type: ignore[attr-defined]  # RLock's private _is_owned (threading.Condition uses it)

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


class SharedClock:
    """One thread stepping a world by ``dt`` and the loops attached to it in lockstep.

    Per tick, holding ``lock``: every attached :class:`DrivenPacer` whose period is due
    runs it (in the order they were started), then the tick's finishers run (added with
    :meth:`finish_periods`: e.g. the lab's law of every period due, computed as one), then
    ``step()`` advances the world one ``dt`` and the clock's time by ``dt``. An exception
    of ``step`` is counted (:attr:`errors`, :attr:`last_error`), passed to ``on_error``
    and the clock goes on (a period's exception is counted on its pacer; a ControlLoop
    catches its own).

    Args:
        step: one world step of ``dt`` (e.g. ``BatchedPlant.step``).
        dt: s per tick.
        realtime: pace ticks by the wall clock (a :class:`Pacer` of period ``dt``, which
            sleeps all the way to each wake-up); False: as fast as possible.
        lock: held around each tick (default a new :class:`HandOverLock`; share it with
            whatever else touches the world, e.g. the backends). Between two ticks the
            clock lets the threads waiting on a HandOverLock in first (at most
            ``hand_over_s``).
        name: the thread's name.
        batch_s: wall time between wake-ups when real time, s (ticks due run together).
        max_catch_up: most world time run at one wake-up, s (beyond: skipped).
        hand_over_s: most wall time the clock waits between two ticks for the threads
            waiting on its :class:`HandOverLock`, s.
        on_error: called with an exception of ``step`` (in the clock's thread, ``lock``
            held), e.g. to put a diverged arm back (``BatchedPlant.step`` raises
            FloatingPointError naming the arms after stepping every arm).
    """

    def __init__(self, step: Callable[[], None], *, dt: float, realtime: bool = True,
                 lock: HandOverLock | threading.RLock | None = None,
                 name: str = "armlab-class",
                 batch_s: float = 0.008, max_catch_up: float = 0.05,
                 hand_over_s: float = HAND_OVER_S,
                 on_error: Callable[[Exception], None] | None = None) -> None:
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        self.step = step
        self.dt = float(dt)
        self.realtime = realtime
        self.lock = HandOverLock() if lock is None else lock
        self.name = name
        self.errors = 0
        self.last_error: Exception | None = None
        self.on_error = on_error
        self.hand_over_s = float(hand_over_s)
        self._k = 0
        self._pacers: list[DrivenPacer] = []
        self._finishers: list[Callable[[], None]] = []
        self._ticking = False
        self._pacer = Pacer(self._tick, period=self.dt, name=name, realtime=realtime,
                            batch_s=max(self.dt, batch_s), max_catch_up=max_catch_up)

    @property
    def steps(self) -> int:
        """Ticks run (t = steps · dt)."""
        return self._k

    @property
    def t(self) -> float:
        """The clock's time, s."""
        return self._k * self.dt

    @property
    def alive(self) -> bool:
        """The clock's thread is running."""
        return self._pacer.alive

    @property
    def loops(self) -> int:
        """Pacers attached."""
        return len(self._pacers)

    def pacer(self, step: Callable[[], None], *, period: float, name: str) -> DrivenPacer:
        """A pacer for a loop on this clock (runs nothing until its ``start()``)."""
        return DrivenPacer(self, step, period=period, name=name)

    def start(self) -> None:
        """Start the clock's thread (nothing when it runs). Real time: lowers the
        interpreter's thread switch interval to 1 ms, as a paced ControlLoop does."""
        if self.realtime:
            sys.setswitchinterval(min(sys.getswitchinterval(), 0.001))
        self._pacer.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the thread after its current batch (the pacers stay attached)."""
        self._pacer.stop(timeout)

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of ticks now in the calling thread (headless; tests, benches)."""
        if self._pacer.alive:
            raise RuntimeError("run_for: the clock's thread is running")
        for _ in range(round(float(seconds) / self.dt)):
            self._tick()

    def stats(self) -> PaceStats:
        """The clock's wake-up lateness and skips (its ticks; real time only)."""
        return self._pacer.stats()

    def finish_periods(self, finish: Callable[[], None]) -> None:
        """Run ``finish`` at every tick once its periods have run, before the world steps
        (:class:`~armlab.control.law_batch.LawBatch`: the periods waiting for their law). An
        exception of ``finish`` is counted (:attr:`errors`), and the world steps."""
        if finish not in self._finishers:
            self._finishers.append(finish)

    def _attach(self, pacer: DrivenPacer) -> None:
        if pacer not in self._pacers:
            self._pacers.append(pacer)

    def _detach(self, pacer: DrivenPacer) -> None:
        if not self._ticking and pacer in self._pacers:  # in a tick: the tick drops it
            self._pacers.remove(pacer)

    def _tick(self) -> None:
        with self.lock:
            k = self._k
            i = 0
            self._ticking = True
            try:
                while i < len(self._pacers):  # a pacer started in a period runs this tick too
                    p = self._pacers[i]
                    while p._attached and k >= p._k_due:
                        p._fire()
                    i += 1
            finally:
                self._ticking = False
                self._pacers = [p for p in self._pacers if p._attached]
            for finish in self._finishers:
                try:
                    finish()
                except Exception as exc:  # the world steps whatever a finisher did
                    self.errors += 1
                    self.last_error = exc
            try:
                self.step()
            except Exception as exc:  # e.g. one arm diverged: the others go on
                self.errors += 1
                self.last_error = exc
                if self.on_error is not None:
                    try:
                        self.on_error(exc)
                    except Exception as again:  # the clock must not die of its handler
                        self.last_error = again
            finally:
                self._k += 1
        if getattr(self.lock, "waiting", 0):
            self._hand_over()

    def _hand_over(self) -> None:
        """Between two ticks, the lock released: let the threads waiting on it take it
        before the next tick does (at most :attr:`hand_over_s`)."""
        deadline = time.perf_counter() + self.hand_over_s
        lock = cast(HandOverLock, self.lock)  # _tick calls this only for a lock that counts
        while lock.waiting and time.perf_counter() < deadline:
            time.sleep(0)  # gives the interpreter to a woken waiter
