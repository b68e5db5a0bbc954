"""Emulated Feetech STS servos behind the same pseudo-terminal as the Dynamixel ones
(:class:`armlab.hardware.emulator.pty.PtyEmulator` serves any family's network).

Each :class:`StsVirtualServo` keeps its 71-byte control-table image
(:mod:`armlab.hardware.families.feetech.table`) and answers the instructions of
:mod:`armlab.hardware.families.feetech.packets`: PING, READ, WRITE, REG_WRITE/ACTION, SYNC_WRITE,
SYNC_READ (each named servo answers in turn) and RESET; Response Status Level (address 8:
0 = PING and READ only, 1 = everything); silence at a baud that is not the servo's. The
servos move because :class:`StsPlantPhysics` hands their registers to the simulated STS
firmware (:class:`armlab.hardware.families.feetech.firmware.StsServoModel`) of the same plant the
simulator uses; its report comes back into the table, its error bits into every status
packet. The SO-101's gripper servo (ID 6) moves the jaw's load.

*Interpretations* (Feetech's documents are silent, and an STS status packet has no bit
for a refused write): a write to a read-only item or to a reserved byte is ignored; a
write to the EEPROM area (addresses below 40) is ignored while Lock (55) is 1, as
LeRobot unlocks before writing EEPROM; a value outside an item's range is ignored; a
READ past the table's end answers zeros there; a packet whose checksum fails gets no
answer.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import ClassVar

from armlab.hardware.backends.gripper import GripperServo, gripper_plant
from armlab.hardware.backends.joint_map import ROBOT_SUPPLY, JointMap
from armlab.hardware.emulator.network import ServoBus, TableImage
from armlab.hardware.emulator.physics import ArmPhysics
from armlab.hardware.families.feetech import packets as ft
from armlab.hardware.families.feetech.firmware import StsRegisters, StsServoModel
from armlab.hardware.families.feetech.packets import Instruction as I
from armlab.hardware.families.feetech.table import TABLE_SIZE, StsControlTable, sts_table_for
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.model import Quadruped, SerialChain

#: The firmware version the emulated servos report (major.minor at addresses 0, 1).
EMULATED_FIRMWARE = (3 << 8) | 10
EEPROM_END = 40  #: first RAM address
LOCK_ADDRESS = 55
#: The register fields the firmware model acts on (each one an item of the table).
_REGISTERS = tuple(f.name for f in fields(StsRegisters))


@dataclass
class StsVirtualServo(TableImage):
    """One emulated STS servo: its table image (``table`` an
    :class:`~armlab.hardware.families.feetech.table.StsControlTable`) and its firmware's error bits.

    Attributes:
        model_error: the status error bits the simulated firmware reports.
        silent: the servo answers nothing (``armlab emulate --fault JOINT:silent@S``).
    """

    model_error: int = 0
    silent: bool = False
    FIRMWARE: ClassVar[int] = EMULATED_FIRMWARE

    def hears(self, baud: float | None) -> bool:
        """Whether the servo hears bytes at ``baud``: never once it went silent (an
        injected fault: a cut cable)."""
        return not self.silent and super().hears(baud)

    @property
    def sts(self) -> StsControlTable:
        return self.table  # type: ignore[return-value]  # an STS servo's table is an StsControlTable

    def put(self, name: str, value: int) -> None:
        """Set an item from the servo's side (present values), sign-magnitude encoded."""
        self.sts.put(self.memory, name, value)

    def answers(self, instruction: int) -> bool:
        """Response Status Level (address 8): 0 = PING and READ only, 1 = everything."""
        if instruction in (I.PING, I.READ, I.SYNC_READ):
            return True
        return self.get("status_return_level") >= 1

    def read(self, address: int, length: int) -> bytes:
        """READ: the bytes from ``address``; zeros past the table's end."""
        data = bytes(self.memory[address : address + length])
        return data + bytes(length - len(data))

    def write(self, address: int, data: bytes) -> None:
        """WRITE: store ``data`` item by item (see the module's interpretations)."""
        image = bytearray(self.memory)
        end = min(address + len(data), TABLE_SIZE)
        image[address:end] = data[: max(0, end - address)]
        locked = self.memory[LOCK_ADDRESS] == 1
        for item in self.table.items:
            if item.address + item.size <= address or item.address >= end:
                continue
            if not item.writable or (locked and item.address < EEPROM_END):
                continue
            if item.address < address or item.address + item.size > end:
                continue  # part of an item
            value = self.table.value_at(image, item.name)
            if item.lo <= value <= item.hi:
                self.memory[item.address : item.address + item.size] = \
                    image[item.address : item.address + item.size]



