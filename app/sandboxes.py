"""Every student's private arm ("My arm"): one batched plant, one thread, one loop per arm.

A class of students each gets a simulated thesis arm of their own. The arms of one
link-length preset live in one :class:`hardware.batched_plant.BatchedPlant` (numpy
over arms); one :class:`control.periodic.SharedClock` thread steps every plant at
1 kHz and, in the same thread, each arm's :class:`control.loop.ControlLoop` when its
period is due. A loop is the lesson's own (commands, trajectories, the step test,
pushes, drags, recording, faults) over a :class:`hardware.batched_backend.BatchedArmBackend`:
one arm of the plant behind the ``Backend`` protocol. So a private arm is the shared
lesson's arm, not a lookalike, and a hundred of them cost one thread. An arm that ships
with X-series servos (the OpenManipulator-X) is simulated with their firmware model as
its shared arm is (:class:`hardware.xseries_sim.XSimBackend`, a plant of its own that
its loop steps, on the same clock): the batched plant models protocol-1.0 servos only.

A seat is found again by its key (a random id the page keeps in its browser's
localStorage): a reload within :data:`IDLE_S` returns to the same arm, gains and
recording. A seat whose page left longer ago is freed; a class already holding
:data:`MAX_ARMS` arms refuses a new one with :class:`ClassFull`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.backends import shipped_x_servo
from control.backend import Backend
from control.loop import ControlLoop
from control.params import Params
from control.periodic import SharedClock
from hardware.batched_backend import BatchedArmBackend, add_sim_arm
from hardware.batched_plant import BatchedPlant
from hardware.servo_spec import RX24F
from hardware.xseries_sim import XSimBackend
from kinematics.model import SerialChain

#: private arms one lab holds at most (the issue's default)
MAX_ARMS = 200
#: s a seat whose page left is kept for a reload
IDLE_S = 600.0
#: s between two looks for seats to free
SWEEP_S = 15.0
#: plant step, s (as the shared arm's SimBackend)
DT = 1e-3


class ClassFull(ValueError):
    """No private arm left: the class holds :data:`MAX_ARMS` already."""


@dataclass
class _Arm:
    preset: str
    arm: int | None  #: its index in the preset's batched plant (None: a plant of its own)
    backend: Backend
    loop: ControlLoop


class Seat:
    """One student's place in the class: the arm a private lesson drives.

    Implements :class:`app.lessons.ArmSource` for the lesson.
    """

    def __init__(self, owner: Sandboxes, key: str) -> None:
        self.key = key
        self._owner = owner
        self.arm: _Arm | None = None
        self.left_at: float | None = None  #: monotonic time its last page left (None: open)
        #: the pages showing it (a reloaded page's new connection may come before the old
        #: one has gone)
        self.pages: set[object] = set()

    def kept(self) -> tuple[str, Params] | None:
        """(preset, gains) of the arm this seat already has, or None."""
        arm = self.arm
        return None if arm is None else (arm.preset, arm.loop.params)

    def arm_for(self, model: SerialChain, params: Params, *, preset: str, q0: np.ndarray,
                history_s: float) -> tuple[Backend, ControlLoop]:
        """The seat's arm for ``preset``: the one it has, or a new one at ``q0`` with
        ``params`` (replacing an arm of another preset). Its loop is running."""
        return self._owner._arm_for(self, model, params, preset=preset, q0=q0,
                                    history_s=history_s)


class Sandboxes:
    """The private arms of one lab (see the module docstring).

    Args:
        max_arms: arms at most (:class:`ClassFull` beyond).
        idle_s: s a seat whose page left is kept.
        realtime: step against the wall clock (False: as fast as possible, for tests).
        clock: monotonic seconds for the idle times (tests pass a fake one).
    """

    def __init__(self, *, max_arms: int = MAX_ARMS, idle_s: float = IDLE_S,
                 realtime: bool = True, clock: Callable[[], float] = time.monotonic) -> None:
        self.max_arms = int(max_arms)
        self.idle_s = float(idle_s)
        self._now = clock
        self._plants: dict[str, BatchedPlant] = {}
        self._seats: dict[str, Seat] = {}
        self.clock = SharedClock(self._step, dt=DT, realtime=realtime, name="armlab-class")
        self._lock = self.clock.lock  # a HandOverLock: a waiting page gets in between ticks
        self.clock.start()
        self._stop = threading.Event()
        self._sweeper = threading.Thread(target=self._sweep_often, name="armlab-seats",
                                         daemon=True)
        self._sweeper.start()

    def _step(self) -> None:
        for plant in self._plants.values():
            plant.step()

    @property
    def n_arms(self) -> int:
        """Private arms held now."""
        with self._lock:
            return sum(1 for s in self._seats.values() if s.arm is not None)

    def has(self, key: str) -> bool:
        """Whether a seat of ``key`` is kept (its page open, or left less than
        :attr:`idle_s` s ago)."""
        with self._lock:
            return key in self._seats

    def kept_params(self, key: str) -> Params | None:
        """The gains of ``key``'s arm, or None (no seat or no arm)."""
        with self._lock:
            seat = self._seats.get(key)
            kept = None if seat is None else seat.kept()
        return None if kept is None else kept[1]

    def loop_of(self, key: str) -> ControlLoop | None:
        """The loop of ``key``'s arm, or None."""
        with self._lock:
            seat = self._seats.get(key)
            return None if seat is None or seat.arm is None else seat.arm.loop

    def seat(self, key: str, *, page: object = None) -> Seat:
        """The seat of ``key`` (kept since its page left, or new), shown by ``page`` (a
        client id) from now on.

        Raises:
            ClassFull: a new seat, and :attr:`max_arms` arms are held.
        """
        with self._lock:
            seat = self._seats.get(key)
            if seat is None:
                if self.n_arms >= self.max_arms:
                    raise ClassFull(f"the class is full: {self.max_arms} private arms are in use; "
                                    "follow the teacher's arm")
                seat = self._seats[key] = Seat(self, key)
            seat.pages.add(page)
            seat.left_at = None
            return seat

    def leave(self, key: str, *, page: object = None) -> None:
        """``page`` no longer shows the seat of ``key``; once no page does, its arm is
        kept :attr:`idle_s` s for a reload. (A reload's old page may leave after its new
        one has taken the seat: the seat stays open.)"""
        with self._lock:
            seat = self._seats.get(key)
            if seat is not None:
                seat.pages.discard(page)
                if not seat.pages:
                    seat.left_at = self._now()

    def sweep(self) -> int:
        """Free the seats whose page left more than :attr:`idle_s` s ago; returns how many."""
        now = self._now()
        with self._lock:
            gone = [s for s in self._seats.values()
                    if s.left_at is not None and now - s.left_at > self.idle_s]
            for seat in gone:
                del self._seats[seat.key]
                self._free(seat)
        return len(gone)

    def _sweep_often(self) -> None:
        while not self._stop.wait(SWEEP_S):
            self.sweep()

    def _arm_for(self, seat: Seat, model: SerialChain, params: Params, *, preset: str,
                 q0: np.ndarray, history_s: float) -> tuple[Backend, ControlLoop]:
        with self._lock:
            if seat.arm is not None and seat.arm.preset == preset:
                return seat.arm.backend, seat.arm.loop
            self._free(seat)
            x_spec = shipped_x_servo(model)
            if x_spec is not None:  # X-series servos: their firmware model, one plant per arm
                backend: Backend = XSimBackend(model, spec=x_spec, dt=DT, q0=q0)
                arm = None
            else:
                plant = self._plants.get(preset)
                if plant is None:
                    plant = self._plants[preset] = BatchedPlant(model, RX24F, dt=DT)
                arm = add_sim_arm(plant, q0=q0, lock=self._lock)
                backend = BatchedArmBackend(plant, arm, lock=self._lock)
            try:
                loop = ControlLoop(model, backend, params, controller="compliance",
                                   history_s=history_s, clock=self.clock)
            except BaseException:
                backend.close()
                if arm is not None:
                    plant.remove_arm(arm)
                raise
            seat.arm = _Arm(preset, arm, backend, loop)
            loop.start()
            return backend, loop

    def _free(self, seat: Seat) -> None:  # holding self._lock
        arm, seat.arm = seat.arm, None
        if arm is None:
            return
        arm.loop.shutdown(torque_off=True)
        arm.backend.close()
        if arm.arm is not None:
            self._plants[arm.preset].remove_arm(arm.arm)

    def close(self) -> None:
        """Stop the class: the sweeper, the clock, then every loop (torque off) and arm.

        The arms are freed holding the class's lock, after the clock stopped: a tick that
        stepped a plant while one of its arms was taken out would leave the plant's arrays
        of different widths."""
        self._stop.set()
        self.clock.stop()
        with self._lock:
            seats = list(self._seats.values())
            self._seats.clear()
            for seat in seats:
                self._free(seat)
