"""Emulated X-series servos speaking protocol 2.0, behind the same pseudo-terminal as the
protocol-1.0 ones (:class:`armlab.hardware.emulator.pty.PtyEmulator` serves either network).

Each :class:`XVirtualServo` keeps its 147-byte control-table image and answers as the
e-manual's "Protocol 2.0" page describes: PING (a broadcast PING is answered by every
servo, in ID order), READ, WRITE, REG_WRITE/ACTION, REBOOT, FACTORY_RESET, SYNC_READ,
SYNC_WRITE and BULK_READ; Status Return Level (0: PING only, 1: + reads, 2: all); the
error numbers (Access for a read-only item, an EEPROM item while torque is on, or an
address past the table; Data Length, Data Range; Instruction for an ACTION with nothing
registered); the alert bit while Hardware Error Status is set; silence at a baud that
is not the servo's. The servos move because :class:`XPlantPhysics` hands their RAM to
the simulated X-series firmware (:class:`armlab.hardware.families.xseries.firmware.XServoModel`) of
the same plant the simulator uses; an arm's gripper servo (the OpenManipulator-X's ID 15) moves
the fingers' load of :func:`armlab.hardware.backends.gripper.gripper_plant`.

*Interpretation* (the e-manual says a goal "should be configured within" its limit):
a Goal Position outside the Min/Max Position Limit (in Position Control), a Goal
Current above Current Limit, a Goal PWM above PWM Limit or a Goal Velocity above
Velocity Limit is refused whole with the Data Limit error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

from armlab.hardware.backends.gripper import GripperServo, gripper_plant
from armlab.hardware.backends.joint_map import JointMap
from armlab.hardware.emulator.network import ServoBus, TableImage
from armlab.hardware.emulator.physics import ArmPhysics
from armlab.hardware.families.xseries import packets as p2
from armlab.hardware.families.xseries.firmware import XRegisters
from armlab.hardware.families.xseries.packets import ErrorNumber as E
from armlab.hardware.families.xseries.packets import Instruction as I
from armlab.hardware.families.xseries.table import (
    TABLE_SIZE,
    OperatingMode,
    XControlTable,
    x_table_for,
)
from armlab.hardware.sim.plant import Plant
from armlab.kinematics.model import Quadruped, SerialChain

#: The firmware version the emulated servos report (address 6).
EMULATED_FIRMWARE = 46
#: First RAM address: EEPROM is 0..63 (written only while Torque Enable is 0).
RAM_START = 64
#: (goal, its limit): a goal whose magnitude exceeds its limit gets the Data Limit error.
_GOAL_LIMITS = (("goal_current", "current_limit"), ("goal_pwm", "pwm_limit"),
                ("goal_velocity", "velocity_limit"))


@dataclass
class XVirtualServo(TableImage):
    """One emulated X-series servo: its 147-byte table image (``table`` an
    :class:`~armlab.hardware.families.xseries.table.XControlTable`) and its firmware's state.

    Attributes:
        hardware_error: Hardware Error Status the simulated firmware reports.
    """

    hardware_error: int = 0
    FIRMWARE: ClassVar[int] = EMULATED_FIRMWARE
    if TYPE_CHECKING:  # for mypy only: the dataclass's fields stay the base's
        table: XControlTable

    def answers(self, instruction: int) -> bool:
        """Status Return Level (address 68): 0 = PING only, 1 = + READs, 2 = all."""
        level = self.get("status_return_level")
        if instruction == I.PING:
            return True
        if instruction in (I.READ, I.SYNC_READ, I.BULK_READ):
            return level >= 1
        return level >= 2

    def error(self, number: int = 0) -> int:
        """The ERROR byte of a reply: ``number`` and the alert bit while a hardware error
        is set."""
        return number | (p2.ALERT if self.hardware_error else 0)

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """READ: (error number, data); Access past the table's end."""
        if length == 0 or address + length > TABLE_SIZE:
            return E.ACCESS, b""
        return 0, bytes(self.memory[address : address + length])

    def check_write(self, address: int, data: bytes) -> int:
        """The error number refusing ``data`` at ``address`` (0: accepted)."""
        if not data or address + len(data) > TABLE_SIZE:
            return E.ACCESS
        torque_on = self.get("torque_enable") == 1
        image = bytearray(self.memory)
        image[address : address + len(data)] = data
        touched = {}
        for a in range(address, address + len(data)):
            item = self.table.at(a)
            if item is None:
                return E.ACCESS  # an undefined address
            if not item.writable or (torque_on and a < RAM_START):
                return E.ACCESS  # read-only, or EEPROM while the torque is on
            touched[item.name] = item
        for item in touched.values():
            if item.address < address or item.address + item.size > address + len(data):
                return E.DATA_LENGTH  # part of an item
            if not item.lo <= self.table.value_at(image, item.name) <= item.hi:
                return E.DATA_RANGE
        return self._limit_error(image, touched)

    def _limit_error(self, image: bytearray, touched: dict) -> int:
        value = lambda name: self.table.value_at(image, name)  # noqa: E731
        if "goal_position" in touched and \
                value("operating_mode") == OperatingMode.POSITION and \
                not value("min_position_limit") <= value("goal_position") <= \
                value("max_position_limit"):
            return E.DATA_LIMIT
        for goal, limit in _GOAL_LIMITS:
            if goal in touched and abs(value(goal)) > value(limit):
                return E.DATA_LIMIT
        if "operating_mode" in touched:
            try:
                self.table.check_operating_mode(value("operating_mode"))
            except ValueError:
                return E.DATA_RANGE
        return 0

    def write(self, address: int, data: bytes) -> int:
        """WRITE: apply ``data`` if every touched item accepts it; the error number."""
        refused = self.check_write(address, data)
        if not refused:
            self.memory[address : address + len(data)] = data
        return refused

    def reboot(self) -> None:
        """REBOOT: the RAM back to its power-on values (torque off), the error cleared."""
        present = self.get("present_position")
        fresh = self.table.defaults(firmware=EMULATED_FIRMWARE, servo_id=self.servo_id,
                                    present_position=present, baud_value=self.get("baud_rate"))
        self.memory[RAM_START:] = fresh[RAM_START:]
        self.pending = None
        self.hardware_error = 0

    def factory_reset(self, level: int) -> None:  # type: ignore[override]  # 2.0's reset takes a level (1.0's none)
        """FACTORY_RESET at ``level`` (0xFF everything, 0x01 keep the ID, 0x02 keep the ID
        and the baud rate)."""
        keep_id = self.servo_id if level in (p2.ResetLevel.KEEP_ID,
                                             p2.ResetLevel.KEEP_ID_AND_BAUD) else 1
        keep_baud = self.get("baud_rate") if level == p2.ResetLevel.KEEP_ID_AND_BAUD else None
        present = self.get("present_position")
        self.memory[:] = self.table.defaults(firmware=EMULATED_FIRMWARE, servo_id=keep_id,
                                             present_position=present, baud_value=keep_baud)
        self.pending = None


