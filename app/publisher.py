"""The thread that pushes a lesson's state to every open page.

It calls the lesson's ``pose`` function ``pose_hz`` times a second (30 by
default) and its ``plots`` function ``plot_hz`` times a second (11: a margin
over the 10 Hz the charts must reach). Each pose frame is one
``server.atomic()`` block, so the links move together; chart frames are not
(viser holds a page's whole stream while an atomic block is open). viser replaces
a pending update of a property by the newer one, so a slow browser skips stale
frames rather than queueing them; a publisher of one page (``app.page.Page``)
makes no frame while that page has not been sent the last one. Nothing is
computed or sent while no browser is connected; the first browser to connect
gets a full frame at once.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import viser

log = logging.getLogger(__name__)

#: Seconds :meth:`Publisher.close` waits for open pages to apply the last frame.
CLOSE_SETTLE_S = 0.5


@dataclass
class PublisherStats:
    """Counters since start (read by the UI bench)."""

    pose_frames: int = 0
    plot_frames: int = 0
    skipped_idle: int = 0
    skipped_behind: int = 0  #: frames not made: the page had not been sent the last one
    errors: int = 0
    last_pose_s: float = 0.0  #: wall time spent in the last pose frame
    last_plot_s: float = 0.0  #: wall time spent in the last plot frame


class Publisher:
    """Calls ``pose()`` at ``pose_hz`` and ``plots()`` at ``plot_hz`` inside ``server.atomic()``.

    Args:
        server: the viser server.
        pose: updates the 3D scene (cheap; called every tick).
        plots: updates charts and numbers; receives ``force=True`` on the first
            frame after a browser connects.
        pose_hz: scene update rate, Hz.
        plot_hz: chart update rate, Hz (at most ``pose_hz``).
    """

    def __init__(self, server: viser.ViserServer, *, pose: Callable[[], None],
                 plots: Callable[[bool], None], pose_hz: float = 30.0,
                 plot_hz: float = 11.0) -> None:
        if not (0 < pose_hz <= 240 and 0 < plot_hz <= 240):
            raise ValueError(f"pose_hz, plot_hz: expected 0 < Hz <= 240, got {pose_hz}, "
                             f"{plot_hz}")
        self.server = server
        self._pose = pose
        self._plots = plots
        self.pose_hz = pose_hz
        self.plot_hz = plot_hz
        self.stats = PublisherStats()
        # a one-page "server" (app.page.Page) says when its page is behind
        self._behind: Callable[[], bool] | None = getattr(server, "behind", None)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="armlab-publisher", daemon=True)
        self._hooks: list[Callable[[], None]] = []

    def add_frame_hook(self, hook: Callable[[], None]) -> None:
        """Call ``hook()`` inside each pose frame's atomic block (after ``pose``)."""
        self._hooks.append(hook)

    def start(self) -> None:
        self._thread.start()

    def close(self, *, settle_s: float = CLOSE_SETTLE_S) -> None:
        """Stop the thread (waits for the current frame).

        If frames were sent, wait ``settle_s`` more: the page applies GUI updates once per
        rendered frame, after the removals of the same batch, so a lesson that removes its
        GUI right after its last frame makes the page log "Tried to update non-existent
        component". The pause lets open pages apply that frame first.
        """
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        if self.stats.pose_frames and settle_s > 0 and self.server.get_clients():
            self.server.flush()
            time.sleep(settle_s)

    def _run(self) -> None:
        pose_period = 1.0 / self.pose_hz
        plot_period = 1.0 / self.plot_hz
        next_pose = next_plot = time.perf_counter()
        had_clients = False
        while not self._stop.is_set():
            now = time.perf_counter()
            has_clients = bool(self.server.get_clients())
            force = has_clients and not had_clients
            pose_due, plot_due = now >= next_pose, now >= next_plot
            if (has_clients and (pose_due or plot_due) and not force
                    and self._behind is not None and self._behind()):
                self.stats.skipped_behind += 1  # the last frame is still on its way
            elif has_clients and (pose_due or plot_due or force):
                self._frame(pose=pose_due or force, plots=plot_due or force, force=force)
            elif not has_clients:
                self.stats.skipped_idle += 1
            had_clients = has_clients
            # Advance each schedule; after a stall skip ahead instead of bursting.
            if pose_due:
                next_pose = max(next_pose + pose_period, now - pose_period)
            if plot_due:
                next_plot = max(next_plot + plot_period, now - plot_period)
            delay = min(next_pose, next_plot) - time.perf_counter()
            self._stop.wait(max(delay, 0.0))

    def _frame(self, *, pose: bool, plots: bool, force: bool) -> None:
        t0 = t1 = time.perf_counter()
        try:
            if pose:
                with self.server.atomic():  # the links move together
                    self._pose()
                    for hook in self._hooks:
                        hook()
                t1 = time.perf_counter()
                self.stats.pose_frames += 1
                self.stats.last_pose_s = t1 - t0
            if plots:  # not atomic: viser sends nothing to a page while an atomic block
                # is open, and a slow chart frame would hold that page's poses back
                self._plots(force)
                self.stats.plot_frames += 1
                self.stats.last_plot_s = time.perf_counter() - t1
        except Exception:  # one bad frame must not freeze every page: log it, go on
            self.stats.errors += 1
            if self.stats.errors <= 3:
                log.exception("publisher frame failed")
