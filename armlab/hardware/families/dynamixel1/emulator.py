"""A virtual Dynamixel bus behind a pseudo-terminal: servos a serial client cannot tell apart.

``armlab emulate`` runs this in its own process (an emulator thread inside the
client's process showed ~23 ms latency spikes; docs/serial.md, "Timing").
Each :class:`VirtualServo` keeps a control-table image with EEPROM/RAM
semantics and answers protocol 1.0 as the manual describes: status return
level, return delay, error bits, REG_WRITE/ACTION, SYNC_WRITE, FACTORY_RESET,
and silence when the client's baud (read from the pty master with TCGETS2)
is not the servo's. The servos move because a simulated :class:`Physics`
(the same plant as the SimBackend) turns their RAM registers into motion and
reports present position, speed and load back into the table.

Readings of the manual that are *interpretations* (the manual is silent): a
write to a read-only item, out of an item's range or (locked) outside 24..35
is refused whole with the range bit; writes to reserved bytes are ignored; a
goal outside the CW/CCW limits is stored, answered with the angle-limit bit,
and the servo stops at the limit; overload and its alarm shutdown come from the simulated
firmware (``firmware.py`` in this folder).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields

from armlab.hardware.backends.joint_map import JointMap, default_joint_map
from armlab.hardware.emulator.network import Physics, ServoBus, TableImage
from armlab.hardware.emulator.physics import RestingPose
from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.firmware import ServoRegisters
from armlab.hardware.families.dynamixel1.quadruped import BodyOnLegs
from armlab.hardware.families.dynamixel1.table import (
    LOCKED_WRITABLE,
    RX24F_TABLE,
    TABLE_SIZE,
    table_for,
)
from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import Parser
from armlab.hardware.servos.servo_spec import value_from_baud
from armlab.hardware.sim.plant import Plant
from armlab.kinematics.model import Quadruped, SerialChain

#: (field, address, size) of every :class:`ServoRegisters` field in the control table
#: (both models share one layout), for copying a servo's RAM into its simulated firmware
REGISTER_ADDRESSES = tuple(
    (f.name, RX24F_TABLE.item(f.name).address, RX24F_TABLE.item(f.name).size)
    for f in fields(ServoRegisters)
)


@dataclass
class VirtualServo(TableImage):
    """One emulated protocol-1.0 servo (AX-12A, RX-24F): its table image and what its
    firmware reports.

    Attributes:
        model_error: error bits the simulated firmware reports (overload).
    """

    model_error: int = 0

    def answers(self, instruction: int) -> bool:
        """Status Return Level (address 16): 0 = PING only, 1 = + READ, 2 = all."""
        level = self.memory[16]
        if instruction == p1.Instruction.PING:
            return True
        if instruction == p1.Instruction.READ:
            return level >= 1
        return level >= 2

    def state_errors(self) -> p1.ErrorBits:
        """Error bits that describe the servo's state (sent with every status packet)."""
        bits = p1.ErrorBits(self.model_error & p1.ErrorBits.OVERLOAD)
        volt = self.get("present_voltage")
        if not self.get("min_voltage_limit") <= volt <= self.get("max_voltage_limit"):
            bits |= p1.ErrorBits.INPUT_VOLTAGE
        if self.get("present_temperature") > self.get("temperature_limit"):
            bits |= p1.ErrorBits.OVERHEATING
        cw, ccw, goal = self.get("cw_angle_limit"), self.get("ccw_angle_limit"), \
            self.get("goal_position")
        if not (cw == 0 and ccw == 0) and not cw <= goal <= ccw:
            bits |= p1.ErrorBits.ANGLE_LIMIT
        return bits

    def read(self, address: int, length: int) -> tuple[p1.ErrorBits, bytes]:
        """READ: (error bits, data); the range bit and no data past the table's end."""
        if length == 0 or address + length > TABLE_SIZE:
            return self.state_errors() | p1.ErrorBits.RANGE, b""
        return self.state_errors(), bytes(self.memory[address : address + length])

    def write(self, address: int, data: bytes) -> p1.ErrorBits:
        """WRITE: apply ``data`` at ``address`` if every touched item accepts it.

        Returns the error bits of the reply; a refused write changes nothing.
        Reserved bytes are ignored.
        """
        refused = self.check_write(address, data)
        if refused:
            return self.state_errors() | refused
        for a, b in zip(range(address, address + len(data)), data, strict=True):
            if self.table.at(a) is not None:
                self.memory[a] = b
        return self.state_errors()

    def check_write(self, address: int, data: bytes) -> p1.ErrorBits:
        """RANGE when the write runs past the table, touches a read-only item (or,
        with Lock = 1, anything outside 24..35) or leaves an item out of its range."""
        if not data or address + len(data) > TABLE_SIZE:
            return p1.ErrorBits.RANGE
        locked = self.memory[47] == 1
        image = bytearray(self.memory)
        image[address : address + len(data)] = data
        touched = set()
        for a in range(address, address + len(data)):
            item = self.table.at(a)
            if item is None:
                continue
            if not item.writable or (locked and a not in LOCKED_WRITABLE):
                return p1.ErrorBits.RANGE
            touched.add(item)
        for item in touched:
            if not item.lo <= self.table.value_at(image, item.name) <= item.hi:
                return p1.ErrorBits.RANGE
        return p1.ErrorBits(0)