class XPlantPhysics(ArmPhysics):
    """Emulated X-series servos moved by the simulated plant (:class:`~armlab.hardware.
    emulator.physics.ArmPhysics`: the arm's, the gripper's): each servo's RAM goes into its
    :class:`~armlab.hardware.families.xseries.firmware.XServoModel`'s registers, its report comes
    back.

    Args:
        plant: one plant of X-series servos (one servo per joint).
        gripper: the gripper's plant, or None.
    """

    def __init__(self, plant: Plant, *, gripper: Plant | None = None) -> None:
        super().__init__(plant, gripper=gripper)
        #: the registers the firmware acts on that the control table holds
        self._names = [f.name for f in fields(XRegisters)
                       if plant.servos and _has(plant.servos[0].spec.name, f.name)]

    def apply(self, s: XVirtualServo) -> None:
        regs = self._model(s).regs
        for name in self._names:
            setattr(regs, name, s.get(name))

    def report(self, s: XVirtualServo) -> None:
        model = self._model(s)
        r = model.report()
        s.put("present_position", r.position)
        s.put("present_velocity", r.velocity)
        s.put("present_pwm", r.pwm)
        s.put("present_current" if s.table.spec.has_current else "present_load", r.current)
        s.put("moving", r.moving)
        s.put("present_input_voltage", r.voltage)
        s.put("present_temperature", r.temperature)
        s.put("torque_enable", r.torque_enable)
        s.put("hardware_error_status", r.hardware_error)
        s.hardware_error = r.hardware_error

    def reboot(self, s: XVirtualServo) -> None:
        self._model(s).reboot()