class StsPlantPhysics(ArmPhysics):
    """Emulated STS servos moved by the simulated plant (:class:`~armlab.hardware.emulator.
    bus.ArmPhysics`: the arm's, the gripper's): each servo's registers go into its
    :class:`~armlab.hardware.families.feetech.firmware.StsServoModel`, its report comes back."""

    def _model(self, s: StsVirtualServo) -> StsServoModel:  # type: ignore[override]  # an STS network's servos are StsVirtualServos
        return super()._model(s)

    def apply(self, s: StsVirtualServo) -> None:
        regs = self._model(s).regs
        for name in _REGISTERS:
            setattr(regs, name, s.get(name))

    def report(self, s: StsVirtualServo) -> None:
        r = self._model(s).report()
        s.put("present_position", r.position)
        s.put("present_speed", r.speed)
        s.put("present_load", max(-1000, min(1000, r.load)))
        s.put("present_current", r.current)
        s.put("present_voltage", r.voltage)
        s.put("present_temperature", r.temperature)
        s.put("moving", r.moving)
        s.put("torque_enable", r.torque_enable)
        s.model_error = r.error
        s.silent = self._model(s).silent


@dataclass
class StsServoNetwork(ServoBus):
    """STS servos (:class:`StsVirtualServo`) on one bus and how they answer Feetech
    instruction packets (what :class:`armlab.hardware.emulator.pty.PtyEmulator` serves)."""

    servos: list[StsVirtualServo]
    physics: StsPlantPhysics
    protocol = "sts"

    def handle(self, packet: ft.InstructionPacket, *, baud: float | None = None
               ) -> list[tuple[StsVirtualServo, bytes]]:
        """Execute one instruction packet heard at ``baud``; return (servo, status packet)
        pairs in the order they go on the wire."""
        listeners = [s for s in self.servos if s.hears(baud)]
        inst, params = packet.instruction, packet.params
        if inst == I.SYNC_WRITE:
            self._sync_write(listeners, params)
            return []
        if inst == I.SYNC_READ:
            return self._sync_read(listeners, params)
        broadcast = packet.servo_id == ft.BROADCAST_ID
        replies = []
        for s in [s for s in listeners if broadcast or s.servo_id == packet.servo_id]:
            servo_id = s.servo_id  # a reply carries the ID the servo had
            data = self._execute(s, inst, params)
            if data is not None and not broadcast and s.answers(inst):
                replies.append((s, ft.status(servo_id, s.model_error, data)))
        return replies

    def _execute(self, s: StsVirtualServo, inst: int, params: bytes) -> bytes | None:
        """Carry out one instruction; its status data (None: an instruction the servo
        ignores, or malformed parameters: no answer)."""
        if inst == I.PING:
            return b""
        if inst == I.READ:
            return s.read(params[0], params[1]) if len(params) == 2 else None
        if inst in (I.WRITE, I.REG_WRITE):
            if len(params) < 2:
                return None
            if inst == I.REG_WRITE:
                s.pending = (params[0], bytes(params[1:]))
                return b""
            s.write(params[0], bytes(params[1:]))
            self.physics.apply(s)
            return b""
        if inst == I.ACTION:
            if s.pending is not None:
                s.write(*s.pending)
                s.pending = None
                self.physics.apply(s)
            return b""
        if inst == I.RESET:  # the factory table (ID 1, the factory baud), torque off
            s.factory_reset()
            self.physics.apply(s)
            self.physics.report(s)
            return b""
        return None

    def _sync_read(self, listeners: list[StsVirtualServo], params: bytes
                   ) -> list[tuple[StsVirtualServo, bytes]]:
        """SYNC_READ (address, length, IDs): the named servos answer in the order named."""
        if len(params) < 3:
            return []
        address, length = params[0], params[1]
        by_id = {s.servo_id: s for s in listeners}
        return [(by_id[i], ft.status(i, by_id[i].model_error, by_id[i].read(address, length)))
                for i in params[2:] if i in by_id]

    def _sync_write(self, listeners: list[StsVirtualServo], params: bytes) -> None:
        if len(params) >= 2:  # address, length, then the body
            self._write_each(listeners, params[0], params[1], params[2:])

    def checksum_error(self, raw: bytes, *, baud: float | None = None
                       ) -> list[tuple[StsVirtualServo, bytes]]:
        """Nothing: an STS servo does not answer a packet whose checksum fails."""
        return []


