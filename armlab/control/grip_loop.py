"""The hand's control loop in its own thread, with a ring-buffer record for the UI.

One writer: the loop thread steps the plant and the :class:`GripController`
every control period and appends a row to the record. The UI never touches
either: it posts commands (callables run by the loop thread at its next
period) and reads copies of the record (:meth:`GripLoop.snapshot`).

A challenge's run (:meth:`GripLoop.restart`) starts the hand again open and at rest (the
plant's state and a fresh controller with the settings in force, at the plant's time)
inside one period, then posts its plan's commands at fixed numbers of periods from it:
a function of the settings and the object alone, whatever the hand did before and
however late the loop runs.

Real time: each tick (``tick_s``, 10 ms) the loop runs the periods that are
due on the wall clock (never more than ``max_catch_up`` s at once: a stalled
machine skips time rather than racing). Not real time (tests, headless): it
runs a tick's worth of periods after another as fast as it can.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from armlab.control.grip import (
    N_FINGERS,
    GraspTrace,
    GripController,
    GripModel,
    GripParams,
    HandPlant,
    grasp_figures,
)
from armlab.control.loop_record import LoopRecord
from armlab.control.periodic import Pacer
from armlab.control.restart import Schedule
from armlab.control.ring_buffer import RingBuffer

#: Record columns (besides t), each (3,) per row: name -> unit.
COLUMNS: dict[str, str] = {
    "voltage": "V",  # motor voltage applied
    "current": "A",  # measured motor current
    "force": "N",  # true fingertip force
    "estimate": "N",  # the controller's force estimate from the current
    "cap": "N",  # the force the controller allows
    "angle": "rad",  # true finger angle
}

@dataclass(frozen=True)
class CloseHand:
    """Grasp: close with the force limit (:meth:`GripLoop.last_grasp` measures from it)."""


@dataclass(frozen=True)
class OpenHand:
    """Release: open the fingers."""


@dataclass(frozen=True)
class MotorsOff:
    """Motors at 0 V now (the springs open the hand): the hand's E-STOP."""


@dataclass(frozen=True)
class SetGripParams:
    """Change the grasp's force limit (N) and/or approach speed (m/s) from the next period
    (None: keep; applied on the parameters in force then, so changes posted together
    compose)."""

    force_limit: float | None = None
    approach_speed: float | None = None


@dataclass(frozen=True)
class SetObject:
    """Put ``obj`` (the plant's object type, or None) between the fingers."""

    obj: object


@dataclass(frozen=True)
class RestartHand:
    """Start the hand again open and at rest, a fresh controller with the settings in
    force; ``plan``'s (periods, command) then follow, each applied ``periods + 1``
    periods after this one (:meth:`GripLoop.restart`)."""

    plan: tuple[tuple[int, object], ...] = ()


@dataclass(frozen=True)
class CancelPlan:
    """Apply nothing more of the last restart's plan (its run was cut short)."""


Command = (CloseHand | OpenHand | MotorsOff | SetGripParams | SetObject | RestartHand
           | CancelPlan)
COMMANDS = (CloseHand, OpenHand, MotorsOff, SetGripParams, SetObject, RestartHand, CancelPlan)


@dataclass(frozen=True)
class GripStatus:
    """The loop's latest state, replaced as a whole every period.

    Attributes:
        t: plant time, s.
        modes: each finger's controller mode.
        closed_at: plant time of the last close command, s (None: never closed).
        running: whether the thread runs.
        fault: "" or why the loop stopped.
        restarts: restarts done (:class:`RestartHand`).
        restarted_at: plant time of the last one's period, before its step (None: none).
    """

    t: float = 0.0
    modes: tuple[str, ...] = ("idle",) * N_FINGERS
    closed_at: float | None = None
    running: bool = False
    fault: str = ""
    restarts: int = 0
    restarted_at: float | None = None