@dataclass
class XServoNetwork(ServoBus):
    """X-series servos (:class:`XVirtualServo`) on one bus and how they answer protocol-2.0
    instruction packets (the interface :class:`armlab.hardware.emulator.pty.PtyEmulator` serves)."""

    servos: list[XVirtualServo]
    physics: XPlantPhysics
    protocol = 2

    def handle(self, packet: p2.InstructionPacket, *, baud: float | None = None
               ) -> list[tuple[XVirtualServo, bytes]]:
        """Execute one instruction packet heard at ``baud``; return (servo, status packet)
        pairs in the order they go on the wire."""
        listeners = [s for s in self.servos if s.hears(baud)]
        inst, params = packet.instruction, packet.params
        if inst == I.SYNC_WRITE:
            self._sync_write(listeners, params)
            return []
        if inst in (I.SYNC_READ, I.BULK_READ):
            return self._group_read(listeners, inst, params)
        broadcast = packet.servo_id == p2.BROADCAST_ID
        targets = [s for s in listeners if broadcast or s.servo_id == packet.servo_id]
        replies = []
        for s in sorted(targets, key=lambda s: s.servo_id) if broadcast else targets:
            servo_id = s.servo_id  # a reply carries the ID the servo had
            number, data = self._execute(s, inst, params)
            if (not broadcast or inst == I.PING) and s.answers(inst):
                replies.append((s, p2.status(servo_id, s.error(number), data)))
        return replies

    def _execute(self, s: XVirtualServo, inst: int, params: bytes) -> tuple[int, bytes]:
        if inst == I.PING:
            return 0, s.get("model_number").to_bytes(2, "little") + bytes(
                (s.get("firmware_version"),))
        if inst == I.READ:
            if len(params) != 4:
                return E.DATA_LENGTH, b""
            return s.read(_u16(params, 0), _u16(params, 2))
        if inst in (I.WRITE, I.REG_WRITE):
            if len(params) < 3:
                return E.DATA_LENGTH, b""
            address, data = _u16(params, 0), bytes(params[2:])
            if inst == I.REG_WRITE:
                refused = s.check_write(address, data)
                if not refused:
                    s.pending = (address, data)
                    s.put("registered_instruction", 1)
                return refused, b""
            refused = s.write(address, data)
            self.physics.apply(s)
            return refused, b""
        if inst == I.ACTION:
            if s.pending is None:
                return E.INSTRUCTION, b""
            refused = s.write(*s.pending)
            s.pending = None
            s.put("registered_instruction", 0)
            self.physics.apply(s)
            return refused, b""
        if inst == I.REBOOT:
            s.reboot()
            self.physics.reboot(s)
            self.physics.apply(s)
            return 0, b""
        if inst == I.FACTORY_RESET:
            if len(params) != 1 or params[0] not in tuple(p2.ResetLevel):
                return E.DATA_RANGE, b""
            if s.get("torque_enable"):
                return E.ACCESS, b""  # EEPROM: torque must be off
            s.factory_reset(params[0])
            self.physics.apply(s)
            return 0, b""
        return E.INSTRUCTION, b""

    def _group_read(self, listeners: list[XVirtualServo], inst: int, params: bytes
                    ) -> list[tuple[XVirtualServo, bytes]]:
        """SYNC_READ (address, length, IDs) or BULK_READ ((ID, address, length) each): the
        servos answer in the order they are named."""
        if inst == I.SYNC_READ:
            if len(params) < 5:
                return []
            address, length = _u16(params, 0), _u16(params, 2)
            asks = [(i, address, length) for i in params[4:]]
        else:
            if len(params) % 5 or not params:
                return []
            asks = [(params[k], _u16(params, k + 1), _u16(params, k + 3))
                    for k in range(0, len(params), 5)]
        by_id = {s.servo_id: s for s in listeners}
        replies = []
        for servo_id, address, length in asks:
            s = by_id.get(servo_id)
            if s is None or not s.answers(inst):
                continue
            number, data = s.read(address, length)
            replies.append((s, p2.status(servo_id, s.error(number), data)))
        return replies

    def _sync_write(self, listeners: list[XVirtualServo], params: bytes) -> None:
        if len(params) >= 4:  # address and length, two bytes each, then the body
            self._write_each(listeners, _u16(params, 0), _u16(params, 2), params[4:])

    def checksum_error(self, raw: bytes, *, baud: float | None = None
                       ) -> list[tuple[XVirtualServo, bytes]]:
        """Nothing: a protocol-2.0 packet whose CRC fails is not recognised as one (the
        client's timeout and retry take care of it)."""
        return []


