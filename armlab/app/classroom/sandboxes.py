"""Every student's private arm ("My arm"): seats that keep an arm across reloads.

A class of students each gets a simulated arm of their own, the shared lesson's arm and
loop (:mod:`armlab.app.workers.class_arms`: batched plants, one clock, a ControlLoop per arm). The
thesis arm's RX-24F arms run in a process of their own
(:class:`armlab.app.workers.worker_process.ArmProcess`),
off the server's interpreter, so a room of pages and the shared arm's loop do not wait
for the class's 1 kHz steps; an arm whose servos have their own firmware simulation
(X-series: the OpenManipulator-X; Feetech STS: the SO-101) runs in the server, on a
:class:`armlab.app.workers.class_arms.ClassArms` made when the first is asked for.

A seat is found again by its key (a random id the page keeps in its browser's
localStorage): a reload within :data:`IDLE_S` returns to the same arm, gains and
recording. A seat also keeps its student's copy of the thesis's hand (the hand lesson)
and of the seed 003 quadruped: each one of the class's, batched on one clock
(:mod:`armlab.app.workers.class_hands`, :mod:`armlab.app.workers.class_quadrupeds`), the hands
in the same worker
process as the RX-24F arms, the quadrupeds in one of their own
(:class:`armlab.app.workers.remote_hand.RemoteHand`,
:class:`armlab.app.workers.remote_gait.RemoteGait`).
A seat whose page left longer ago is freed; a class whose seats already hold
:data:`MAX_ARMS` arms (hands, quadrupeds) refuses a new one with :class:`ClassFull`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from armlab.app.arm.backends import has_firmware_sim
from armlab.app.workers.class_arms import Arm, ClassArms
from armlab.app.workers.remote_gait import RemoteGait
from armlab.app.workers.remote_hand import RemoteHand
from armlab.app.workers.worker_process import ArmProcess
from armlab.control.backend import Backend
from armlab.control.grip import GripParams
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.walking import GaitSpec
from armlab.hardware.sim.hand_plant import GraspObject
from armlab.kinematics.model import SerialChain

#: private arms one lab holds at most (the issue's default)
MAX_ARMS = 200
#: s a seat whose page left is kept for a reload
IDLE_S = 600.0
#: s between two looks for seats to free
SWEEP_S = 15.0
#: what runs in a worker process of its own rather than in the class's (beside its arms
#: and hands): the quadrupeds, whose class costs about a core for thirty robots
OWN_PROCESS = (RemoteGait.KIND,)


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
        return self.arm.loop  # a RemoteLoop quacks as one


class Seat:
    """One student's place in the class: the arm a private lesson drives.

    Implements :class:`armlab.app.lessons.ArmSource` for the lesson.
    """

    def __init__(self, owner: Sandboxes, key: str) -> None:
        self.key = key
        self._owner = owner
        self.arm: _Arm | None = None
        #: the student's hand and quadruped, by kind ("hand", "quad"), and the worker that
        #: runs each
        self.members: dict[str, tuple[ArmProcess, RemoteHand | RemoteGait]] = {}
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
        return self._owner._member_for(  # type: ignore[return-value]  # the hand kind's add: a RemoteHand
            self, RemoteHand.KIND, lambda p: p.add_hand(obj, params, history_s=history_s))

    def quadruped_for(self, spec: GaitSpec, *, speed: float, history_s: float) -> RemoteGait:
        """The seat's quadruped: the one it has (as it was left), or a new one standing,
        to walk ``spec`` at ``speed`` cycles/s. It walks on the class's clock."""
        return self._owner._member_for(  # type: ignore[return-value]  # the quadruped kind's add: a RemoteGait
            self, RemoteGait.KIND,
            lambda p: p.add_quadruped(spec, speed=speed, history_s=history_s))

    @property
    def holds(self) -> bool:
        """Whether the seat holds an arm, a hand or a quadruped."""
        return self.arm is not None or bool(self.members)


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
        self._local: ClassArms | None = None  # X-series and STS arms, made at the first
        self._own: dict[str, ArmProcess] = {}  # kind -> its worker (OWN_PROCESS), at the first
        self._stop = threading.Event()
        self._sweeper = threading.Thread(target=self._sweep_often, name="armlab-seats",
                                         daemon=True)
        self._sweeper.start()

    @property
    def n_arms(self) -> int:
        """Seats holding a private arm, hand or quadruped now."""
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
            kept = seat.arm
            if kept is not None and kept.preset == preset and not _ended(kept.host):
                return kept.arm.backend, kept.loop
            self._free_arm(seat)
            host: ArmProcess | ClassArms
            if has_firmware_sim(model):  # X-series, STS: in the server (see above)
                if self._local is None:
                    self._local = ClassArms(realtime=self._realtime)
                host = self._local
            else:
                host = self._process_for("arm")
            arm = host.add(model, params, preset=preset, q0=q0, history_s=history_s)
            seat.arm = _Arm(host, arm)
            return arm.backend, seat.arm.loop

    def _member_for(self, seat: Seat, kind: str,
                    add: Callable[[ArmProcess], RemoteHand | RemoteGait]
                    ) -> RemoteHand | RemoteGait:
        with self._lock:
            held = seat.members.get(kind)
            if held is not None and held[0].ended is None:
                return held[1]
            self._free_member(seat, kind)
            process = self._process_for(kind)
            made = add(process)
            seat.members[kind] = (process, made)
            return made

    def _process_for(self, kind: str) -> ArmProcess:  # holding self._lock
        """The worker for an arm or a member of ``kind``: the class's, or
        (:data:`OWN_PROCESS`) one of its own; a new one for a worker that has ended (killed
        or crashed)."""
        if kind not in OWN_PROCESS:
            if self.process.ended is not None:
                ended, self.process = self.process, ArmProcess(realtime=self._realtime)
                ended.close()
            return self.process
        process = self._own.get(kind)
        if process is None or process.ended is not None:
            if process is not None:
                process.close()
            process = self._own[kind] = ArmProcess(realtime=self._realtime)
        return process

    def _free_arm(self, seat: Seat) -> None:  # holding self._lock
        arm, seat.arm = seat.arm, None
        if arm is not None:
            arm.host.free(arm.arm)

    def _free(self, seat: Seat) -> None:  # holding self._lock
        self._free_arm(seat)
        for kind in list(seat.members):
            self._free_member(seat, kind)

    def _free_member(self, seat: Seat, kind: str) -> None:  # holding self._lock
        held = seat.members.pop(kind, None)
        if held is not None:
            held[0].free_member(held[1])

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
            for process in (self.process, *self._own.values()):
                process.close()  # every arm, hand and quadruped in it freed, torque off
