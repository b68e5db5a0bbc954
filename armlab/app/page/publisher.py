"""The thread that pushes a lesson's state to every open page.

It calls the lesson's ``pose`` function ``pose_hz`` times a second (30 by
default) and its ``plots`` function ``plot_hz`` times a second (11: a margin
over the 10 Hz the charts must reach). Each pose frame is one
``server.atomic()`` block, so the links move together; on the whole server chart
frames are not (viser holds every page's stream while an atomic block is open),
on one page (:class:`armlab.app.classroom.private_page.Page`) the whole frame is. viser replaces
a pending update of a property by the newer one, so a slow browser skips stale
frames rather than queueing them; a publisher of one page
(``armlab.app.classroom.private_page.Page``)
makes no frame while that page has not been sent the last one: it looks again every
:data:`BEHIND_RETRY_S` and gives the frame up only when the next one falls due; a page
behind for :data:`BEHIND_MAX_S` gets its frame anyway (on a busy server a page kept behind
by its share of the traffic must not freeze, and the frame wakes its sender). Nothing is
computed or sent while no browser is connected; the first browser to connect
gets a full frame at once.

A publisher makes its frames on a thread of its own, or on a :class:`FrameThread`
it shares with others: a classroom's private pages share one, so thirty pages'
frames are made one after another instead of by thirty threads taking the
interpreter from each other (each handover of Python's GIL between threads costs
a wake-up, and a late wake-up is a late frame).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from armlab.app.page.surface import Surface

log = logging.getLogger(__name__)

#: Seconds :meth:`Publisher.close` waits for open pages to apply the last frame.
CLOSE_SETTLE_S = 0.5
#: Seconds after which a publisher of one page looks again when a frame fell due while
#: the page had not yet been sent the last one.
BEHIND_RETRY_S = 0.004
#: Seconds a publisher of one page gives its frames up while the page is behind; then it
#: makes one anyway (at most one a BEHIND_MAX_S: viser replaces a pending update by a newer
#: one, so a page that is slow to read is never sent a growing backlog).
BEHIND_MAX_S = 1.0


@dataclass
class PublisherStats:
    """Counters since start (read by the UI bench)."""

    pose_frames: int = 0
    plot_frames: int = 0
    skipped_idle: int = 0
    skipped_behind: int = 0  #: frames not made: the page had not been sent the last one
    waited_behind: int = 0  #: looks again a little later, for the same reason
    forced_behind: int = 0  #: frames made with the page behind for BEHIND_MAX_S
    errors: int = 0
    last_pose_s: float = 0.0  #: wall time spent in the last pose frame
    last_plot_s: float = 0.0  #: wall time spent in the last plot frame


class Publisher:
    """Calls ``pose()`` at ``pose_hz`` and ``plots()`` at ``plot_hz`` inside ``server.atomic()``.

    Args:
        server: where the lesson is: the lab's server (every page) or one page.
        pose: updates the 3D scene (cheap; called every tick).
        plots: updates charts and numbers; receives ``force=True`` on the first
            frame after a browser connects.
        pose_hz: scene update rate, Hz.
        plot_hz: chart update rate, Hz (at most ``pose_hz``).
        frames: the thread that makes the frames, shared with other publishers (None: a
            thread of this publisher's own).
        every: called at every tick of the schedule, whether a frame is made or not (no
            page open, or the page behind): what the lesson does at the frames' pace for
            whoever watches, such as measuring an experiment once it is over.
    """

    def __init__(self, server: Surface, *, pose: Callable[[], None],
                 plots: Callable[[bool], None], pose_hz: float = 30.0,
                 plot_hz: float = 11.0, frames: FrameThread | None = None,
                 every: Callable[[], None] | None = None) -> None:
        if not (0 < pose_hz <= 240 and 0 < plot_hz <= 240):
            raise ValueError(f"pose_hz, plot_hz: expected 0 < Hz <= 240, got {pose_hz}, "
                             f"{plot_hz}")
        self.server = server
        self._pose = pose
        self._plots = plots
        self._every = every
        self.pose_hz = pose_hz
        self.plot_hz = plot_hz
        self.stats = PublisherStats()
        # a one-page "server" (armlab.app.classroom.private_page.Page) says when its page is behind
        self._behind: Callable[[], bool] | None = getattr(server, "behind", None)
        self._stop = threading.Event()
        self._frames = frames
        self._thread = threading.Thread(target=self._run, name="armlab-publisher", daemon=True)
        self._hooks: list[Callable[[], None]] = []
        # the schedule (perf_counter s) and whether a page was open at the last tick
        self._next_pose = self._next_plot = 0.0
        self._had_clients = False
        self._behind_since: float | None = None  #: when the page was first found behind

    def add_frame_hook(self, hook: Callable[[], None]) -> None:
        """Call ``hook()`` inside each pose frame's atomic block (after ``pose``)."""
        self._hooks.append(hook)

    def start(self) -> None:
        """Start making frames (on the shared frame thread if one was given)."""
        self._next_pose = self._next_plot = time.perf_counter()
        if self._frames is None:
            self._thread.start()
        else:
            self._frames.add(self)

    def close(self, *, settle_s: float = CLOSE_SETTLE_S) -> None:
        """Stop making frames (waits for the current frame).

        If frames were sent, wait ``settle_s`` more: the page applies GUI updates once per
        rendered frame, after the removals of the same batch, so a lesson that removes its
        GUI right after its last frame makes the page log "Tried to update non-existent
        component". The pause lets open pages apply that frame first.
        """
        self._stop.set()
        if self._frames is not None:
            self._frames.remove(self)
        elif self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        if self.stats.pose_frames and settle_s > 0 and self.server.get_clients():
            self.server.flush()
            time.sleep(settle_s)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._stop.wait(max(self._tick() - time.perf_counter(), 0.0))

    def _tick(self) -> float:
        """Make the frames that are due; return when the next one is (perf_counter s)."""
        if self._every is not None:
            try:
                self._every()
            except Exception:  # as a bad frame: logged, and the frames go on
                self._failed("publisher tick failed")
        now = time.perf_counter()
        has_clients = bool(self.server.get_clients())
        force = has_clients and not self._had_clients
        pose_due, plot_due = now >= self._next_pose, now >= self._next_plot
        behind = (has_clients and (pose_due or plot_due) and not force
                  and self._behind is not None and self._behind())
        if not behind:
            self._behind_since = None
        elif self._behind_since is None:
            self._behind_since = now
        since = self._behind_since  # None exactly when the page is not behind
        if since is not None and now - since < BEHIND_MAX_S:
            # the last frame is still on its way: look again shortly, and give this frame
            # up only when the next one falls due (a frame late rather than none)
            if now - min(self._next_pose, self._next_plot) < 1.0 / self.pose_hz:
                self.stats.waited_behind += 1
                return now + BEHIND_RETRY_S
            self.stats.skipped_behind += 1
        elif has_clients and (pose_due or plot_due or force):
            if behind:  # behind for BEHIND_MAX_S: this frame is made all the same
                self.stats.forced_behind += 1
                self._behind_since = None
            self._frame(pose=pose_due or force, plots=plot_due or force, force=force)
        elif not has_clients:
            self.stats.skipped_idle += 1
        self._had_clients = has_clients
        # Advance each schedule; after a stall skip ahead instead of bursting.
        if pose_due:
            self._next_pose = max(self._next_pose + 1.0 / self.pose_hz,
                                  now - 1.0 / self.pose_hz)
        if plot_due:
            self._next_plot = max(self._next_plot + 1.0 / self.plot_hz,
                                  now - 1.0 / self.plot_hz)
        return min(self._next_pose, self._next_plot)

    def _frame(self, *, pose: bool, plots: bool, force: bool) -> None:
        # A page's own frame (a one-page server) is one atomic block, charts included: the
        # block holds only that page's messages, and viser wakes its sender once per block
        # instead of once per message (a system call that lets another thread take the
        # GIL, which the frame then waits to get back). On the whole server the charts stay
        # outside: its block would hold every page's stream while a chart frame is made.
        page = self._behind is not None
        whole = self.server.atomic() if page else contextlib.nullcontext()
        # the links move together: in the page's block, or in a block of their own
        links = contextlib.nullcontext() if page else self.server.atomic()
        t0 = t1 = time.perf_counter()
        try:
            with whole:
                if pose:
                    with links:
                        self._pose()
                        for hook in self._hooks:
                            hook()
                    t1 = time.perf_counter()
                    self.stats.pose_frames += 1
                    self.stats.last_pose_s = t1 - t0
                if plots:
                    self._plots(force)
                    self.stats.plot_frames += 1
                    self.stats.last_plot_s = time.perf_counter() - t1
        except Exception:  # one bad frame must not freeze every page: log it, go on
            self._failed("publisher frame failed")

    def _failed(self, what: str) -> None:
        """Count the error being handled; log the first three."""
        self.stats.errors += 1
        if self.stats.errors <= 3:
            log.exception(what)


class FrameThread:
    """One thread that makes the frames of many publishers, each when it is due.

    The publishers take turns in the order their frames fall due, so when the thread
    cannot keep up every publisher's rate drops alike. A frame that raises is logged
    by its publisher and the others go on.

    Args:
        name: the thread's name.
    """

    def __init__(self, *, name: str = "armlab-frames") -> None:
        self._cond = threading.Condition()
        self._due: list[tuple[float, int, Publisher]] = []  # a heap: (due, order, publisher)
        self._members: set[Publisher] = set()
        self._order = itertools.count()
        self._busy: Publisher | None = None  # the publisher making a frame now
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def add(self, publisher: Publisher) -> None:
        """Make ``publisher``'s frames from now on (its first tick is due now)."""
        with self._cond:
            if self._closed:
                raise RuntimeError("FrameThread: closed")
            self._members.add(publisher)
            heapq.heappush(self._due, (time.perf_counter(), next(self._order), publisher))
            self._cond.notify()

    def remove(self, publisher: Publisher) -> None:
        """Make no more of ``publisher``'s frames; wait for the one being made, if any
        (unless called from one of those frames)."""
        with self._cond:
            self._members.discard(publisher)
            self._due = [entry for entry in self._due if entry[2] is not publisher]
            heapq.heapify(self._due)
            if threading.current_thread() is not self._thread:
                self._cond.wait_for(lambda: self._busy is not publisher, timeout=2.0)

    def close(self) -> None:
        """Stop the thread (after the frame being made)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._closed:
                    wait = self._due[0][0] - time.perf_counter() if self._due else None
                    if wait is not None and wait <= 0:
                        break
                    self._cond.wait(wait)
                if self._closed:
                    return
                _, order, publisher = heapq.heappop(self._due)
                self._busy = publisher
            due = time.perf_counter() + 1.0 / publisher.pose_hz
            try:
                due = publisher._tick()
            except Exception:  # _frame logs a lesson's errors; this is the publisher's own
                log.exception("publisher tick failed")
            finally:
                with self._cond:
                    self._busy = None
                    if publisher in self._members:
                        heapq.heappush(self._due, (due, order, publisher))
                    self._cond.notify_all()
