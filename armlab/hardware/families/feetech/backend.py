"""``StsBackend``: the controller's servos are Feetech STS servos (the SO-101's STS3215s).

The same ``armlab.control.backend.Backend`` as the Dynamixel backends, on the same base
(:class:`~armlab.hardware.backends.servo_bus.ServoBusBackend`: finding the servos, the
joint map, limits, E-STOP, reconnect, the gripper's servo), with what the STS series
does its own way (:mod:`armlab.hardware.families.feetech.table`,
:mod:`armlab.hardware.families.feetech.packets`):

- :meth:`StsBackend.configure`: torque off; EEPROM unlocked (Lock 0: an STS ignores
  EEPROM writes while locked); return delay 0, Response Status Level 0 (the thesis's
  "answer READ only"), position mode, the position loop's P, D, I coefficients (P 16,
  LeRobot's for the SO-101), each written only when it differs (EEPROM wears); in RAM
  Acceleration 0 (no limit: every goal comes with its speed) and Torque Limit at
  ``torque_limit`` (the gripper's at half, as LeRobot sets it); baud; EEPROM locked again.
  Logged step by step. The compliance law writes goal positions only: this servo has no
  current (torque) mode, so the servo's P coefficient and torque limit are the lab's
  configuration, as the thesis's compliance slope and torque limit were on the RX-24F;
- :meth:`read`: one SYNC_READ of Present Position .. Present Current (56..70) of every
  servo; the torque is Present Current (a magnitude) × the torque constant, signed as
  Present Load (the PWM duty): the servo's only torque reading (*interpretation*:
  Feetech documents no sign for the current);
- :meth:`write`: every Goal Position, Goal Time and Goal Speed (42..47, sign-magnitude)
  in one SYNC_WRITE, after clamping into the joint limits and the servos' Min/Max
  Position Limit, so a goal outside either never leaves the process;
- a status byte with error bits (overload, overheating, voltage, angle sensor,
  over-current) is named with the joint's servo in its alarm
  (:func:`~armlab.hardware.families.feetech.table.sts_alarm`); the loop then stops with torque off.
  Torque on again clears an overload (the firmware holds its output back until then);
- the gripper's servo (the SO-101's ID 6, :func:`armlab.hardware.backends.gripper.
  so101_gripper`) is read in the same SYNC_READ and written in the same SYNC_WRITE as the
  joints (its goal from :meth:`~ServoBusBackend.set_gripper`, clamped into the jaw's range
  and its servo's limits), its torque on and off with theirs.
"""

from __future__ import annotations

import logging

import numpy as np

from armlab.control.backend import GripperState, JointState
from armlab.hardware.backends.gripper import (
    GRIPPER_SPEED,
    SO101_GRIPPER_TORQUE_LIMIT,
    gripper_state,
)
from armlab.hardware.backends.servo_bus import ServoBusBackend
from armlab.hardware.families.feetech.table import (
    COUNTS,
    StsControlTable,
    StsSpec,
    lab_settings,
    sts_alarm,
)

log = logging.getLogger("armlab.sts")

#: Present Position (2), Speed (2), Load (2), Voltage, Temperature, .., Current (2) at
#: 69: one SYNC_READ of 56..70.
PRESENT_AT, PRESENT_LEN = 56, 15
#: Goal Position (2), Goal Time (2), Goal Speed (2): one SYNC_WRITE of 42..47.
GOAL_AT, GOAL_LEN = 42, 6