def _has(model: str, name: str) -> bool:
    """Whether the X-series ``model``'s control table has an item ``name``."""
    return any(item.name == name for item in x_table_for(model).items)


def _u16(data: bytes, at: int) -> int:
    return data[at] | data[at + 1] << 8


def emulated_x_network(model: SerialChain, ids: Sequence[int], *, servo: str = "XM430-W350",
                       baud: float = 1_000_000, dt: float = 1e-3,
                       gripper: GripperServo | None = None) -> XServoNetwork:
    """The X-series servos of ``model`` on one bus (``ids`` in joint order), moved by a
    plant of the same chain, as the simulator's; with ``gripper``, its servo too, moving
    the fingers (:func:`armlab.hardware.backends.gripper.gripper_plant`).

    Args:
        model: a serial chain.
        ids: servo IDs in joint order.
        servo: the X-series model of every joint ("XM430-W350", "XL430-W250", "XL330-M288").
        baud: bit/s in every servo's EEPROM (one of the X-series rates).
        dt: plant step, s.
        gripper: the gripper's servo (its ID after the joints'), or None.
    """
    ids = [int(i) for i in ids]
    if len(ids) != model.n:
        raise ValueError(f"ids: {len(ids)} given for the {model.n} joints of {model.name}")
    every = ids + ([gripper.servo_id] if gripper is not None else [])
    if len(set(every)) != len(every) or not all(0 <= i <= p2.MAX_ID for i in every):
        raise ValueError(f"ids: distinct IDs in 0..{p2.MAX_ID}, got {every}")
    table = x_table_for(servo)
    baud_value = table.from_si("baud_rate", baud)
    plant = Plant(model, table.spec, dt=dt)
    fingers = None if gripper is None else gripper_plant(gripper, table.spec, dt=dt)
    physics = XPlantPhysics(plant, gripper=fingers)
    models = [*plant.servos, *(fingers.servos if fingers is not None else ())]
    servos = [XVirtualServo.new(table, i, j, baud_value=baud_value,
                                present_position=m.report().position)
              for j, (i, m) in enumerate(zip(every, models, strict=True))]
    for s in servos:
        physics.apply(s)
        physics.report(s)
    return XServoNetwork(servos, physics)


def x_network_for_map(model: SerialChain | Quadruped, jmap: JointMap, *,
                      baud: float = 1_000_000, dt: float = 1e-3) -> XServoNetwork:
    """The X-series family's emulator (:mod:`armlab.hardware.families`): the servos of
    ``jmap`` (and its gripper's) on ``model``, as :func:`emulated_x_network`."""
    if not isinstance(model, SerialChain):
        raise ValueError(f"--servo {jmap.servo}: X-series servos drive a serial arm here, "
                         f"not the {model.name}")
    return emulated_x_network(model, jmap.ids, servo=jmap.servo, baud=baud, dt=dt,
                              gripper=jmap.gripper)