def emulated_sts_network(model: SerialChain, ids: Sequence[int], *, servo: str = "STS3215",
                         baud: float = 1_000_000, dt: float = 1e-3,
                         params: ServoParams | None = None,
                         gripper: GripperServo | None = None) -> StsServoNetwork:
    """The STS servos of ``model`` on one bus (``ids`` in joint order), moved by a plant of
    the same chain, as the simulator's; with ``gripper``, its servo too, moving the jaw
    (:func:`armlab.hardware.backends.gripper.gripper_plant`).

    Args:
        model: a serial chain.
        ids: servo IDs in joint order (0..252).
        servo: the STS model of every joint.
        baud: bit/s in every servo's EEPROM (an STS rate).
        dt: plant step, s.
        params: the servos' physical constants and supply (default: the datasheet's).
        gripper: the gripper's servo (the SO-101's ID 6), or None.
    """
    ids = [int(i) for i in ids]
    if len(ids) != model.n:
        raise ValueError(f"ids: {len(ids)} given for the {model.n} joints of {model.name}")
    every = ids + ([gripper.servo_id] if gripper is not None else [])
    if len(set(every)) != len(every) or not all(0 <= i <= ft.MAX_ID for i in every):
        raise ValueError(f"ids: distinct IDs in 0..{ft.MAX_ID}, got {every}")
    table = sts_table_for(servo)
    baud_value = table.from_si("baud_rate", baud)
    plant = Plant(model, table.spec, dt=dt, params=params)
    jaw = None if gripper is None else gripper_plant(gripper, table.spec, dt=dt,
                                                     params=params)
    physics = StsPlantPhysics(plant, gripper=jaw)
    models = [*plant.servos, *(jaw.servos if jaw is not None else ())]
    servos = [StsVirtualServo.new(table, i, j, baud_value=baud_value,
                                  present_position=m.present_position())
              for j, (i, m) in enumerate(zip(every, models, strict=True))]
    for s in servos:
        physics.apply(s)
        physics.report(s)
    return StsServoNetwork(servos, physics)


def sts_network_for_map(model: SerialChain | Quadruped, jmap: JointMap, *,
                        baud: float = 1_000_000, dt: float = 1e-3) -> StsServoNetwork:
    """The STS family's emulator (:mod:`armlab.hardware.families`): the servos of ``jmap``
    (and its gripper's) on ``model``, at the robot's supply (:data:`~armlab.hardware.
    backends.joint_map.ROBOT_SUPPLY`; else the datasheet's)."""
    if not isinstance(model, SerialChain):
        raise ValueError(f"--servo {jmap.servo}: STS servos drive a serial arm here, "
                         f"not the {model.name}")
    supply = ROBOT_SUPPLY.get(model.name)
    return emulated_sts_network(
        model, jmap.ids, servo=jmap.servo, baud=baud, dt=dt,
        params=None if supply is None else ServoParams(voltage=supply), gripper=jmap.gripper)