class GripRecord(LoopRecord):
    """A hand loop's record and status, as a lesson reads them (any thread).

    Attributes:
        dt: s, the control period (one record row each).
        status: the loop's latest :class:`GripStatus`.
    """

    dt: float
    status: GripStatus
    _ring: RingBuffer
    COMMANDS = COMMANDS
    WHAT = "hand-loop"

    def close_hand(self) -> None:
        """Post a grasp (close with the force limit); :meth:`last_grasp` measures from it."""
        self.post(CloseHand())

    def open_hand(self) -> None:
        """Post a release."""
        self.post(OpenHand())

    def restart(self, plan: list[tuple[int, Command]]) -> int:
        """Start the hand again open and at rest at the loop's next period, then ``plan``'s
        (periods, command), each applied ``periods + 1`` periods after that one; the
        restart's number (``status.restarts`` reaches it at that period, whose plant time
        before its step is ``status.restarted_at``)."""
        number = self.status.restarts + 1
        self.post(RestartHand(tuple(plan)))
        return number

    def cancel_plan(self) -> None:
        """Apply nothing more of the last restart's plan (the run was cut short)."""
        self.post(CancelPlan())

    @staticmethod
    def _record_for(history_s: float, dt: float) -> RingBuffer:
        return RingBuffer(1 + N_FINGERS * len(COLUMNS), RingBuffer.rows_for(history_s, dt))

    def snapshot(self, window_s: float | None = None) -> dict[str, np.ndarray]:
        """Copy of the record: "t" (m,) s and each of :data:`COLUMNS` (m, 3), oldest first.

        ``window_s``: only the last that many seconds (None: everything kept).
        """
        return self.unpack(self._ring.rows(window_s))

    def unpack(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Raw rows (m, 1 + 3·len(COLUMNS)) as :meth:`snapshot` gives them (views)."""
        out = {"t": data[:, 0]}
        for i, name in enumerate(COLUMNS):
            out[name] = data[:, 1 + N_FINGERS * i: 1 + N_FINGERS * (i + 1)]
        return out

    def last_grasp(self, force_limit: float, *, settle: float = 0.2
                   ) -> dict[str, float | None] | None:
        """:func:`armlab.control.grip.grasp_figures` of the record since the last close command.

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


class GripLoop(GripRecord):
    """Runs ``controller`` on ``plant`` every ``controller.dt`` s.

    Args:
        plant: the hand (e.g. ``armlab.hardware.sim.hand_plant.HandSim``).
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
        self._ring = self._record_for(history_s, self.dt)
        self._commands: deque[Command] = deque()
        self._pacer = Pacer(self._period, period=self.dt, name="armlab-grip",
                            realtime=realtime, batch_s=tick_s, max_catch_up=max_catch_up,
                            idle_s=0.0005, catch=(ValueError, RuntimeError, FloatingPointError),
                            on_exit=self._stopped)
        self._current = plant.step(np.zeros(N_FINGERS), self.dt)
        self._closed_at: float | None = None
        self._schedule = Schedule()  #: a restart's plan (the loop thread's)
        self.restarts = 0  #: restarts done (:meth:`restart`)
        self.restarted_at: float | None = None  #: plant time of the last one's period
        self.status = GripStatus(t=plant.t, modes=controller.modes)

    # --- commands (any thread) -----------------------------------------------------
    def _send(self, command: Command) -> None:  # type: ignore[override]  # each loop takes its own command types
        self._commands.append(command)

    @property
    def params(self) -> GripParams:
        """The grasp's settings in force."""
        return self.controller.params

    @property
    def model(self) -> GripModel:
        """What the controller knows of the hand."""
        return self.controller.model

    @property
    def obj(self) -> object:
        """The object between the fingers (None: nothing)."""
        return self.plant.obj

    def _restart(self, plan: tuple[tuple[int, object], ...]) -> None:
        """:class:`RestartHand` in the loop thread."""
        self.plant.reset(keep_time=True)  # type: ignore[attr-defined]  # the simulated hand the loop drives has reset
        ctl = self.controller
        self.controller = GripController(ctl.model, ctl.params, dt=ctl.dt)
        self._current = np.zeros(N_FINGERS)
        self._closed_at = None
        self._schedule.begin(plan, self._commands.append)
        self.restarted_at = self.plant.t
        self.restarts += 1

    def _apply(self, command: Command, plant: HandPlant, ctl: GripController) -> None:
        match command:
            case CloseHand():
                ctl.close()
                self._closed_at = plant.t
            case OpenHand():
                ctl.open()
            case MotorsOff():
                ctl.stop()
            case SetGripParams(force, speed):
                changes = {"force_limit": force, "approach_speed": speed}
                ctl.set_params(replace(ctl.params, **{k: v for k, v in changes.items()
                                                      if v is not None}))
            case SetObject(obj):
                plant.set_object(obj)

    # --- the loop ------------------------------------------------------------------
    def start(self) -> None:
        """Start the loop thread."""
        self._pacer.start()

    def shutdown(self) -> None:
        """Stop the thread (waits for the current tick); the motors are left at 0 V."""
        self._pacer.stop(timeout=2.0)
        self.status = GripStatus(self.plant.t, self.controller.modes, self._closed_at, False,
                                 self.status.fault, self.restarts, self.restarted_at)

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of periods now, in the calling thread (the thread must not run)."""
        self._pacer.run_for(seconds)

    def _stopped(self, error: Exception | None) -> None:
        fault = "" if error is None else f"the hand loop stopped: {error}"
        self.status = GripStatus(self.plant.t, self.controller.modes, self._closed_at, False,
                                 fault, self.restarts, self.restarted_at)

    def _period(self) -> None:
        self._schedule.tick()  # a restart's commands due this period
        while self._commands:
            command = self._commands.popleft()
            if isinstance(command, RestartHand):
                self._restart(command.plan)
            elif isinstance(command, CancelPlan):
                self._schedule.cancel()
            else:
                self._apply(command, self.plant, self.controller)
        plant, ctl = self.plant, self.controller
        volts = ctl.update(self._current)
        self._current = plant.step(volts, self.dt)
        row = np.concatenate([
            [plant.t], volts, self._current, plant.contact_force, ctl.estimated_force(),
            ctl.force_cap, plant.finger_angle,
        ])
        self._ring.append(row)
        self.status = GripStatus(plant.t, ctl.modes, self._closed_at, self._pacer.running,
                                 restarts=self.restarts, restarted_at=self.restarted_at)
