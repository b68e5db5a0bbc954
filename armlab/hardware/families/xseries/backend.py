"""``XSeriesBackend``: the controller's servos are X-series Dynamixels (protocol 2.0).

The same ``armlab.control.backend.Backend`` as the protocol-1.0
:class:`~armlab.hardware.families.dynamixel1.backend.DynamixelBackend`, on the same base
(:class:`~armlab.hardware.backends.servo_bus.ServoBusBackend`: finding the servos, the
joint map, limits, E-STOP, reconnect), with what protocol 2.0 and the X-series do
their own way:

- :meth:`XSeriesBackend.configure`: torque off (EEPROM is written only then), return
  delay 0, operating mode (current-based position control where the servo measures its
  current, so Goal Current bounds its torque, with a Position D Gain for the damping the
  current loop takes away; position control on the XL430), status return level, no
  profile limits (the controller sends a speed with every goal), Goal Current or Goal
  PWM at ``torque_limit``, baud. Logged step by step; EEPROM items are written only when
  they differ;
- :meth:`read`: one SYNC_READ of Present Current, Velocity and Position (addresses
  126..135) for every servo; the torque is current × the servo's torque constant, or
  Present Load × stall torque on a servo without current sensing;
- :meth:`write`: every Profile Velocity and Goal Position (112..119) in one SYNC_WRITE,
  after clamping into the joint limits and the servos' Min/Max Position Limits;
- a servo that raised its hardware alert (the error byte's bit 7) is asked its Hardware
  Error Status once, named by ID and flag in its joint's alarm (:func:`hardware_alarm`);
  a flag in its Shutdown register has switched its torque off, and torque on REBOOTs it
  first (the only way back, e-manual "Shutdown");
- the gripper's servo the map names (the OpenManipulator-X's ID 15,
  :mod:`armlab.hardware.backends.gripper`)
  is configured in current-based position control at the gripper's gentle Goal Current,
  read in the same SYNC_READ and written in the same SYNC_WRITE as the joints (its goal
  from :meth:`XSeriesBackend.set_gripper`, clamped into the finger's range), its torque
  on and off with theirs.
"""

from __future__ import annotations

import logging
import time
from typing import cast

import numpy as np

from armlab.control.backend import GripperState, JointState
from armlab.hardware.backends.servo_bus import ServoBusBackend
from armlab.hardware.families.xseries import packets as p2
from armlab.hardware.families.xseries.gripper import (
    GRIPPER_PROFILE_VELOCITY,
    decode_gripper,
    gripper_settings,
)
from armlab.hardware.families.xseries.table import (
    VELOCITY_UNIT,
    OperatingMode,
    XControlTable,
    XSpec,
    hardware_alarm,
    lab_mode,
    lab_settings,
)

log = logging.getLogger("armlab.xseries")

#: Present Current (2), Present Velocity (4), Present Position (4): one SYNC_READ.
PRESENT_AT, PRESENT_LEN = 126, 10
#: Profile Velocity (4) and Goal Position (4): one SYNC_WRITE.
GOAL_AT, GOAL_LEN = 112, 8
#: Velocity Limit, Max Position Limit, Min Position Limit (44..55): one READ.
LIMIT_ITEMS = ("velocity_limit", "max_position_limit", "min_position_limit")
#: s a servo takes to restart after REBOOT before it answers again
REBOOT_WAIT = 0.5


