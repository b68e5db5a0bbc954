"""The hand's control loop in its own thread, with a ring-buffer record for the UI.

One writer: the loop thread steps the plant and the :class:`GripController`
every control period and appends a row to the record. The UI never touches
either: it posts commands (callables run by the loop thread at its next
period) and reads copies of the record (:meth:`GripLoop.snapshot`).

Real time: each tick (``tick_s``, 10 ms) the loop runs the periods that are
due on the wall clock (never more than ``max_catch_up`` s at once: a stalled
machine skips time rather than racing). Not real time (tests, headless): it
runs a tick's worth of periods after another as fast as it can.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from control.grip import N_FINGERS, GraspTrace, GripController, HandPlant, grasp_figures

#: Record columns (besides t), each (3,) per row: name -> unit.
COLUMNS: dict[str, str] = {
    "voltage": "V",  # motor voltage applied
    "current": "A",  # measured motor current
    "force": "N",  # true fingertip force
    "estimate": "N",  # the controller's force estimate from the current
    "cap": "N",  # the force the controller allows
    "angle": "rad",  # true finger angle
}

Command = Callable[[HandPlant, GripController], None]


@dataclass(frozen=True)
class GripStatus:
    """The loop's latest state, replaced as a whole every period.

    Attributes:
        t: plant time, s.
        modes: each finger's controller mode.
        closed_at: plant time of the last close command, s (None: never closed).
        running: whether the thread runs.
        fault: "" or why the loop stopped.
    """

    t: float = 0.0
    modes: tuple[str, ...] = ("idle",) * N_FINGERS
    closed_at: float | None = None
    running: bool = False
    fault: str = ""


class GripLoop:
    """Runs ``controller`` on ``plant`` every ``controller.dt`` s.

    Args:
        plant: the hand (e.g. ``hardware.hand.HandSim``).
        controller: the grasp controller.
        realtime: pace the loop by the wall clock (False: as fast as possible).
        history_s: seconds of record kept.
        tick_s: wall time between batches of periods.
        max_catch_up: most simulated seconds run in one tick.
    """

    def __init__(self, plant: HandPlant, controller: GripController, *, realtime: bool = True,
                 history_s: float = 10.0, tick_s: float = 0.01,
                 max_catch_up: float = 0.1) -> None:
        self.plant = plant
        self.controller = controller
        self.realtime = realtime
        self.dt = controller.dt
        self.tick_s = tick_s
        self.max_catch_up = max_catch_up
        self._cap = max(2, math.ceil(history_s / self.dt))
        self._width = 1 + N_FINGERS * len(COLUMNS)
        self._rows = np.full((self._cap, self._width), np.nan)
        self._count = 0  # rows ever written
        self._rec_lock = threading.Lock()
        self._commands: deque[Command] = deque()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._current = plant.step(np.zeros(N_FINGERS), self.dt)
        self._closed_at: float | None = None
        self.status = GripStatus(t=plant.t, modes=controller.modes)

    # --- commands (any thread) -----------------------------------------------------
    def post(self, command: Command) -> None:
        """Run ``command(plant, controller)`` in the loop thread before its next period."""
        self._commands.append(command)

    def close_hand(self) -> None:
        """Post a grasp (close with the force limit); :meth:`last_grasp` measures from it."""
        self.post(self._close)

    def _close(self, plant: HandPlant, controller: GripController) -> None:
        controller.close()
        self._closed_at = plant.t

    def open_hand(self) -> None:
        """Post a release."""
        self.post(lambda _p, c: c.open())

    # --- the loop ------------------------------------------------------------------
    def start(self) -> None:
        """Start the loop thread."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="armlab-grip", daemon=True)
        self._thread.start()

    def shutdown(self) -> None:
        """Stop the thread (waits for the current tick); the motors are left at 0 V."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._thread = None
        self.status = GripStatus(self.plant.t, self.controller.modes, self._closed_at, False,
                                 self.status.fault)

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of periods now, in the calling thread (the thread must not run)."""
        if self._thread is not None:
            raise RuntimeError("run_for: the loop thread is running")
        for _ in range(max(1, round(seconds / self.dt))):
            self._period()

    def _run(self) -> None:
        start = time.perf_counter()
        done = 0
        periods_per_tick = max(1, round(self.tick_s / self.dt))
        try:
            while not self._stop.is_set():
                if self.realtime:
                    due = int((time.perf_counter() - start) / self.dt) - done
                    limit = round(self.max_catch_up / self.dt)
                    if due > limit:  # fell behind: skip wall time, do not race
                        start += (due - limit) * self.dt
                        due = limit
                else:
                    due = periods_per_tick
                for _ in range(due):
                    self._period()
                done += due
                self._stop.wait(self.tick_s if self.realtime else 0.0005)
        except (ValueError, RuntimeError, FloatingPointError) as exc:
            self.status = GripStatus(self.plant.t, self.controller.modes, self._closed_at,
                                     False, f"the hand loop stopped: {exc}")
            return
        self.status = GripStatus(self.plant.t, self.controller.modes, self._closed_at, False)

    def _period(self) -> None:
        plant, ctl = self.plant, self.controller
        while self._commands:
            self._commands.popleft()(plant, ctl)
        volts = ctl.update(self._current)
        self._current = plant.step(volts, self.dt)
        row = np.concatenate([
            [plant.t], volts, self._current, plant.contact_force, ctl.estimated_force(),
            ctl.force_cap, plant.finger_angle,
        ])
        with self._rec_lock:
            self._rows[self._count % self._cap] = row
            self._count += 1
        self.status = GripStatus(plant.t, ctl.modes, self._closed_at, self._thread is not None)

    # --- reading (any thread) --------------------------------------------------------
    def snapshot(self, window_s: float | None = None) -> dict[str, np.ndarray]:
        """Copy of the record: "t" (m,) s and each of :data:`COLUMNS` (m, 3), oldest first.

        ``window_s``: only the last that many seconds (None: everything kept).
        """
        with self._rec_lock:
            n = min(self._count, self._cap)
            if self._count <= self._cap:
                rows = self._rows[:n].copy()
            else:
                k = self._count % self._cap
                rows = np.concatenate([self._rows[k:], self._rows[:k]])
        if window_s is not None and n:
            rows = rows[rows[:, 0] >= rows[-1, 0] - window_s]
        out = {"t": rows[:, 0]}
        for i, name in enumerate(COLUMNS):
            out[name] = rows[:, 1 + N_FINGERS * i: 1 + N_FINGERS * (i + 1)]
        return out

    def last_grasp(self, force_limit: float, *, settle: float = 0.2
                   ) -> dict[str, float | None] | None:
        """:func:`control.grip.grasp_figures` of the record since the last close command.

        Times are counted from the close. None before any close (or once the
        close has left the record).
        """
        t0 = self.status.closed_at
        if t0 is None:
            return None
        snap = self.snapshot()
        keep = snap["t"] > t0
        if not keep.any() or snap["t"][0] > t0 + self.dt:
            return None
        trace = GraspTrace(snap["t"][keep] - t0, snap["voltage"][keep], snap["current"][keep],
                           snap["force"][keep], snap["estimate"][keep])
        return grasp_figures(trace, force_limit, settle=settle)