@dataclass
class ServoNetwork(ServoBus):
    """Protocol-1.0 servos (:class:`VirtualServo`) on one bus and how they answer
    instruction packets."""

    servos: list[VirtualServo]
    physics: Physics[VirtualServo]
    protocol = 1  #: the protocol its servos speak (the X-series' network: 2)

    def parser(self) -> Parser:
        """A parser that keeps packets whose checksum fails (``bad``): its servos answer
        those with the checksum error."""
        return self.codec.PacketParser(collect_bad=True)

    def handle(self, packet: p1.InstructionPacket, *, baud: float | None = None
               ) -> list[tuple[VirtualServo, bytes]]:
        """Execute one instruction packet heard at ``baud``; return (servo, status packet) pairs."""
        listeners = [s for s in self.servos if s.hears(baud)]
        inst = packet.instruction
        if inst == p1.Instruction.SYNC_WRITE:
            self._sync_write(listeners, packet.params)
            return []
        if packet.servo_id == p1.BROADCAST_ID:
            targets = listeners
        else:
            targets = [s for s in listeners if s.servo_id == packet.servo_id]
        replies = []
        for s in targets:
            servo_id = s.servo_id  # a reply carries the ID the packet was sent to
            error, params = self._execute(s, inst, packet.params)
            if packet.servo_id != p1.BROADCAST_ID and s.answers(inst):
                replies.append((s, p1.status(servo_id, error, params)))
        return replies

    def checksum_error(self, raw: bytes, *, baud: float | None = None
                       ) -> list[tuple[VirtualServo, bytes]]:
        """Status packets with the checksum bit for a broken instruction addressed to a servo."""
        if len(raw) < 4 or raw[2] == p1.BROADCAST_ID:
            return []
        return [
            (s, p1.status(s.servo_id, s.state_errors() | p1.ErrorBits.CHECKSUM))
            for s in self.servos
            if s.hears(baud) and s.servo_id == raw[2] and s.answers(p1.Instruction.WRITE)
        ]

    def _execute(self, s: VirtualServo, inst: int, params: bytes) -> tuple[p1.ErrorBits, bytes]:
        I = p1.Instruction
        if inst == I.PING:
            return s.state_errors(), b""
        if inst == I.READ:
            if len(params) != 2:
                return s.state_errors() | p1.ErrorBits.INSTRUCTION, b""
            return s.read(params[0], params[1])
        if inst in (I.WRITE, I.REG_WRITE):
            if len(params) < 2:
                return s.state_errors() | p1.ErrorBits.INSTRUCTION, b""
            if inst == I.REG_WRITE:
                refused = s.check_write(params[0], params[1:])
                if not refused:
                    s.pending = (params[0], bytes(params[1:]))
                    s.put("registered", 1)
                return s.state_errors() | refused, b""
            error = s.write(params[0], params[1:])
            self.physics.apply(s)
            return error, b""
        if inst == I.ACTION:
            if s.pending is None:
                return s.state_errors() | p1.ErrorBits.INSTRUCTION, b""
            error = s.write(*s.pending)
            s.pending = None
            s.put("registered", 0)
            self.physics.apply(s)
            return error, b""
        if inst == I.FACTORY_RESET:
            s.factory_reset()
            self.physics.apply(s)
            self.physics.report(s)
            return s.state_errors(), b""
        return s.state_errors() | p1.ErrorBits.INSTRUCTION, b""

    def _sync_write(self, listeners: list[VirtualServo], params: bytes) -> None:
        if len(params) >= 2:  # address, length, then the body
            self._write_each(listeners, params[0], params[1], params[2:])


def make_servos(tables: Sequence[ControlTable], ids: Sequence[int], *, baud_value: int,
                positions: Sequence[int]) -> list[VirtualServo]:
    """One :class:`VirtualServo` per joint, ``ids[i]`` driving joint ``i``."""
    if len(set(ids)) != len(ids):
        raise ValueError(f"ids: duplicates in {list(ids)}")
    for i in ids:
        if not 0 <= i <= p1.MAX_ID:
            raise ValueError(f"ids: {i} outside 0..{p1.MAX_ID}")
    return [
        VirtualServo.new(t, i, j, baud_value=baud_value, present_position=pos)
        for j, (t, i, pos) in enumerate(zip(tables, ids, positions, strict=True))
    ]


