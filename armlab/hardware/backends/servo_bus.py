"""What the backends on a serial bus of Dynamixel servos share, whichever protocol.

:class:`ServoBusBackend` is the part of ``armlab.control.backend.Backend`` that does not
depend on the servos' protocol or control table: opening the bus and finding every mapped
servo (PING, model; the other protocol named when nothing answers), the joint map, the
joint limits narrowed to the servos' own, the wall-clock ``sync``, E-STOP (broadcast
torque off, also tried whenever the link fails), reconnecting after a lost link and
switching the servos' baud, an arm's gripper servo (found with the joints', its goal
clamped into the gripper's range), goals clamped into the servos' own limits and sent in
one SYNC_WRITE, and torque on without a jump (each servo without torque first gets its
present position as goal). Each family's backend adds how it reads, lays out its goals,
brings its servos back at torque on and configures them:
:class:`~armlab.hardware.families.dynamixel1.backend.DynamixelBackend` (protocol 1.0),
:class:`~armlab.hardware.families.xseries.backend.XSeriesBackend` (X-series, protocol 2.0) and
:class:`~armlab.hardware.families.feetech.backend.StsBackend` (Feetech STS, the SO-101's).
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from armlab.control.backend import BackendError, GoalLimits, GripperState, JointState
from armlab.hardware.backends.gripper import GripperHolder
from armlab.hardware.backends.joint_map import (
    JointMap,
    default_joint_map,
    load_joint_map,
    servo_table,
)
from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.registry import family
from armlab.hardware.wire.bus import Bus, BusStats
from armlab.hardware.wire.errors import BusError, NoReply
from armlab.kinematics.catalog import ROBOT_FILES
from armlab.kinematics.model import Quadruped, SerialChain

log = logging.getLogger("armlab.dynamixel")

#: Thesis §2.3 "Set Status Return Level": 1 = status packets for READ only.
THESIS_STATUS_RETURN_LEVEL = 1
#: rad/s towards the goal set when torque comes on (the present position, clamped).
SAFE_SPEED = 1.0
#: s: a torque-off sent again this soon after the last is the same press (the page's
#: E-STOP sends one at once and the loop one at its next period): logged once
ESTOP_REPEAT_S = 1.0


def uncalibrated_note(model: SerialChain | Quadruped, port: str) -> str:
    """What a person is told of an arm whose joint map is not calibrated: what it risks,
    what the lab does and the command that calibrates it."""
    robot = model.name if model.name in ROBOT_FILES else str(model.urdf_path or model.name)
    return (f"uncalibrated: {model.name}'s joint map is not calibrated (no map, or one "
            "drafted by a scan), so its angles may not be the arm's and a goal may drive a "
            "joint into its stop or the table; torque stays off until you confirm on the "
            f"page that the arm is clear. Calibrate: armlab scan --port {port} --robot "
            f"{robot} --calibrate --write-map arm.toml, then serve with --joint-map arm.toml")


class ServoBusBackend(GoalLimits, GripperHolder, ABC):
    """A :class:`~armlab.control.backend.Backend` on servos of one family.

    Args:
        model: the robot model (joint order, joint limits).
        port: serial device (or the emulator's /dev/pts/N).
        baud: bit/s the servos run at after configuration (thesis: 1 Mbps).
        joint_map: joint-to-servo mapping, or the path of a JSON/TOML map file;
            default: :func:`default_joint_map` (thesis IDs 1, 3, 5 for the receptionist arm).
        from_baud: bit/s the servos answer at now, if not ``baud`` (e.g. an RX-24F
            fresh from the factory at 57 600): configuration then switches them.
        configure: run the thesis's configuration sequence on open.
        torque_limit: fraction 0..1 of the maximum torque for the torque limit.
        status_return_level: what the servos answer after configuration (1 or 2).
        retries, timeout_margin, echo, rs485: passed to :class:`~armlab.hardware.wire.bus.Bus`.

    Raises:
        BackendError: port missing/busy/forbidden, a servo silent or of the wrong model
            (the bus's :class:`~armlab.hardware.wire.errors.BusError` translated, kept as
            its cause).
    """

    #: the protocol of the servos this backend drives (its family's tag)
    PROTOCOL: ClassVar[int | str]
    _cw: list[int]  #: each servo's raw lower position limit (from :meth:`_limits`)
    _ccw: list[int]  #: each servo's raw upper position limit

    def __init__(self, model: SerialChain | Quadruped, port: str, *, baud: float = 1_000_000,
                 joint_map: JointMap | str | Path | None = None, from_baud: float | None = None,
                 configure: bool = True, torque_limit: float = 1.0,
                 status_return_level: int = THESIS_STATUS_RETURN_LEVEL,
                 retries: int | None = None, timeout_margin: float | None = None,
                 echo: bool = False,
                 rs485: bool = False):
        if not 0.0 <= torque_limit <= 1.0:
            raise ValueError(f"torque_limit: a fraction 0..1 of max torque, got {torque_limit}")
        if status_return_level not in (1, 2):
            raise ValueError(f"status_return_level must be 1 or 2, got {status_return_level}")
        self.model = model
        if isinstance(joint_map, str | Path):
            joint_map = load_joint_map(joint_map, model)
        self.map = joint_map or default_joint_map(model)
        if self.map.protocol != self.PROTOCOL:
            raise ValueError(
                f"the {self.map.servo} speaks protocol {self.map.family.label}: open it with "
                "armlab.hardware.family_parts.open_servo_backend(), which picks the backend")
        self.table: ControlTable = servo_table(self.map.servo)
        self.spec = self.table.spec
        self._baud_value(baud)  # ValueError for a rate the servos cannot take
        self.baud = float(baud)
        self.torque_limit = float(torque_limit)
        self.gripper = self.map.gripper
        #: every servo on the bus: the joints', then the gripper's
        self._ids = self.map.ids + ((self.gripper.servo_id,) if self.gripper else ())
        self._gripper_goal: int | None = None  #: raw goal position, sent with every write
        self._gripper_alarm = ""  #: the gripper servo's alarm ("" = healthy)
        self._layout()
        self.status_return_level_setting = int(status_return_level)
        self.configuration: list[str] = []
        self.estops = 0
        self._estop_unsent = False  # the last torque-off could not be written
        self._estop_logged = -math.inf  # monotonic s of the last "torque off sent" line
        self._estop_lock = threading.Lock()
        self._torque = False
        self._shutdown = np.zeros(self.map.n, dtype=bool)
        self._closed = False
        self._sync_t0: float | None = None
        #: s, the most a ``sync(t)`` came after its time (the loop or the OS stalled)
        self.late_max = 0.0
        self._bus_options: dict[str, Any] = {"retries": retries, "timeout_margin": timeout_margin,
                             "echo": echo, "rs485": rs485, "table": self.table,
                             "protocol": self.PROTOCOL}
        if not configure and from_baud is not None and from_baud != baud:
            raise ValueError("from_baud needs configure=True to switch the servos' baud")
        self._open(port, from_baud or baud, configure=configure, from_baud=from_baud)
        self._t0 = time.monotonic()
        #: why the lab keeps the torque off until a person confirms (None: calibrated)
        self.uncalibrated = None if self.map.calibrated else uncalibrated_note(model, port)
        if self.uncalibrated:
            log.warning(self.uncalibrated)

    def _open(self, port: str, baud: float, *, configure: bool,
              from_baud: float | None = None) -> None:
        """Open the bus on ``port`` at ``baud``, find the servos, read their limits and (if
        asked) configure them; on any failure the bus is closed again and a bus error
        becomes one BackendError."""
        try:
            self.bus = Bus(port, baud, **self._bus_options)
        except BusError as exc:
            raise BackendError(str(exc)) from exc
        try:
            self._find_servos()
            self._lower, self._upper = self._limits()
            if configure:
                self.configure(from_baud=from_baud)
        except BusError as exc:
            self.bus.close()
            raise BackendError(str(exc)) from exc
        except BaseException:
            self.bus.close()
            raise

    # -- Backend protocol ---------------------------------------------------

    @property
    def n(self) -> int:
        return self.map.n

    @property
    def stats(self) -> BusStats:
        """The bus counters (transactions, retries, timeouts, corrupt replies...)."""
        return self.bus.stats

    def sync(self, t: float) -> None:
        """Hardware lives in real time: nothing to integrate.

        A loop running ahead of the wall clock (headless ``run_for``) is held back
        until ``t`` s after its first ``sync``, so a 16 ms period stays 16 ms on the
        servos; a real-time loop (behind or on time) never waits here.
        """
        now = time.monotonic()
        if self._sync_t0 is None:
            self._sync_t0 = now - t
        wait = self._sync_t0 + t - now
        if wait > 0:
            time.sleep(wait)
        else:
            self.late_max = max(self.late_max, -wait)

    def _sync_torque(self, ids: tuple[int, ...], on: int) -> None:
        address, data = self.table.encode("torque_enable", on)
        self._guard(self.bus.sync_write, address, len(data), {i: data for i in ids})

    def estop(self) -> bool:
        """Broadcast torque off now; never raises (the link may be gone).

        Returns:
            True once the packet was written to the port; False when it could not be (the
            servos' torque is then unknown: the caller must say so, not "torque off").
        """
        with self._estop_lock:  # the page's press and the loop's may come at once
            return self._estop()

    def _estop(self) -> bool:
        self.estops += 1
        was_on = self._torque
        try:
            self.bus.write_bytes(self.bus.broadcast_id, *self.table.encode("torque_enable", 0))
        except (BusError, OSError, ValueError) as exc:
            if not self._estop_unsent:  # one line per outage, not one per retry
                if was_on:
                    log.error("e-stop: torque off could not be sent (%s)", exc)
                else:  # nothing holds the arm: say so, and do not alarm
                    log.warning("e-stop: the link is down (%s); the servos' torque was "
                                "already off", exc)
            self._estop_unsent = True
            return False
        self._torque = False
        now = time.monotonic()
        # one press reaches here twice (the page's E-STOP, then the loop's): one line each
        again = now - self._estop_logged < ESTOP_REPEAT_S and not self._estop_unsent
        (log.debug if again else log.warning)(
            "e-stop: broadcast torque off sent%s",
            " (the link is back)" if self._estop_unsent else "")
        if not again:
            self._estop_logged = now
        self._estop_unsent = False
        return True

    @property
    def senses_current(self) -> bool:
        """Whether the servos measure their motor current
        (``armlab.control.backend.CurrentSensing``):
        X-series with a current sensor and Feetech STS; protocol-1.0 servos report a load
        estimate."""
        return bool(getattr(self.spec, "has_current", False))

    def set_gripper(self, position: float) -> float:
        """Hold the gripper's finger at ``position``, clamped into its range (a goal
        beyond it is never sent), from the next :meth:`write` on; returns the clamped goal.

        Raises:
            ValueError: a non-finite position, or no gripper servo in the map.
        """
        if self.gripper is None:
            raise ValueError("this arm's joint map names no gripper servo")
        x, self._gripper_goal = self._gripper_goal_raw(position)
        return x

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Clamp goals into the limits; send them with their speeds in one SYNC_WRITE (the
        gripper's goal with them, :meth:`_send_goals`)."""
        q, v = self.checked_goal(position, speed)
        goals, speeds = self.goal_words(q, v)
        self._send_goals({j.servo_id: (g, sp)
                          for j, g, sp in zip(self.map.joints, goals, speeds, strict=True)})

    def set_torque(self, on: bool) -> None:
        """Torque on or off, the gripper's with the joints'. On: first what the family does
        to bring its servos back (:meth:`_before_torque_on`); then a servo whose torque was
        off gets its present position (clamped) as goal at ``SAFE_SPEED``, so nothing
        jumps (the gripper's finger stays where it is)."""
        if on:
            self._before_torque_on()
            off = [k for k in range(self.n) if not self._torque or self._shutdown[k]]
            grip = self.gripper is not None and (not self._torque or bool(self._gripper_alarm))
            if off or grip:
                state = self.read()
                goals, speeds = self.goal_words(state.position, np.full(self.n, SAFE_SPEED))
                if grip and state.gripper is not None:  # the finger stays where it is
                    self.set_gripper(state.gripper.position)
                ids = self.map.ids
                self._send_goals({ids[k]: (goals[k], speeds[k]) for k in off})
            self._sync_torque(self._ids, 1)
            self._shutdown[:] = False
            self._gripper_alarm = ""
        else:
            self._sync_torque(self._ids, 0)
        self._torque = bool(on)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.bus.close()

    def reconnect(self) -> list[str]:
        """After a lost link: open the same device path again (a ``/dev/serial/by-id`` name
        or ``armlab emulate --link`` survives a re-plug or a restart), find the servos,
        read their limits, run the configuration sequence again and broadcast torque off.

        Returns:
            The configuration lines.

        Raises:
            BackendError: the device or a servo is still missing (the old bus stays closed).
        """
        port = self.bus.port
        with contextlib.suppress(OSError, BusError):
            self.bus.close()
        self._open(port, self.baud, configure=True)
        try:
            self._sync_torque(self._ids, 0)
        except BackendError:
            self.bus.close()
            raise
        self._torque = False
        self._estop_unsent = False
        self._shutdown[:] = False
        log.warning("link to %s back: servos configured again, torque off", port)
        return self.configuration

    # -- set-up -------------------------------------------------------------

    def _switch_baud(self, from_baud: float | None, lines: list[str]) -> None:
        """The last configuration step: servos answering at ``from_baud`` are told the
        backend's baud and the bus follows them (one logged line each, added to ``lines``)."""
        target = self._baud_value(self.baud)
        if from_baud is not None and self._baud_value(from_baud) != target:
            for i, who in self._named_servos():
                self._write_setting(i, "baud_rate", target)
                lines.append(f"servo {i} ({who}): baud {self.baud:.0f} bps")
                log.info(lines[-1])
            time.sleep(0.01)
            self._guard(self.bus.set_baud, self.baud)
            for i, _ in self._named_servos():
                self._guard(self.bus.ping, i)
        else:
            lines.append(f"all servos: baud {self.baud:.0f} bps (already set)")
            log.info(lines[-1])

    def _named_servos(self) -> list[tuple[int, str]]:
        """(ID, name for the log) of every servo on the bus: the joints', the gripper's."""
        grip = self.gripper
        return [(j.servo_id, j.name) for j in self.map.joints] + (
            [(grip.servo_id, f"gripper {grip.joint}")] if grip is not None else [])

    def _write_setting(self, servo_id: int, name: str, value: int) -> None:
        self._guard(self.bus.write, servo_id, name, value)

    def _setting(self, servo_id: int, who: str, name: str, value: int, text: str) -> str:
        """Write item ``name`` of servo ``servo_id`` (``who``: its name for the log) unless
        it is an EEPROM item that already holds ``value`` (EEPROM wears); the line for the
        log, ``text`` said of the servo."""
        if (self.table.item(name).area == "EEPROM"
                and self._guard(self.bus.read, servo_id, name) == value):
            return f"servo {servo_id} ({who}): {text} (already set)"
        self._write_setting(servo_id, name, value)
        return f"servo {servo_id} ({who}): {text}"

    def _find_servos(self) -> None:
        """PING every mapped servo (the joints', then the gripper's: one that does not
        answer, or is of another model, is named) and check its model; read how it answers
        (:meth:`_read_replies`).

        When the first servo does not answer, the servos may speak the other protocol (a
        joint map naming the wrong servo family): :meth:`_wrong_protocol` asks, and names
        it. Nothing is written to a servo before they all answered.
        """
        for k, j in enumerate(self.map.joints):
            try:
                self.bus.ping(j.servo_id)
            except BusError as exc:
                wrong = self._wrong_protocol() if k == 0 and isinstance(exc, NoReply) else None
                raise BackendError(wrong or f"joint {j.name}: {exc}") from exc
            self.bus.identify(j.servo_id, expect=self.map.servo)
            self._read_replies(j.servo_id)
        g = self.gripper
        if g is None:
            return
        try:
            self.bus.ping(g.servo_id)
            self.bus.identify(g.servo_id, expect=self.map.servo)
        except BusError as exc:
            raise BackendError(
                f"the gripper's servo (ID {g.servo_id}, {g.joint}) on {self.bus.port}: {exc}; "
                f"check its cable and ID (armlab scan --port {self.bus.port} lists what "
                "answers), or remove [gripper] from the joint map") from exc
        self._read_replies(g.servo_id)

    def _read_replies(self, servo_id: int) -> None:
        """Read how servo ``servo_id`` answers, for the bus: its return delay (how long to
        wait) and its status return level (an earlier session may have left it answering
        PING and READ only, so the bus must not wait for its answer to a write: the
        level is kept in EEPROM on protocol 1.0 and STS servos, in RAM until power-off on
        X-series)."""
        self.bus.return_delay[servo_id] = self.bus.read(servo_id, "return_delay_time")
        self.bus.status_return_level[servo_id] = self.bus.read(servo_id, "status_return_level")

    def _wrong_protocol(self) -> str | None:
        """The message for servos that answer another family's protocol at this baud (None
        when nothing does): the joint map names a servo model of the wrong family
        (:meth:`~armlab.hardware.wire.bus.Bus.ping_other_protocol`: a broadcast PING in
        protocol 2.0, the map's IDs in 1.0)."""
        other, ids = self.bus.ping_other_protocol(self.map.ids)
        if not ids:
            return None
        return (f"the servos on {self.bus.port} answer {family(other).protocol_name} "
                f"(ID{'s' if len(ids) > 1 else ''} {', '.join(map(str, ids))}), but the joint "
                f"map names {self.map.servo} ({self.map.family.protocol_name}): fix the map's "
                f"servo model (armlab scan --port {self.bus.port} shows what answers)")

    def _narrowed(self, cw: list[int], ccw: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """The map's joint limits narrowed to the servos' raw limits ``cw``..``ccw``;
        BackendError naming the joints where the two do not overlap."""
        a_lo = np.array([self.spec.raw_to_position(x) for x in cw])
        a_hi = np.array([self.spec.raw_to_position(x) for x in ccw])
        q_lo, q_hi = self.map.servo_limits_to_joint(a_lo, a_hi)
        lower = np.maximum(self.map.lower, q_lo)
        upper = np.minimum(self.map.upper, q_hi)
        if np.any(lower > upper):
            bad = [j.name for j, lo, hi in zip(self.map.joints, lower, upper, strict=True)
                   if lo > hi]
            raise BackendError(f"joints {', '.join(bad)}: the joint map's limits and the "
                               "servos' angle limits do not overlap")
        return lower, upper

    def _goal_positions(self, position: np.ndarray) -> list[int]:
        """Raw goal positions for joint goals: clamped into [lower, upper], then into each
        servo's own position limits (never outside)."""
        q = np.clip(position, self._lower, self._upper)
        a = self.map.to_servo(q)
        return [min(max(self.spec.position_to_raw(x), lo), hi)
                for x, lo, hi in zip(a, self._cw, self._ccw, strict=True)]

    def _send_goals(self, words: dict[int, tuple[int, int]]) -> None:
        """One SYNC_WRITE of raw (goal position, speed) per servo ID, each as the family's
        bytes (:meth:`_goal_bytes`), the gripper's goal after them once one was set
        (:meth:`_gripper_words`)."""
        if self.gripper is not None and self._gripper_goal is not None:
            words = words | {self.gripper.servo_id: self._gripper_words(self._gripper_goal)}
        self._guard(self.bus.sync_write, self._goal_at, self._goal_len,
                    {i: self._goal_bytes(g, sp) for i, (g, sp) in words.items()})

    def _joint_state(self, pos: Sequence[float] | np.ndarray, vel: Sequence[float] | np.ndarray,
                     load: Sequence[float] | np.ndarray, errors: Sequence[int],
                     alarms: Sequence[str], *,
                     torque_on: tuple[bool, ...],
                     gripper: GripperState | None = None) -> JointState:
        """The servos' decoded readings (servo side, one per joint) as the joints' state,
        timed from the backend's opening."""
        signs = self.map.signs
        return JointState(
            t=time.monotonic() - self._t0,
            position=self.map.to_joint(np.array(pos)),
            velocity=signs * np.array(vel),
            load=signs * np.array(load),
            errors=tuple(errors),
            torque_on=torque_on,
            alarms=tuple(alarms),
            gripper=gripper,
        )

    def _guard(self, fn, *args, **kwargs):
        """Run a bus call; on a link failure try torque off, then raise one BackendError
        (the control layer's error; the bus's :class:`~armlab.hardware.wire.errors.BusError` is its
        cause)."""
        try:
            return fn(*args, **kwargs)
        except BusError as exc:
            self.estop()
            raise BackendError(self._joints_of(exc) + str(exc)) from exc
        except OSError as exc:
            self.estop()
            raise BackendError(f"serial link on {self.bus.port} failed: {exc}") from None

    def _joints_of(self, exc: BusError) -> str:
        """"joint NAME: " (or "joint A, joint B: ", "the gripper JOINT: ") for the servos
        a :class:`~armlab.hardware.wire.errors.NoReply` names, so the message says which joint
        stopped answering; "" for any other error."""
        ids = exc.ids if isinstance(exc, NoReply) else ()
        names = [f"joint {j.name}" for j in self.map.joints if j.servo_id in ids]
        if self.gripper is not None and self.gripper.servo_id in ids:
            names.append(f"the gripper {self.gripper.joint}")
        return f"{', '.join(names)}: " if names else ""

    # -- what each protocol does its own way ---------------------------------

    #: where the goals sit: one SYNC_WRITE of ``_goal_len`` bytes at ``_goal_at`` a servo
    _goal_at: int
    _goal_len: int

    def _baud_value(self, baud: float) -> int:
        """The servos' Baud Rate value for ``baud``; ValueError for a rate they cannot take."""
        return self.table.from_si("baud_rate", baud)

    @abstractmethod
    def _layout(self) -> None:
        """Where the present values and goals sit in the control table (``_goal_at``,
        ``_goal_len`` among them; called by ``__init__`` before the port opens)."""

    @abstractmethod
    def read(self) -> JointState:
        """The joints' state, read from every servo."""

    @abstractmethod
    def goal_words(self, position: np.ndarray, speed: np.ndarray) -> tuple[list[int], list[int]]:
        """Raw goal positions and speeds for joint goals, clamped into [lower, upper] and
        each servo's own position limits (never outside)."""

    @abstractmethod
    def _goal_bytes(self, goal: int, speed: int) -> bytes:
        """A servo's raw goal position and speed as its part of the goals' SYNC_WRITE."""

    def _gripper_words(self, goal: int) -> tuple[int, int]:
        """The gripper's raw (goal position, speed) for raw goal ``goal``."""
        raise NotImplementedError(f"the {self.map.servo} drives no gripper")

    @abstractmethod
    def _before_torque_on(self) -> None:
        """What torque on does first to bring the servos back (the family's recovery from
        a shut-down or overload)."""

    @abstractmethod
    def configure(self, *, from_baud: float | None = None) -> list[str]:
        """The servos' configuration sequence, one logged line per step; the lines, also
        kept in :attr:`configuration`."""

    @abstractmethod
    def _limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits: the map's, narrowed to the servos' own (read from them); sets
        ``_cw``, ``_ccw`` (raw)."""
