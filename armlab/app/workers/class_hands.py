"""Private hands on one loop: every student's copy of the thesis's three-finger hand.

The hand lesson's own hand runs on a :class:`armlab.control.grip_loop.GripLoop` (a
:class:`armlab.hardware.sim.hand_plant.HandSim` and a :class:`armlab.control.grip.GripController`, 1
kHz). A
class of them would cost a quarter of a core each, so the private hands of a class live
in one :class:`armlab.hardware.sim.batched_hand.BatchedHand` and one
:class:`armlab.control.batched_grip.BatchedGrip` (numpy over hands), stepped by one
:class:`armlab.control.periodic.SharedClock` thread: per period, every hand's posted commands,
the controllers' update, the plants' step, one record row per hand. A lesson drives its
student's hand through a :class:`ClassHand`: the ``GripLoop`` surface (commands,
``status``, ``params``, ``snapshot``, ``last_grasp``), so the private lesson is the
shared one. What a page reads never waits for the clock's lock: the record has a lock of
its own per hand, the settings are kept on the hand as applied, and the fingers' modes
are published once per period (:attr:`ClassHands.view`).

:class:`armlab.app.classroom.sandboxes.Sandboxes` keeps each hand with its student's seat.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace
from functools import partial

import numpy as np

from armlab.control.batched_grip import BatchedGrip
from armlab.control.grip import MODES, N_FINGERS, GripModel, GripParams
from armlab.control.grip_loop import (
    CancelPlan,
    CloseHand,
    Command,
    GripRecord,
    GripStatus,
    MotorsOff,
    OpenHand,
    RestartHand,
    SetGripParams,
    SetObject,
)
from armlab.control.periodic import SharedClock
from armlab.control.restart import Schedule
from armlab.hardware.sim.batched_hand import BatchedHand
from armlab.hardware.sim.hand_plant import GraspObject, HandParams, HandSim

#: s, the control period (as GripLoop's)
DT = 1.0e-3
#: what a freed hand's status and commands say
FREED = "this hand was freed (a reload of the page makes a new one)"


class ClassHand(GripRecord):
    """One student's hand in a :class:`ClassHands`, as a lesson drives it (a ``GripLoop``'s
    surface: it runs from the moment it was made; :meth:`shutdown` frees nothing).

    Attributes:
        model: what the controller knows of the hand.
        params: the grasp's settings in force (as applied by the class's loop).
        obj: the object between the fingers (None: nothing), as applied.
        closed_at: class time of its last close command (None: never closed).
    """

    def __init__(self, owner: ClassHands, hand: int, *, params: GripParams,
                 obj: GraspObject | None, history_s: float) -> None:
        self._owner = owner
        self.hand = hand
        self.dt = owner.dt
        self.model = owner.grip.model
        self.params = params
        self.obj = obj
        self.closed_at: float | None = None
        self.restarts = 0  #: restarts done (:class:`RestartHand`)
        self.restarted_at: float | None = None  #: class time of the last one, before its step
        self.schedule = Schedule()  #: the last restart's plan (the class's loop's)
        self._ring = self._record_for(history_s, self.dt)

    def _send(self, command: Command) -> None:  # type: ignore[override]  # each loop takes its own command types
        """To the class's next period (ValueError: this hand was freed)."""
        self._owner._post(self.hand, command)

    @property
    def status(self) -> GripStatus:  # type: ignore[override]  # a property over the base's status attribute (read-only here)
        """The hand's state at the class's last period: time, its fingers' modes, its last
        close; a fault once it was freed or the class's loop failed."""
        t, rows, codes, fault = self._owner.view
        row = rows.get(self.hand)
        if row is None:
            return GripStatus(t, ("idle",) * N_FINGERS, self.closed_at, False,
                              fault or FREED, self.restarts, self.restarted_at)
        modes = tuple(MODES[k] for k in codes[row])
        return GripStatus(t, modes, self.closed_at, self._owner.clock.alive, fault,
                          self.restarts, self.restarted_at)

    def start(self) -> None:
        """Nothing: the class's loop runs every hand it holds."""

    def shutdown(self) -> None:
        """Nothing: the hand stays with its student's seat (:meth:`ClassHands.free` ends
        it)."""