class PlantPhysics(RestingPose):
    """Emulated servos moved by simulated plants (``armlab.hardware.sim.plant.Plant``).

    One plant per serial chain: the arm, or each leg of the quadruped (its hip
    mount held fixed). ``slots[k]`` = (plant index, joint index) of the servo
    whose :attr:`VirtualServo.joint` is ``k``. The servo's RAM registers go into
    the simulated firmware's :class:`~armlab.hardware.families.dynamixel1.firmware.ServoRegisters`;
    present values, the torque registers (an alarm shutdown clears them) and the
    overload bit come back from its report.
    """

    def __init__(self, plants: Sequence[Plant], slots: Sequence[tuple[int, int]], *,
                 load: Callable[[float], None] | None = None):
        self.plants = list(plants)
        self.slots = list(slots)
        self.load = load  #: puts outside loads on the plants up to t (the quadruped's body)
        self._resting = {}

    def advance_to(self, t: float) -> None:
        """Step the plants up to ``t`` s (to within half a step, as
        :meth:`~armlab.hardware.sim.plant.Plant.advance_to`). With a load, step by step,
        each step carrying the load put on for exactly that step: the bus ticks at every
        packet, and a load put on up to each tick's ``t`` would add a copy of the body's
        weight per packet to the step not yet taken (plant pushes add up)."""
        if self.load is None:
            for plant in self.plants:
                plant.advance_to(t)
        else:
            lead = self.plants[0]
            while lead.t + 0.5 * lead.dt <= t:
                now = lead.t + lead.dt
                self.load(now)
                for plant in self.plants:
                    plant.advance_to(now)
        self._settle_resting()

    def _locate(self, joint: int) -> tuple[Plant, int]:
        if not 0 <= joint < len(self.slots):
            raise ValueError(f"no joint {joint} on this robot")
        p, j = self.slots[joint]
        return self.plants[p], j

    def _servo(self, s: VirtualServo):
        p, j = self.slots[s.joint]
        return self.plants[p], j

    def apply(self, s: VirtualServo) -> None:
        plant, j = self._servo(s)
        regs = plant.servos[j].regs
        mem = s.memory
        for name, address, size in REGISTER_ADDRESSES:
            value = mem[address] if size == 1 else mem[address] | (mem[address + 1] << 8)
            setattr(regs, name, value)

    def report(self, s: VirtualServo) -> None:
        plant, j = self._servo(s)
        r = plant.servos[j].report()
        mem = s.memory
        mem[36], mem[37] = r.position & 0xFF, r.position >> 8
        mem[38], mem[39] = r.speed & 0xFF, r.speed >> 8
        mem[40], mem[41] = r.load & 0xFF, r.load >> 8
        mem[42], mem[43] = r.voltage, r.temperature
        mem[46] = r.moving
        mem[24] = r.torque_enable
        mem[34], mem[35] = r.torque_limit & 0xFF, r.torque_limit >> 8
        s.model_error = r.error


def emulated_network(model: SerialChain | Quadruped, *, ids: Sequence[int] | None = None,
                     servo: str | None = None, baud: float = 1_000_000, dt: float = 1e-3
                     ) -> ServoNetwork:
    """The servos of ``model`` on one bus, moved by the same plant as the SimBackend.

    Args:
        model: a serial chain (one plant) or the quadruped (one plant per leg, 12 servos).
        ids: servo IDs in joint order (default: thesis IDs 1, 3, 5 for the
            receptionist arm, else 1..n).
        servo: "RX-24F" or "AX-12A" (default: RX-24F for the thesis arm, AX-12A otherwise).
        baud: bit/s in every servo's EEPROM.
        dt: plant step, s.
    """
    jmap = default_joint_map(model, servo=servo, ids=tuple(ids) if ids is not None else None)
    table = table_for(jmap.servo)
    chains = list(model.legs.values()) if isinstance(model, Quadruped) else [model]
    plants, slots = [], []
    for c, chain in enumerate(chains):
        plants.append(Plant(chain, table.spec, dt=dt))
        slots += [(c, j) for j in range(chain.n)]
    positions = [plants[p].servos[j].present_position() for p, j in slots]
    servos = make_servos([table] * len(slots), jmap.ids, baud_value=value_from_baud(baud),
                         positions=positions)
    load = None
    if isinstance(model, Quadruped):  # the legs carry the body, as in QuadrupedSimBackend
        load = BodyOnLegs(model, plants).load
    physics = PlantPhysics(plants, slots, load=load)
    for s in servos:
        physics.apply(s)
        physics.report(s)
    return ServoNetwork(servos, physics)


def network_for_map(model: SerialChain | Quadruped, jmap: JointMap, *, baud: float = 1_000_000,
                    dt: float = 1e-3) -> ServoNetwork:
    """The protocol-1.0 family's emulator (:mod:`armlab.hardware.families`): the servos of
    ``jmap`` on ``model``, as :func:`emulated_network`; ValueError for a baud no servo
    of the family can take."""
    value_from_baud(baud)
    return emulated_network(model, ids=jmap.ids, servo=jmap.servo, baud=baud, dt=dt)
