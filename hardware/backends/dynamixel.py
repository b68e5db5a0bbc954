"""``DynamixelBackend``: the controller's servos are real (or emulated) protocol-1.0
Dynamixels on a port.

Implements ``armlab.control.backend.Backend`` over a :class:`~armlab.hardware.wire.bus.Bus`
(what does not depend on the protocol, :class:`~armlab.hardware.backends.servo_bus.ServoBusBackend`:
finding the servos, limits, E-STOP, reconnect), with protocol 1.0's own:

- open: read each servo's CW/CCW angle limits and narrow the joint limits to them;
- :meth:`DynamixelBackend.configure`: the thesis's configuration sequence
  (§2.3, Fig. 2.22): return delay 0, status return level 1 (answer READ only),
  compliance margins 0 and slopes 64, torque limit, baud. Explicit and logged;
  EEPROM items are written only when they differ (EEPROM wears);
- :meth:`read`: one READ of addresses 36..41 (present position, speed, load) per
  servo (the AX-12A and RX-24F have no SYNC_READ);
- :meth:`write`: every goal position and moving speed in one SYNC_WRITE, after
  clamping into the joint limits, so a goal outside the CW/CCW limits never
  leaves the process.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from armlab.control.backend import BackendError, JointState
from armlab.hardware.backends.servo_bus import SAFE_SPEED, ServoBusBackend
from armlab.hardware.servos.control_table import (
    THESIS_COMPLIANCE_MARGIN,
    THESIS_COMPLIANCE_SLOPE,
)
from armlab.hardware.servos.servo_spec import value_from_baud
from armlab.hardware.wire import protocol1 as p1
from armlab.hardware.wire.bus import sync_data

log = logging.getLogger("armlab.dynamixel")

#: Error bits that stop the servo's torque with the default alarm shutdown (36).
SHUTDOWN_BITS = p1.ErrorBits.OVERHEATING | p1.ErrorBits.OVERLOAD


class DynamixelBackend(ServoBusBackend):
    """A :class:`~armlab.control.backend.Backend` on protocol-1.0 servos.

    Args: as :class:`~armlab.hardware.backends.servo_bus.ServoBusBackend`.
    """

    PROTOCOL = 1

    def _baud_value(self, baud: float) -> int:
        """The servos' Baud Rate value for ``baud``; ValueError for a rate they cannot take."""
        return value_from_baud(baud)

    def _layout(self) -> None:
        """Where the present values and goals sit in the control table."""
        item = self.table.item
        # one READ of present position, speed and load (adjacent items): address, length and
        # each item's bytes in the reply
        present = [item(n) for n in ("present_position", "present_speed", "present_load")]
        self._present_at = present[0].address
        self._present_len = present[-1].address + present[-1].size - self._present_at
        self._present = [slice(i.address - self._present_at, i.address - self._present_at + i.size)
                         for i in present]
        self._torque_limit = item("torque_limit")
        self._goal = item("goal_position")  # followed by moving_speed: one 4-byte write
        self._goal_size = self._goal.size + item("moving_speed").size
        self._torque_limit_raw = self.spec.torque_limit_to_raw(
            self.torque_limit * self.spec.stall_torque)

    # -- Backend protocol ---------------------------------------------------

    def read(self) -> JointState:
        """READ 36..41 of every servo -> joint positions, speeds, loads and error bits."""
        pos = np.empty(self.n)
        vel = np.empty(self.n)
        load = np.empty(self.n)
        errors = []
        s = self.spec
        for k, j in enumerate(self.map.joints):
            data = self._guard(self.bus.read_bytes, j.servo_id, self._present_at,
                               self._present_len)
            raw_pos, raw_speed, raw_load = (int.from_bytes(data[at], "little")
                                            for at in self._present)
            pos[k] = s.raw_to_position(raw_pos)
            vel[k] = s.raw_to_present_speed(raw_speed)
            load[k] = s.raw_to_load(raw_load)
            err = int(self.bus.errors.get(j.servo_id, 0))
            errors.append(err)
            if err & SHUTDOWN_BITS and not self._shutdown[k]:
                self._shutdown[k] = True
                log.warning("joint %s (servo %d): %s; its torque is off", j.name, j.servo_id,
                            p1.describe_errors(err))
        signs = self.map.signs
        return JointState(
            t=time.monotonic() - self._t0,
            position=self.map.to_joint(pos),
            velocity=signs * vel,
            load=signs * load,
            errors=tuple(errors),
            torque_on=tuple(bool(self._torque and not sd) for sd in self._shutdown),
            alarms=tuple(p1.error_names(e) for e in errors),
        )

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Clamp goals into the limits and send them with the speeds in one SYNC_WRITE."""
        q, v = self.checked_goal(position, speed)
        raw_goal, raw_speed = self.goal_words(q, v)
        data = sync_data({j.servo_id: (g, sp) for j, g, sp in
                          zip(self.map.joints, raw_goal, raw_speed, strict=True)}, (2, 2))
        self._guard(self.bus.sync_write, self._goal.address, self._goal_size, data)

    def goal_words(self, position: np.ndarray, speed: np.ndarray) -> tuple[list[int], list[int]]:
        """Raw goal positions and moving speeds for joint goals: clamped into
        [lower, upper], then into each servo's CW..CCW limits (never outside)."""
        q = np.clip(position, self._lower, self._upper)
        a = self.map.to_servo(q)
        goals = [min(max(self.spec.position_to_raw(x), lo), hi)
                 for x, lo, hi in zip(a, self._cw, self._ccw, strict=True)]
        speeds = [self.spec.speed_to_raw(abs(x)) for x in speed]
        return goals, speeds

    def set_torque(self, on: bool) -> None:
        """Torque on or off. A servo whose torque was off first gets its present position
        (clamped into the limits) as goal at ``SAFE_SPEED``, so nothing jumps; the torque
        limit is written again (the recovery from an overload shutdown)."""
        ids = self.map.ids
        if on:
            # an overload shutdown zeroed the torque limit: restoring it is the recovery
            limit = p1.word(self._torque_limit_raw)
            self._guard(self.bus.sync_write, self._torque_limit.address, self._torque_limit.size,
                        {i: limit for i in ids})
            off = [k for k in range(self.n) if not self._torque or self._shutdown[k]]
            if off:  # only servos without torque get a new goal (holding ones keep theirs)
                here = self.read().position
                goals, speeds = self.goal_words(here, np.full(self.n, SAFE_SPEED))
                self._guard(self.bus.sync_write, self._goal.address, self._goal_size, sync_data(
                    {ids[k]: (goals[k], speeds[k]) for k in off}, (2, 2)))
            self._sync_torque(ids, 1)
            self._shutdown[:] = False
        else:
            self._sync_torque(ids, 0)
        self._torque = bool(on)

    # -- set-up -------------------------------------------------------------

    def configure(self, *, from_baud: float | None = None) -> list[str]:
        """The thesis's configuration sequence (§2.3, Fig. 2.22), one logged line per step.

        IDs are already set (the joint map names them). Steps: return delay 0
        (thesis: the minimum), status return level, compliance margins 0 and
        slopes 64, torque limit (``torque_limit`` × max torque), baud. Returns
        the lines, also kept in :attr:`configuration`.
        """
        steps: list[tuple[str, int, str]] = [
            ("return_delay_time", 0, "return delay 0 µs"),
            ("status_return_level", self.status_return_level_setting,
             f"status return level {self.status_return_level_setting}"),
            ("cw_compliance_margin", THESIS_COMPLIANCE_MARGIN, "CW compliance margin 0"),
            ("ccw_compliance_margin", THESIS_COMPLIANCE_MARGIN, "CCW compliance margin 0"),
            ("cw_compliance_slope", THESIS_COMPLIANCE_SLOPE, "CW compliance slope 64"),
            ("ccw_compliance_slope", THESIS_COMPLIANCE_SLOPE, "CCW compliance slope 64"),
            ("torque_limit", self._torque_limit_raw, f"torque limit {self.torque_limit:.0%}"),
        ]
        lines = []
        for j in self.map.joints:
            i = j.servo_id
            for name, value, text in steps:
                item = self.table.item(name)
                if item.area == "EEPROM" and self._guard(self.bus.read, i, name) == value:
                    line = f"servo {i} ({j.name}): {text} (already set)"
                else:
                    self._write_setting(i, name, value)
                    line = f"servo {i} ({j.name}): {text}"
                log.info(line)
                lines.append(line)
        self._switch_baud(from_baud, lines)
        self.configuration = lines
        return lines

    def _limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits: the map's, narrowed to each servo's CW..CCW angle limits (both in
        one READ a servo: :meth:`~armlab.hardware.wire.bus.Bus.read_items`)."""
        limits = [self.bus.read_items(i, ("cw_angle_limit", "ccw_angle_limit"))
                  for i in self.map.ids]
        cw = [x["cw_angle_limit"] for x in limits]
        ccw = [x["ccw_angle_limit"] for x in limits]
        for j, a, b in zip(self.map.joints, cw, ccw, strict=True):
            if a == 0 and b == 0:
                raise BackendError(
                    f"servo {j.servo_id} ({j.name}) is in wheel mode (CW and CCW angle "
                    "limits 0): set its angle limits before using it as a joint")
        self._cw, self._ccw = [int(x) for x in cw], [int(x) for x in ccw]
        return self._narrowed(self._cw, self._ccw)