class ClassHands:
    """Every private hand of a class on one clock (see the module docstring); the clock
    runs from the start.

    Args:
        realtime: pace the clock by the wall clock (False: as fast as possible, for tests).
        params: the simulated hand (all the same).

    Attributes:
        plant, grip: every hand's plant and controller (rows: the hands in the order they
            joined).
        clock: the thread stepping them.
        view: (t, {hand id: row}, (N, 3) mode codes, fault) as of the last period.
    """

    def __init__(self, *, realtime: bool = True, params: HandParams | None = None) -> None:
        self.plant = BatchedHand(params)
        self.grip = BatchedGrip(GripModel.of(HandSim(self.plant.params)), dt=DT)
        self.dt = DT
        self._hands: dict[int, ClassHand] = {}
        self._rows: list[ClassHand] = []  # in the batch's row order
        self._commands: deque[tuple[int, Command]] = deque()
        self._current = np.zeros((0, N_FINGERS))
        self.fault = ""
        self.view: tuple[float, dict[int, int], np.ndarray, str] = (0.0, {}, self.grip.mode_codes,
                                                                    "")
        self.clock = SharedClock(self._period, dt=DT, realtime=realtime,
                                 name="armlab-class-hands", batch_s=0.01, max_catch_up=0.1,
                                 on_error=self._failed)
        self.lock = self.clock.lock
        self.clock.start()

    @property
    def n_hands(self) -> int:
        return len(self._hands)

    def add(self, obj: GraspObject | None, params: GripParams, *,
            history_s: float) -> ClassHand:
        """A new hand, open and at rest, around ``obj`` with grasp settings ``params``
        (ValueError: an object the hand cannot hold, a force the motors cannot)."""
        with self.lock:
            hand = self.plant.add(obj)
            try:
                if self.grip.add(params) != hand:
                    raise RuntimeError("the class's hands and controllers lost step")
            except BaseException:
                self.plant.remove(hand)
                raise
            self._current = np.concatenate([self._current, np.zeros((1, N_FINGERS))])
            made = self._hands[hand] = ClassHand(self, hand, params=params,
                                                 obj=self.plant.obj(hand), history_s=history_s)
            self._rows.append(made)
            self._publish(joined=True)
            return made

    def free(self, hand: ClassHand) -> None:
        """Take ``hand`` out of the class (nothing if it is out already)."""
        with self.lock:
            if self._hands.pop(hand.hand, None) is None:
                return
            r = self.plant.row(hand.hand)
            self.plant.remove(hand.hand)
            self.grip.remove(hand.hand)
            self._current = np.delete(self._current, r, axis=0)
            del self._rows[r]
            self._publish(joined=True)

    def close(self) -> None:
        """Stop the clock and free every hand."""
        self.clock.stop(timeout=2.0)
        with self.lock:
            for hand in list(self._hands.values()):
                self.free(hand)

    # -- the loop --------------------------------------------------------------------------

    def _post(self, hand: int, command: Command) -> None:
        if hand not in self._hands:
            raise ValueError(FREED)
        self._commands.append((hand, command))

    def _apply(self, hand: ClassHand, command: Command) -> None:
        grip, h = self.grip, hand.hand
        match command:
            case CloseHand():
                grip.close(h)
                hand.closed_at = self.plant.t
            case OpenHand():
                grip.open(h)
            case MotorsOff():
                grip.stop(h)
            case SetGripParams(force, speed):
                changes = {"force_limit": force, "approach_speed": speed}
                grip.set_params(h, replace(grip.params(h), **{
                    k: v for k, v in changes.items() if v is not None}))
                hand.params = grip.params(h)
            case RestartHand(plan):  # a challenge's run: open and at rest, as a new hand
                self.plant.reset(h)
                grip.reset(h)
                self._current[self.plant.row(h)] = 0.0
                hand.closed_at = None
                hand.schedule.begin(plan, partial(self._queue, h))
                hand.restarted_at = self.plant.t
                hand.restarts += 1
            case CancelPlan():
                hand.schedule.cancel()
            case SetObject(obj):
                self.plant.set_object(h, obj)  # type: ignore[arg-type]  # a hand's object: the simulator's GraspObject (or None)
                hand.obj = self.plant.obj(h)

    def _queue(self, h: int, command: Command) -> None:
        """Queue ``command`` for hand ``h``, applied at the clock's next period."""
        self._commands.append((h, command))

    def _period(self) -> None:  # the clock's thread, holding self.lock
        for row in self._rows:  # restarts' commands due this period
            row.schedule.tick()
        while self._commands:
            h, command = self._commands.popleft()
            if (hand := self._hands.get(h)) is not None:
                try:
                    self._apply(hand, command)
                except ValueError:  # refused (the lesson checks first): nothing changes
                    pass
        if self._rows:
            grip, plant = self.grip, self.plant
            volts = grip.update(self._current)
            self._current = plant.step(volts, self.dt)
            rows = np.concatenate([
                np.full((len(self._rows), 1), plant.t), volts, self._current,
                plant.contact_force, grip.estimated_force(), grip.force_cap,
                plant.finger_angle], axis=1)
            for hand, row in zip(self._rows, rows, strict=True):
                hand._ring.append(row)
        self._publish()

    def _publish(self, *, joined: bool = False) -> None:  # holding self.lock
        """Renew :attr:`view` (``joined``: hands were added or freed since)."""
        rows = self.view[1]
        if joined:
            rows = {hand.hand: r for r, hand in enumerate(self._rows)}
        self.view = (self.plant.t, rows, self.grip.mode_codes, self.fault)

    def _failed(self, error: Exception) -> None:  # the clock's thread, holding self.lock
        self.fault = f"the class's hands stopped: {error}"
        self._publish()


__all__ = ["ClassHand", "ClassHands", "DT"]