class StsBackend(ServoBusBackend):
    """A :class:`~armlab.control.backend.Backend` on Feetech STS servos.

    Args: as :class:`~armlab.hardware.backends.servo_bus.ServoBusBackend` (``torque_limit``:
    the fraction of the maximum torque the joints' servos may use, their Torque Limit;
    ``status_return_level`` 1, the thesis's, is the STS's Response Status Level 0 and 2
    its 1).
    """

    PROTOCOL = "sts"
    table: StsControlTable
    spec: StsSpec
    _goal_at, _goal_len = GOAL_AT, GOAL_LEN

    def _layout(self) -> None:
        t = self.table
        self._torque_limit_raw = round(self.torque_limit * t.item("max_torque").default)  # type: ignore[operator]  # the STS tables give max_torque a default
        self._gripper_limit_raw = round(SO101_GRIPPER_TORQUE_LIMIT  # type: ignore[operator]  # the STS tables give max_torque a default
                                        * t.item("max_torque").default)
        #: (item, offset in the SYNC_READ's bytes) of what a read decodes
        self._present = {name: t.item(name).address - PRESENT_AT for name in (
            "present_position", "present_speed", "present_load", "present_current")}
        self._gripper_ends = (0, COUNTS - 1)  #: the gripper servo's own raw limits

    # -- Backend protocol ---------------------------------------------------

    def _decode(self, raw: bytes) -> tuple[float, float, float]:
        """One servo's part of the SYNC_READ -> horn angle rad, speed rad/s, torque N·m."""
        t, at = self.table, self._present
        s = self.spec
        value = {name: t.decode(name, raw[k:]) for name, k in at.items()}
        return (s.raw_to_position(value["present_position"]),
                s.raw_to_speed(value["present_speed"]),
                s.signed_torque(value["present_current"], value["present_load"]))

    def read(self) -> JointState:
        """One SYNC_READ of 56..70 -> joint positions, speeds, torques, error bits, alarms."""
        data = self._guard(self.bus.sync_read, PRESENT_AT, PRESENT_LEN, list(self._ids))
        pos, vel, load, errors, alarms = [], [], [], [], []
        for k, j in enumerate(self.map.joints):
            a, v, tau = self._decode(data[j.servo_id])
            pos.append(a)
            vel.append(v)
            load.append(tau)
            err = int(self.bus.errors.get(j.servo_id, 0))
            errors.append(err)
            alarms.append(sts_alarm(err, servo_id=j.servo_id))
            if err and not self._shutdown[k]:  # told once, until the torque comes on again
                self._shutdown[k] = True
                log.warning("joint %s: %s", j.name, alarms[-1])
        return self._joint_state(
            pos, vel, load, errors, alarms,
            # a flagged STS keeps its torque (an overload only holds its output back)
            # until the lab switches it off
            torque_on=(self._torque,) * self.n,
            gripper=self._read_gripper(data[self.gripper.servo_id]) if self.gripper else None)

    def _read_gripper(self, raw: bytes) -> GripperState:
        """The gripper servo's part of the SYNC_READ as the jaw's state; its error bits
        are told once and logged."""
        g = self.gripper
        assert g is not None
        err = int(self.bus.errors.get(g.servo_id, 0))
        if err and not self._gripper_alarm:  # told once
            self._gripper_alarm = sts_alarm(err, servo_id=g.servo_id)
            log.warning("gripper: %s", self._gripper_alarm)
        a, v, tau = self._decode(raw)
        return gripper_state(g, angle=a, speed=v, torque=tau,
                             torque_on=self._torque,
                             alarm=self._gripper_alarm)

    def _goal_bytes(self, goal: int, speed: int) -> bytes:
        """Goal Position, Goal Time 0 and Goal Speed as the SYNC_WRITE's 6 bytes."""
        t = self.table
        return (t.encode("goal_position", goal)[1] + t.encode("goal_time", 0)[1]
                + t.encode("goal_speed", speed)[1])

    def _gripper_words(self, goal: int) -> tuple[int, int]:
        """The gripper's goal clamped into its servo's limits, at the gripper's speed."""
        lo, hi = self._gripper_ends
        return min(max(goal, lo), hi), self.spec.goal_speed_to_raw(GRIPPER_SPEED)

    def goal_words(self, position: np.ndarray, speed: np.ndarray) -> tuple[list[int], list[int]]:
        """Raw goal positions and speeds for joint goals: clamped into [lower, upper],
        then into each servo's Min..Max Position Limit (never outside). A speed of 0 is
        Goal Speed 0: no limit, as on the Dynamixels."""
        return self._goal_positions(position), [self.spec.goal_speed_to_raw(x) for x in speed]

    def _before_torque_on(self) -> None:
        """The Torque Limits written again (the lab's, whatever happened since; the
        gripper's its own); the torque coming on then clears an overload."""
        limits = {j.servo_id: self._torque_limit_raw for j in self.map.joints}
        if self.gripper is not None:
            limits[self.gripper.servo_id] = self._gripper_limit_raw
        self._guard(self.bus.sync_write, self.table.item("torque_limit").address, 2, {
            i: self.table.encode("torque_limit", x)[1] for i, x in limits.items()})

    # -- set-up -------------------------------------------------------------

    def configure(self, *, from_baud: float | None = None) -> list[str]:
        """The configuration sequence, one logged line per step (see the module
        docstring). Returns the lines, also kept in :attr:`configuration`."""
        level = self.status_return_level_setting - 1  # the thesis's 1 is the STS's 0
        reply = "answers PING and READ only" if level == 0 else "answers everything"
        lines: list[str] = ["all servos: torque off"]
        self._sync_torque(self._ids, 0)
        gripper_id = None if self.gripper is None else self.gripper.servo_id
        for i, who in self._named_servos():
            self._write_setting(i, "lock", 0)
            lines.append(f"servo {i} ({who}): EEPROM unlocked (Lock 0)")
            share = SO101_GRIPPER_TORQUE_LIMIT if i == gripper_id else self.torque_limit
            for name, value, text in (
                    ("return_delay_time", 0, "return delay 0 µs"),
                    ("status_return_level", level, f"response status level {level} ({reply})"),
                    *lab_settings(self.table, torque_limit=share)):
                lines.append(self._setting(i, who, name, value, text))
        self._switch_baud(from_baud, lines)
        for i, who in self._named_servos():
            self._write_setting(i, "lock", 1)
            lines.append(f"servo {i} ({who}): EEPROM locked (Lock 1)")
        for line in lines:
            log.info(line)
        self.configuration = lines
        return lines

    def _limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits: the map's, narrowed to each servo's Min..Max Position Limit (both
        in one READ a servo; both 0 is the whole turn); the gripper servo's kept for its
        goals."""
        names = ("min_position_limit", "max_position_limit")
        ends = []
        for i in self._ids:
            x = self._guard(self.bus.read_items, i, names)
            lo, hi = x[names[0]], x[names[1]]
            ends.append((0, COUNTS - 1) if lo == hi == 0 else (lo, hi))
        if self.gripper is not None:
            self._gripper_ends = ends.pop()
        self._cw = [lo for lo, _ in ends]
        self._ccw = [hi for _, hi in ends]
        return self._narrowed(self._cw, self._ccw)
