"""The quadruped's walking loop: a :class:`Walker` driving 12 servos through a Backend.

Every period (20 ms by default; periods at loop times 0, P, 2P, ...) the loop's thread
(or, with ``clock=``, a :class:`~armlab.control.periodic.SharedClock`'s: a class's quadrupeds)

1. runs the commands the UI posted (go, stop, new plan, speed, reset, e-stop);
2. brings the backend to the loop time and reads the servos (positions as they
   report them);
3. records the row: the goal sent last period next to the position read now (what
   seed 003 §4.1 compares), the stability margin, the body pose, the stance flags and
   the feet on the floor;
4. advances the walker by ``speed × period`` cycles and sends the new joint goals,
   with moving speeds that reach them within about a period.

The body's weight is the plant's business: the simulated legs and the emulator
carry it themselves (``armlab.hardware.families.dynamixel1.quadruped.BodyOnLegs``), as real legs do.

Without a backend (no servos) the loop only plays the walker, so the lesson still
shows the gait. One writer: the loop thread owns walker, backend and record; the UI
reads :attr:`GaitLoop.status`, :attr:`GaitLoop.state` and :meth:`GaitLoop.snapshot`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.control.backend import Backend, BackendError
from armlab.control.commands import EStop, Reset
from armlab.control.loop_record import LoopRecord
from armlab.control.periodic import DrivenPacer, Pacer, SharedClock
from armlab.control.ring_buffer import RingBuffer
from armlab.control.trajectory import APPROACH_SPEED
from armlab.control.walking import (
    GaitPlan,
    Walker,
    WalkState,
    mean_angle_error_pct,
    servo_angle_deg,
)

#: Record layout: name -> number of columns (t first).
COLUMNS: dict[str, int] = {"t": 1, "walking": 1, "phase": 1, "q_cmd": 12, "q": 12,
                           "margin": 1, "body": 4, "stance": 4, "feet": 12}
#: Moving-speed limits sent with each goal, rad/s (AX-12A: about 6 rad/s unloaded).
MIN_SPEED = 0.2
MAX_SPEED = 6.0
#: Seconds to rise from where the servos are to the standing pose before walking, at the
#: least: legs farther away rise at the lab's approach speed
#: (:data:`~armlab.control.trajectory.APPROACH_SPEED`), however far they are.
STAND_UP_S = 1.5

@dataclass(frozen=True)
class Walk:
    """Walk ``plan`` (a direction or a gait): at once when standing, else from the next
    cycle boundary."""

    plan: GaitPlan


@dataclass(frozen=True)
class SetPlan:
    """Use ``plan`` from the next cycle boundary (at once when standing)."""

    plan: GaitPlan


@dataclass(frozen=True)
class StopWalking:
    """Walk on until all four feet stand, then stop there."""


@dataclass(frozen=True)
class SetSpeed:
    """Gait speed, cycles/s (0.05..3)."""

    speed: float

    def __post_init__(self) -> None:
        v = float(self.speed)
        if not (math.isfinite(v) and 0.05 <= v <= 3.0):
            raise ValueError(f"gait speed must be 0.05..3 cycles/s, got {self.speed}")
        object.__setattr__(self, "speed", v)


@dataclass(frozen=True)
class SetInPlace:
    """Walk in place (body held at the origin) or across the floor; back to the origin."""

    in_place: bool


#: What the gait loop takes (``armlab.control.commands.Reset`` and ``EStop`` as the arm's loop).
Command = Walk | SetPlan | StopWalking | SetSpeed | SetInPlace | Reset | EStop
COMMANDS = (Walk, SetPlan, StopWalking, SetSpeed, SetInPlace, Reset, EStop)


@dataclass(frozen=True)
class GaitStatus:
    """The loop's latest state, replaced as a whole every period.

    Attributes:
        t: loop time, s.
        walking: the phase is advancing.
        stopping: walking on to the next moment all four feet stand, then stopping.
        command: the direction walked ("forward", ...).
        gait: "trot" or "crawl".
        speed: gait speed, cycles/s.
        servos: True while servos are driven (a backend is attached and healthy).
        torque_on: whether the servos' torque is on.
        standing_up: rising to the standing pose.
        fault: "" or why the servos are no longer driven (press Reset).
        running: whether the thread runs.
        restarts: challenge restarts of its servos done (a
            :class:`~armlab.control.restart.RestartableArm`'s; 0 for others).
        restarted_at: loop time of the last one's period (None: none).
    """

    t: float = 0.0
    walking: bool = False
    stopping: bool = False
    command: str = "forward"
    gait: str = "trot"
    speed: float = 0.5
    servos: bool = False
    torque_on: bool = False
    standing_up: bool = False
    fault: str = ""
    running: bool = False
    restarts: int = 0
    restarted_at: float | None = None


class GaitRecord(LoopRecord):
    """A gait loop's commands, record and figures, as a lesson uses them (any thread).

    Attributes:
        status: the loop's latest :class:`GaitStatus`.
        state: the walker's latest :class:`WalkState` (what the scene draws).
        to_servo: joint angles -> horn angles (see :class:`GaitLoop`).
    """

    status: GaitStatus
    state: WalkState
    _ring: RingBuffer
    COMMANDS = COMMANDS
    WHAT = "gait-loop"

    def to_servo(self, q: np.ndarray) -> np.ndarray:
        """(..., 12) joint angles -> horn angles from the servo centre, rad (identity)."""
        return np.asarray(q, dtype=float)

    def go(self, plan: GaitPlan) -> None:
        """Post :class:`Walk`."""
        self.post(Walk(plan))

    def set_plan(self, plan: GaitPlan) -> None:
        """Post :class:`SetPlan`."""
        self.post(SetPlan(plan))

    def stop(self) -> None:
        """Post :class:`StopWalking`."""
        self.post(StopWalking())

    def set_speed(self, speed: float) -> None:
        """Post :class:`SetSpeed` (ValueError outside 0.05..3 cycles/s)."""
        self.post(SetSpeed(speed))

    def set_in_place(self, in_place: bool) -> None:
        """Post :class:`SetInPlace`."""
        self.post(SetInPlace(bool(in_place)))

    def reset(self) -> None:
        """Stop, back to the origin at phase 0; torque on again and stand up (after an
        e-stop or a fault)."""
        self.post(Reset())


    # --- reading (any thread) ------------------------------------------------------------

    def snapshot(self, window_s: float | None = None) -> dict[str, np.ndarray]:
        """Copy of the record, oldest first: each of :data:`COLUMNS` as (m,) or (m, k).

        ``feet`` is (m, 12): the four feet's world x, y, z in leg order.
        ``q_cmd`` is the goal sent one period before ``q`` was read (without servos: the
        commanded angles; NaN before the first); ``q`` is NaN without servos; ``walking``
        is 1 while the gait runs (after standing up).
        """
        return self.unpack(self._ring.rows(window_s))

    def unpack(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Raw rows (m, sum of COLUMNS' widths) as :meth:`snapshot` gives them (views)."""
        out, c = {}, 0
        for name, width in COLUMNS.items():
            out[name] = data[:, c] if width == 1 else data[:, c:c + width]
            c += width
        return out

    def servo_angles_deg(self, snap: dict[str, np.ndarray]
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Eq. 4.1's inputs from a :meth:`snapshot`: ``ok`` (N,) marks the walking samples
        with finite angles; their commanded and reported horn angles (M, 12), degrees."""
        cmd, act = snap["q_cmd"], snap["q"]
        ok = (snap["walking"] > 0.5) & np.all(np.isfinite(cmd), axis=1) \
            & np.all(np.isfinite(act), axis=1)
        return (ok, servo_angle_deg(self.to_servo(cmd[ok])),
                servo_angle_deg(self.to_servo(act[ok])))

    def angle_error(self, window_s: float | None = None) -> dict[str, Any] | None:
        """Seed 003 eq. 4.1 over the walking samples of the last ``window_s`` s.

        Commanded = the goal sent (IK angle + the servo's set point), actual = the
        position the servo reported one period later, both as horn angles in degrees from
        the servo's raw 0 (:func:`armlab.control.walking.servo_angle_deg`).

        Returns:
            None without walking samples read from servos; else ``mean_pct`` (mean |%| over
            all servos), ``per_servo_pct`` (3,) by servo number in the leg (1 hip yaw,
            2 hip pitch, 3 knee), ``per_joint_pct`` (12,), ``samples``.
        """
        return self.angle_error_of(self.snapshot(window_s))

    def angle_error_of(self, snap: dict[str, np.ndarray]) -> dict[str, object] | None:
        """:meth:`angle_error` over the rows of ``snap`` (a :meth:`snapshot`'s layout: a
        challenge's window of periods)."""
        ok, cmd, act = self.servo_angles_deg(snap)
        if not ok.any():
            return None
        per_joint = np.array([mean_angle_error_pct(cmd[:, j], act[:, j]) for j in range(12)])
        per_servo = per_joint.reshape(4, 3).mean(axis=0)
        return {"mean_pct": mean_angle_error_pct(cmd, act), "per_servo_pct": per_servo,
                "per_joint_pct": per_joint, "samples": int(ok.sum())}


class GaitLoop(GaitRecord):
    """Runs ``walker`` on ``backend`` every ``period`` s.

    Args:
        walker: the gait player.
        backend: 12 servos in the walker's joint order, or None (animation only).
        period: control period, s.
        realtime: pace by the wall clock (False: as fast as possible, for tests).
        speed: gait speed, cycles/s.
        to_servo: (..., 12) joint angles -> (..., 12) horn angles from the servo centre, rad
            (a joint map's ``to_servo``; it must broadcast over rows); default identity.
        history_s: seconds of record kept.
        clock: run the periods on this :class:`SharedClock` (with the world it steps: a
            class's private quadrupeds) instead of a thread of the loop's own.
    """

    def __init__(self, walker: Walker, backend: Backend | None, *, period: float = 0.02,
                 realtime: bool = True, speed: float = 0.5,
                 to_servo: Callable[[np.ndarray], np.ndarray] | None = None,
                 history_s: float = 20.0, tick_s: float = 0.01,
                 max_catch_up: float = 0.1, clock: SharedClock | None = None) -> None:
        if not (math.isfinite(period) and 0.001 <= period <= 0.2):
            raise ValueError(f"period must be in [0.001, 0.2] s, got {period}")
        self.walker = walker
        self.backend = backend
        self.period = float(period)
        self.realtime = realtime
        if to_servo is not None:
            self.to_servo = to_servo  # type: ignore[method-assign,assignment]  # this instance's own mapping
        self._speed = SetSpeed(speed).speed  # validates
        self._ring = RingBuffer(sum(COLUMNS.values()), RingBuffer.rows_for(history_s, self.period))
        self._commands: deque[Command] = deque()
        self._pacer: Pacer | DrivenPacer = (
            Pacer(self._period, period=self.period, name="armlab-gait", realtime=realtime,
                  batch_s=tick_s, max_catch_up=max_catch_up, idle_s=0.002,
                  on_exit=self._stopped)
            if clock is None else clock.pacer(self._period, period=self.period,
                                               name="armlab-gait"))
        self._t = -self.period  #: time of the last period run (the first is at 0)
        self._walking = False
        self._stopping = False
        self._rest_at: float | None = None  # phase at which a stop completes
        self._fault = ""
        self._torque = backend is not None
        self._torque_sent = False  # torque on is sent at the first period with servos
        self._last_goal = np.full(12, np.nan)
        #: the rise to standing: (from q, start time, duration s)
        self._ramp: tuple[np.ndarray, float, float] | None = None
        self.state: WalkState = walker.state()
        self.status = self._make_status()

    # --- commands (any thread) ---------------------------------------------------------

    def _send(self, command: Command) -> None:  # type: ignore[override]  # each loop takes its own command types
        self._commands.append(command)

    def estop(self) -> None:
        """Torque off at the next period (from any thread; never raises) and stop walking.

        The loop thread sends it (one writer on the bus); without a running thread it is
        sent from here.
        """
        self.post(EStop())
        if not self._pacer.running and self.backend is not None:
            try:
                self.backend.estop()
            except (BackendError, OSError, ValueError):
                pass

    def _apply(self, command: Command) -> None:
        """One command, in the loop thread."""
        match command:
            case Walk(plan):
                self.walker.set_plan(plan, now=not self._walking)
                self._walking, self._stopping, self._rest_at = True, False, None
            case SetPlan(plan):
                self.walker.set_plan(plan, now=not self._walking)
            case StopWalking():
                if self._walking:
                    self._stopping = True
                    self._rest_at = self.walker.phase + self.walker.next_rest()
            case SetSpeed(speed):
                self._speed = speed
            case SetInPlace(in_place):
                self.walker.in_place = in_place
                self.walker.reset()
            case Reset():
                self._walking = self._stopping = False
                self._rest_at = None
                self.walker.reset()
                self._last_goal = np.full(12, np.nan)  # the rise starts from the reading
                if self.backend is not None:
                    try:
                        self.backend.set_torque(True)
                        self._torque = True
                        self._fault = ""
                        self._ramp = None  # set from the next reading
                    except (BackendError, OSError, ValueError) as exc:
                        self._fail(f"torque on failed: {exc}")
            case EStop():
                self._walking = self._stopping = False
                self._torque = False
                if self.backend is not None:
                    self.backend.estop()

    # --- the loop ------------------------------------------------------------------------

    def start(self) -> None:
        """Start the loop thread."""
        self._pacer.start()

    def shutdown(self, *, torque_off: bool = True) -> None:
        """Stop the thread (waits for the current tick); torque off by default."""
        self._pacer.stop(timeout=3.0)
        if torque_off and self.backend is not None:
            try:
                self.backend.estop()
            except (BackendError, OSError, ValueError):
                pass
            self._torque = False
        self.status = self._make_status()

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of periods now, in the calling thread (the thread must not run)."""
        self._pacer.run_for(seconds)

    def _stopped(self, _error: Exception | None) -> None:
        self.status = self._make_status()

    def _fail(self, why: str) -> None:
        self._fault = why
        self._walking = self._stopping = False
        self._torque = False
        if self.backend is not None:
            self.backend.estop()

    def _period(self) -> None:
        while self._commands:
            self._apply(self._commands.popleft())
        self._t += self.period  # periods at 0, P, 2P, ...: the backend is brought there
        t = self._t
        q_meas = np.full(12, np.nan)
        servos = self.backend is not None and not self._fault
        if servos:
            assert self.backend is not None  # servos: it has one
            try:
                if self._torque and not self._torque_sent:
                    self.backend.set_torque(True)  # goal = where each servo is: no jump
                    self._torque_sent = True
                self.backend.sync(t)
                q_meas = np.asarray(self.backend.read().position, dtype=float)
            except (BackendError, OSError) as exc:
                self._fail(f"reading the servos failed: {exc}")
                servos = False
        state = self.state
        self._record(t, state, q_meas)
        if self._walking:
            self.walker.advance(self._speed * self.period)
            if self._stopping and self._rest_at is not None and \
                    self.walker.phase >= self._rest_at - 1e-9:
                self._walking = self._stopping = False
                self._rest_at = None
        state = self.walker.state()
        self.state = state
        goal = state.q
        if servos and self._torque:
            if self._ramp is None and np.all(np.isfinite(q_meas)):
                rise = float(np.max(np.abs(goal - q_meas))) / APPROACH_SPEED
                self._ramp = (q_meas.copy(), t, max(STAND_UP_S, rise))
            if self._ramp is not None and t - self._ramp[1] < self._ramp[2]:
                s = (t - self._ramp[1]) / self._ramp[2]  # linear: the speed is d / T
                goal = (1.0 - s) * self._ramp[0] + s * goal
            prev = np.where(np.isfinite(self._last_goal), self._last_goal, goal)
            speed = np.clip(1.5 * np.abs(goal - prev) / self.period, MIN_SPEED, MAX_SPEED)
            assert self.backend is not None  # servos: it has one
            try:
                self.backend.write(goal, speed)
            except (BackendError, OSError) as exc:
                self._fail(f"writing the servos failed: {exc}")
            except ValueError as exc:
                self._fail(f"goal refused: {exc}")
        self._last_goal = goal.copy()
        self.status = self._make_status()

    def _record(self, t: float, state: WalkState, q_meas: np.ndarray) -> None:
        row = np.concatenate([[t, float(self._walking and self._ramp_done(t)), state.phase],
                              self._last_goal, q_meas, [state.margin], state.body,
                              state.stance.astype(float), state.feet.reshape(12)])
        self._ring.append(row)

    def _ramp_done(self, t: float) -> bool:
        return self._ramp is None or t - self._ramp[1] >= self._ramp[2] + self.period

    def _make_status(self) -> GaitStatus:
        spec = self.walker.plan.spec
        return GaitStatus(
            t=max(self._t, 0.0), walking=self._walking, stopping=self._stopping,
            command=spec.command, gait=spec.gait, speed=self._speed,
            servos=self.backend is not None and not self._fault, torque_on=self._torque,
            standing_up=self._ramp is not None and self._t - self._ramp[1] < self._ramp[2],
            fault=self._fault, running=self._pacer.running,
            restarts=int(getattr(self.backend, "restarts", 0)),
            restarted_at=getattr(self.backend, "restarted_at", None))