class XSeriesBackend(ServoBusBackend):
    """A :class:`~armlab.control.backend.Backend` on X-series servos (protocol 2.0).

    Args: as :class:`~armlab.hardware.backends.servo_bus.ServoBusBackend` (``torque_limit``:
    the fraction of Current Limit, or of PWM Limit on a servo without current sensing,
    the servos may use).
    """

    PROTOCOL = 2
    table: XControlTable
    spec: XSpec
    _goal_at, _goal_len = GOAL_AT, GOAL_LEN

    def _layout(self) -> None:
        spec = self.spec
        self._alarms = [""] * self.map.n  #: the hardware error each servo reported
        self.mode = lab_mode(spec)
        self.table.check_operating_mode(self.mode)

    # -- Backend protocol ---------------------------------------------------

    def read(self) -> JointState:
        """One SYNC_READ of 126..135 -> joint positions, speeds, torques and alarms."""
        data = self._guard(self.bus.sync_read, PRESENT_AT, PRESENT_LEN, list(self._ids))
        s = self.spec
        pos, vel, load, errors, alarms = [], [], [], [], []
        for k, j in enumerate(self.map.joints):
            raw = data[j.servo_id]
            current = int.from_bytes(raw[0:2], "little", signed=True)
            vel.append(s.raw_to_velocity(int.from_bytes(raw[2:6], "little", signed=True)))
            pos.append(s.raw_to_position(int.from_bytes(raw[6:10], "little", signed=True)))
            load.append(s.raw_to_torque(current))
            err = cast(p2.StatusError, self.bus.errors.get(j.servo_id, p2.StatusError()))  # 2.0's
            errors.append(err.byte)
            if err.alert and not self._shutdown[k]:  # asked once, told once
                bits = self._guard(self.bus.read, j.servo_id, "hardware_error_status")
                self._alarms[k] = hardware_alarm(bits, servo_id=j.servo_id)
                self._shutdown[k] = True
                log.warning("joint %s: %s", j.name, self._alarms[k])
            alarms.append(self._alarms[k] if err.alert else "")
        return self._joint_state(
            pos, vel, load, errors, alarms,
            torque_on=tuple(bool(self._torque and not sd) for sd in self._shutdown),
            gripper=self._read_gripper(data[self.gripper.servo_id]) if self.gripper else None)

    def _read_gripper(self, raw: bytes) -> GripperState:
        """The gripper servo's part of the SYNC_READ (current, velocity, position) as the
        finger's state; its hardware alert is asked about once and logged."""
        g = self.gripper
        assert g is not None
        err = cast(p2.StatusError, self.bus.errors.get(g.servo_id, p2.StatusError()))  # 2.0's
        if err.alert and not self._gripper_alarm:
            bits = self._guard(self.bus.read, g.servo_id, "hardware_error_status")
            self._gripper_alarm = hardware_alarm(bits, servo_id=g.servo_id)
            log.warning("gripper: %s", self._gripper_alarm)
        return decode_gripper(
            g, self.spec, position=int.from_bytes(raw[6:10], "little", signed=True),
            velocity=int.from_bytes(raw[2:6], "little", signed=True),
            current=int.from_bytes(raw[0:2], "little", signed=True),
            torque_on=self._torque and not self._gripper_alarm, alarm=self._gripper_alarm)

    def _goal_bytes(self, goal: int, speed: int) -> bytes:
        """Profile Velocity and Goal Position as the SYNC_WRITE's 4 + 4 bytes."""
        return speed.to_bytes(4, "little") + goal.to_bytes(4, "little")

    def _gripper_words(self, goal: int) -> tuple[int, int]:
        """The gripper's goal at its profile velocity."""
        return goal, GRIPPER_PROFILE_VELOCITY

    def goal_words(self, position: np.ndarray, speed: np.ndarray) -> tuple[list[int], list[int]]:
        """Raw goal positions and profile velocities for joint goals: clamped into
        [lower, upper], then into each servo's Min..Max Position Limit (never outside).
        A speed of 0 is Profile Velocity 0: no limit, as Moving Speed 0 on protocol 1.0."""
        goals = self._goal_positions(position)
        speeds = [0 if x == 0 else min(max(round(abs(x) / VELOCITY_UNIT), 1), vmax)
                  for x, vmax in zip(speed, self._vmax, strict=True)]
        return goals, speeds

    def _before_torque_on(self) -> None:
        """A servo that shut down on a hardware error (the gripper's too) is REBOOTed (the
        only way back, e-manual "Shutdown") and its RAM settings written again."""
        ids = self.map.ids
        down = [ids[k] for k in range(self.n) if self._shutdown[k]]
        if self._gripper_alarm:
            down.append(self.gripper.servo_id)  # type: ignore[union-attr]  # a gripper alarm: there is a gripper
        for i in down:
            self._guard(self.bus.reboot, i)
        if down:
            time.sleep(REBOOT_WAIT)
            for i in down:
                self._guard(self.bus.ping, i)
                self._ram_settings(i, [])

    # -- set-up -------------------------------------------------------------

    def configure(self, *, from_baud: float | None = None) -> list[str]:
        """The configuration sequence, one logged line per step (see the module docstring).
        Returns the lines, also kept in :attr:`configuration`."""
        lines: list[str] = []
        self._sync_torque(self._ids, 0)
        for i, who, mode in self._configured():
            mode_text = ("current-based position control" if mode ==
                         OperatingMode.CURRENT_BASED_POSITION else "position control")
            eeprom = [("return_delay_time", 0, "return delay 0 µs"),
                      ("operating_mode", mode, f"operating mode {mode} ({mode_text})")]
            lines.append(f"servo {i} ({who}): torque off (EEPROM is written only then)")
            for name, value, text in eeprom:
                lines.append(self._setting(i, who, name, value, text))
            self._ram_settings(i, lines, name=who)
        for line in lines:
            log.info(line)
        self._switch_baud(from_baud, lines)
        self.configuration = lines
        return lines

    def _configured(self) -> list[tuple[int, str, int]]:
        """(ID, name for the log, operating mode) of every servo to configure: the joints
        in the lab's mode, the gripper's in current-based position control."""
        out = [(j.servo_id, j.name, self.mode) for j in self.map.joints]
        if self.gripper is not None:
            out.append((self.gripper.servo_id, f"gripper {self.gripper.joint}",
                        OperatingMode.CURRENT_BASED_POSITION))
        return out

    def _named_servos(self) -> list[tuple[int, str]]:
        """(ID, name for the log) of every servo on the bus: the joints', the gripper's."""
        return [(i, who) for i, who, _ in self._configured()]

    def _ram_settings(self, servo_id: int, lines: list[str], *, name: str = "") -> None:
        """The RAM items (lost at a REBOOT): status return level, no profile limit, then
        the mode's own (:func:`armlab.hardware.families.xseries.table.lab_settings`: the torque
        bound, the D gain; the gripper's
        :func:`armlab.hardware.families.xseries.gripper.gripper_settings`)."""
        who = f"servo {servo_id}" + (f" ({name})" if name else "")
        gripper = self.gripper is not None and servo_id == self.gripper.servo_id
        settings = (("status_return_level", self.status_return_level_setting,
                     f"status return level {self.status_return_level_setting}"),
                    ("profile_acceleration", 0, "profile acceleration 0 (no limit)"),
                    ("profile_velocity", 0, "profile velocity 0 (set with every goal)"),
                    *(gripper_settings(self.spec) if gripper else
                      lab_settings(self.spec, torque_limit=self.torque_limit)))
        for item, value, text in settings:
            self._write_setting(servo_id, item, value)
            lines.append(f"{who}: {text}")

    def _limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits: the map's, narrowed to each servo's Min..Max Position Limit.

        One READ of Velocity Limit, Max and Min Position Limit (44..55) a servo
        (:meth:`~armlab.hardware.wire.bus.Bus.read_items`: a limit read wrong would let goals past
        it)."""
        limits = [self._guard(self.bus.read_items, i, LIMIT_ITEMS) for i in self.map.ids]
        self._cw = [x["min_position_limit"] for x in limits]
        self._ccw = [x["max_position_limit"] for x in limits]
        #: a profile velocity above Velocity Limit would be refused (Data Limit)
        self._vmax = [x["velocity_limit"] for x in limits]
        return self._narrowed(self._cw, self._ccw)

