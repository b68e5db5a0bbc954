"""Every student's private arm ("My arm"): seats that keep an arm across reloads.

A class of students each gets a simulated arm of their own, the shared lesson's arm and
loop (:mod:`app.class_arms`: batched plants, one clock, a ControlLoop per arm). The
thesis arm's RX-24F arms run in a process of their own (:class:`app.arm_process.ArmProcess`),
off the server's interpreter, so a room of pages and the shared arm's loop do not wait
for the class's 1 kHz steps; an arm with X-series servos (the OpenManipulator-X) runs in
the server, on a :class:`app.class_arms.ClassArms` made when the first is asked for.

A seat is found again by its key (a random id the page keeps in its browser's
localStorage): a reload within :data:`IDLE_S` returns to the same arm, gains and
recording. A seat also keeps its student's copy of the thesis's hand (the hand lesson):
one of the class's hands on one loop (:class:`app.class_hands.ClassHands`) in the same
worker process as the RX-24F arms (:class:`app.remote_hand.RemoteHand`). A seat whose
page left longer ago is freed; a class whose seats already hold :data:`MAX_ARMS` arms or
hands refuses a new one with :class:`ClassFull`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.arm_process import ArmProcess
from app.backends import shipped_x_servo
from app.class_arms import Arm, ClassArms
from app.remote_hand import RemoteHand
from control.backend import Backend
from control.grip import GripParams
from control.loop import ControlLoop
from control.params import Params
from hardware.hand import GraspObject
from kinematics.model import SerialChain

#: private arms one lab holds at most (the issue's default)
MAX_ARMS = 200
#: s a seat whose page left is kept for a reload
IDLE_S = 600.0
#: s between two looks for seats to free
SWEEP_S = 15.0


class ClassFull(ValueError):
    """No private arm left: the class holds :data:`MAX_ARMS` already."""


@dataclass
class _Arm:
    host: ArmProcess | ClassArms  #: where it runs
    arm: Arm  #: (its backend and loop: the worker's proxies when ``host`` is one)

    @property
    def preset(self) -> str:
        return self.arm.preset

    @property
    def loop(self) -> ControlLoop:
        return self.arm.loop  # type: ignore[return-value]  # a RemoteLoop quacks as one


class Seat:
    """One student's place in the class: the arm a private lesson drives.

    Implements :class:`app.lessons.ArmSource` for the lesson.
    """

    def __init__(self, owner: Sandboxes, key: str) -> None:
        self.key = key
        self._owner = owner
        self.arm: _Arm | None = None
        #: the student's hand (the hand lesson) and the worker that runs it
        self.hand: tuple[ArmProcess, RemoteHand] | None = None
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

    def hand_for(self, obj: GraspObject, params: GripParams, *,
                 history_s: float) -> RemoteHand:
        """The seat's hand: the one it has (as it was left), or a new one, open, around
        ``obj`` with grasp settings ``params``. It runs on the class's loop."""
        return self._owner._hand_for(self, obj, params, history_s=history_s)

    @property
    def holds(self) -> bool:
        """Whether the seat holds an arm or a hand."""
        return self.arm is not None or self.hand is not None


def _ended(host: ArmProcess | ClassArms) -> bool:
    """Whether ``host`` is a worker process that has ended (its arms are gone)."""
    return isinstance(host, ArmProcess) and host.ended is not None


class Sandboxes:
    """The private arms of one lab (see the module docstring).

    Args:
        max_arms: arms at most (:class:`ClassFull` beyond).
        idle_s: s a seat whose page left is kept.
        realtime: step against the wall clock (False: as fast as possible, for tests).
        clock: monotonic seconds for the idle times (tests pass a fake one).

    Attributes:
        process: the worker process running the RX-24F arms.
    """

    def __init__(self, *, max_arms: int = MAX_ARMS, idle_s: float = IDLE_S,
                 realtime: bool = True, clock: Callable[[], float] = time.monotonic) -> None:
        self.max_arms = int(max_arms)
        self.idle_s = float(idle_s)
        self._now = clock
        self._realtime = realtime
        self._seats: dict[str, Seat] = {}
        self._lock = threading.RLock()
        self.process = ArmProcess(realtime=realtime)  # starts now: ready by the first arm
        self._local: ClassArms | None = None  # X-series arms, made at the first
        self._stop = threading.Event()
        self._sweeper = threading.Thread(target=self._sweep_often, name="armlab-seats",
                                         daemon=True)
        self._sweeper.start()

    @property
    def n_arms(self) -> int:
        """Seats holding a private arm or hand now."""
        with self._lock:
            return sum(1 for s in self._seats.values() if s.holds)

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
            arm = seat.arm
            if arm is not None and arm.preset == preset and not _ended(arm.host):
                return arm.arm.backend, arm.loop  # type: ignore[return-value]
            self._free_arm(seat)
            host: ArmProcess | ClassArms
            if shipped_x_servo(model) is not None:  # X-series: in the server (see above)
                if self._local is None:
                    self._local = ClassArms(realtime=self._realtime)
                host = self._local
            else:
                if self.process.ended is not None:  # killed or crashed: a new one
                    ended, self.process = self.process, ArmProcess(realtime=self._realtime)
                    ended.close()
                host = self.process
            arm = host.add(model, params, preset=preset, q0=q0, history_s=history_s)
            seat.arm = _Arm(host, arm)
            return arm.backend, seat.arm.loop  # type: ignore[return-value]

    def _hand_for(self, seat: Seat, obj: GraspObject, params: GripParams, *,
                  history_s: float) -> RemoteHand:
        with self._lock:
            if seat.hand is not None and seat.hand[0].ended is None:
                return seat.hand[1]
            self._free_hand(seat)
            if self.process.ended is not None:  # killed or crashed: a new one
                ended, self.process = self.process, ArmProcess(realtime=self._realtime)
                ended.close()
            hand = self.process.add_hand(obj, params, history_s=history_s)
            seat.hand = (self.process, hand)
            return hand

    def _free_arm(self, seat: Seat) -> None:  # holding self._lock
        arm, seat.arm = seat.arm, None
        if arm is not None:
            arm.host.free(arm.arm)

    def _free(self, seat: Seat) -> None:  # holding self._lock
        self._free_arm(seat)
        self._free_hand(seat)

    def _free_hand(self, seat: Seat) -> None:  # holding self._lock
        held, seat.hand = seat.hand, None
        if held is not None:
            held[0].free_hand(held[1])

    def close(self) -> None:
        """Stop the class: the sweeper, then every arm (its loop with torque off) and the
        process and clock that ran them."""
        self._stop.set()
        with self._lock:
            seats = list(self._seats.values())
            self._seats.clear()
            if self._local is not None:
                self._local.close([s.arm.arm for s in seats
                                   if s.arm is not None and s.arm.host is self._local])
            self.process.close()  # every arm and hand in it freed, torque off
