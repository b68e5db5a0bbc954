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

import numpy as np

from armlab.control.backend import BackendError, JointState
from armlab.hardware.backends.servo_bus import ServoBusBackend
from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.table import (
    THESIS_COMPLIANCE_MARGIN,
    THESIS_COMPLIANCE_SLOPE,
)
from armlab.hardware.servos.servo_spec import value_from_baud
from armlab.hardware.wire.named_items import sync_data

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
        # goal_position followed by moving_speed: one 4-byte write
        self._goal_at = item("goal_position").address
        self._goal_len = item("goal_position").size + item("moving_speed").size
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
        return self._joint_state(
            pos, vel, load, errors, [p1.error_names(e) for e in errors],
            torque_on=tuple(bool(self._torque and not sd) for sd in self._shutdown))

    def _goal_bytes(self, goal: int, speed: int) -> bytes:
        """Goal Position and Moving Speed as the SYNC_WRITE's 2 + 2 bytes."""
        return sync_data({0: (goal, speed)}, (2, 2))[0]

    def goal_words(self, position: np.ndarray, speed: np.ndarray) -> tuple[list[int], list[int]]:
        """Raw goal positions and moving speeds for joint goals: clamped into
        [lower, upper], then into each servo's CW..CCW limits (never outside)."""
        goals = self._goal_positions(position)
        return goals, [self.spec.speed_to_raw(abs(x)) for x in speed]

    def _before_torque_on(self) -> None:
        """The torque limit written again: an overload shutdown zeroed it, and restoring it
        is the recovery."""
        limit = p1.word(self._torque_limit_raw)
        self._guard(self.bus.sync_write, self._torque_limit.address, self._torque_limit.size,
                    {i: limit for i in self.map.ids})

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
                line = self._setting(i, j.name, name, value, text)
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
