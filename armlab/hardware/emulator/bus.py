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
and the servo stops at the limit (``armlab.hardware.sim.dynamixel_servo``); overload and its alarm
shutdown come from the simulated firmware (``armlab.hardware.sim.dynamixel_servo``).
"""

from __future__ import annotations

import fcntl
import math
import os
import random
import select
import struct
import time
import tty
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, Self, TextIO

from armlab.hardware.backends.joint_map import JointMap, default_joint_map
from armlab.hardware.families import family
from armlab.hardware.servos.control_table import (
    LOCKED_WRITABLE,
    RX24F_TABLE,
    TABLE_SIZE,
    ControlTable,
    table_for,
)
from armlab.hardware.servos.servo_spec import RETURN_DELAY_UNIT, value_from_baud
from armlab.hardware.sim.dynamixel_servo import ServoRegisters
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.quadruped import BodyOnLegs
from armlab.hardware.wire import protocol1 as p1
from armlab.hardware.wire import protocol2 as p2
from armlab.kinematics.model import Quadruped, SerialChain
from armlab.kinematics.validate import scalar

TCGETS2 = 0x802C542A  #: _IOR('T', 0x2A, struct termios2) on Linux
EMULATED_FIRMWARE = 24
PACKET_GAP = 0.1  #: s: a longer pause between bytes drops a partial packet
BAUD_TOLERANCE = 0.03  #: a UART still decodes bytes within about 3 % of its rate
#: s of plant time integrated at most before answering; when the CPU cannot keep the
#: plant in real time, its clock slips instead of the replies coming late
MAX_CATCH_UP = 0.1
#: (field, address, size) of every :class:`ServoRegisters` field in the control table
#: (both models share one layout), for copying a servo's RAM into its simulated firmware
REGISTER_ADDRESSES = tuple(
    (f.name, RX24F_TABLE.item(f.name).address, RX24F_TABLE.item(f.name).size)
    for f in fields(ServoRegisters)
)


def line_baud(master_fd: int) -> float | None:
    """The baud rate the client set on the pty's slave side (TCGETS2 on the master)."""
    buf = bytearray(44)
    try:
        fcntl.ioctl(master_fd, TCGETS2, buf)
    except OSError:
        return None
    return float(struct.unpack_from("2I", buf, 36)[1])  # c_ospeed


@dataclass
class TableImage:
    """What every emulated servo keeps, whatever its protocol: its model's control table
    and the table's image.

    Attributes:
        table: the model's control table.
        memory: the table image (50 bytes on the AX-12A and RX-24F, 147 on the X-series).
        joint: index of the simulated servo this one is (see the network's physics).
        pending: a REG_WRITE waiting for ACTION (address, data).
    """

    table: ControlTable
    memory: bytearray
    joint: int
    pending: tuple[int, bytes] | None = None

    #: the firmware version the emulated servos report
    FIRMWARE: ClassVar[int] = EMULATED_FIRMWARE

    @classmethod
    def new(cls, table: ControlTable, servo_id: int, joint: int, *, baud_value: int,
            present_position: int) -> Self:
        """A servo fresh from power-on with ID ``servo_id`` at EEPROM baud value ``baud_value``."""
        mem = table.defaults(firmware=cls.FIRMWARE, servo_id=servo_id,
                             present_position=present_position, baud_value=baud_value)
        return cls(table, mem, joint)

    def get(self, name: str) -> int:
        return self.table.value_at(self.memory, name)

    def put(self, name: str, value: int) -> None:
        """Set an item from the servo's side (present values, shutdown), bypassing access."""
        item = self.table.item(name)
        self.memory[item.address : item.address + item.size] = int(value).to_bytes(
            item.size, "little", signed=item.signed)

    @property
    def servo_id(self) -> int:
        return self.get("id")

    @property
    def baud(self) -> float:
        return self.table.to_si("baud_rate", self.get("baud_rate"))

    @property
    def return_delay(self) -> float:
        """s before the status packet (2 µs a unit, thesis §2.3)."""
        return RETURN_DELAY_UNIT * self.get("return_delay_time")

    def hears(self, baud: float | None) -> bool:
        """Whether bytes at ``baud`` reach this servo's UART intact (None: unknown, yes)."""
        return baud is None or abs(baud - self.baud) <= BAUD_TOLERANCE * self.baud

    def factory_reset(self) -> None:
        """FACTORY_RESET (protocol 1.0; Feetech's RESET): everything back to the factory's
        (ID 1, the model's default baud), the horn where it is."""
        present = self.get("present_position")
        self.memory[:] = self.table.defaults(firmware=self.FIRMWARE, servo_id=1,
                                             present_position=present)
        self.pending = None


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



class Physics(Protocol):
    """What moves emulated servos: the simulated plant behind their registers."""

    def advance_to(self, t: float) -> None:
        """Integrate the plant up to ``t`` s since the emulator started."""
        ...

    def apply(self, servo: VirtualServo) -> None:
        """Copy the servo's RAM registers (torque enable, compliance, goal, speed,
        torque limit, punch) into its simulated servo."""
        ...

    def report(self, servo: VirtualServo) -> None:
        """Write present position, speed, load, voltage, temperature and moving
        into the servo's table, as its firmware would."""
        ...


@dataclass
class ServoBus:
    """Emulated servos on one bus and the simulated plant that moves them. A protocol's
    network (:class:`ServoNetwork`, :class:`armlab.hardware.emulator.xseries.XServoNetwork`) adds
    ``protocol`` and how its servos answer instruction packets (``handle``,
    ``checksum_error``): what :class:`PtyEmulator` serves.

    Attributes:
        servos: the emulated servos (IDs may change by WRITE or FACTORY_RESET).
        physics: the plant that moves them.
        t: s of plant time reached.
    """

    servos: list[Any]
    physics: Any
    t: float = 0.0

    if TYPE_CHECKING:  # what each protocol's network (a subclass) defines, for mypy only
        protocol: ClassVar[int | str]

        def handle(self, packet: Any, *, baud: float | None = None
                   ) -> list[tuple[Any, bytes]]: ...

        def checksum_error(self, raw: bytes, *, baud: float | None = None
                           ) -> list[tuple[Any, bytes]]: ...

    def tick(self, t: float) -> None:
        """Advance the plant to ``t`` s and refresh every servo's present values."""
        self.t = t
        self.physics.advance_to(t)
        for s in self.servos:
            self.physics.report(s)

    def _write_each(self, listeners: Sequence[TableImage], address: int, length: int,
                    body: bytes) -> None:
        """A SYNC_WRITE's body, (ID, ``length`` bytes) per servo: each listening servo
        named writes its bytes at ``address`` (as its WRITE would, refused or not) and its
        simulated firmware gets them; a body of another length is ignored whole."""
        if length == 0 or len(body) % (length + 1):
            return
        by_id = {s.servo_id: s for s in listeners}
        for k in range(0, len(body), length + 1):
            s = by_id.get(body[k])
            if s is not None:
                s.write(address, bytes(body[k + 1 : k + 1 + length]))  # type: ignore[attr-defined]  # each family's servo has write
                self.physics.apply(s)


@dataclass
class ServoNetwork(ServoBus):
    """Protocol-1.0 servos (:class:`VirtualServo`) on one bus and how they answer
    instruction packets."""

    servos: list[VirtualServo]
    physics: Physics
    protocol = 1  #: the protocol its servos speak (:mod:`armlab.hardware.emulator.xseries`: 2)

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


@dataclass(frozen=True)
class Faults:
    """Fault injection on replies, each a probability per status packet.

    Attributes:
        drop: the reply is never sent.
        corrupt: one byte of the reply (after the header) is flipped.
        delay: the reply is held back ``delay_time`` s (later than a client's timeout).
        delay_time: s.
        seed: random seed (None: from the OS).
    """

    drop: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0
    delay_time: float = 0.05
    seed: int | None = None

    def __post_init__(self) -> None:
        for name in ("drop", "corrupt", "delay"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name}: a fraction of replies in [0, 1], got {v}")
        scalar("delay_time (s)", self.delay_time, nonnegative=True)


@dataclass
class EmulatorStats:
    """Counters of a running emulator (``slipped``: s the plant clock fell behind the wall
    clock because the CPU could not integrate it in real time)."""

    packets: int = 0
    replies: int = 0
    dropped: int = 0
    corrupted: int = 0
    delayed: int = 0
    wrong_baud: int = 0
    slipped: float = 0.0
    lost_bytes: int = 0


@dataclass
class PtyEmulator:
    """Serves the emulated network of any servo family (:class:`ServoNetwork`, protocol
    1.0; :class:`~armlab.hardware.emulator.xseries.XServoNetwork`, 2.0; the family's
    ``emulator`` in :mod:`armlab.hardware.families`) on a new pseudo-terminal; the
    network's ``protocol`` tag picks the packet codec.

    Args:
        network: the servos.
        pace: hold each reply until the request and reply would have crossed the
            wire at the line's baud (10 bits a byte) plus the return delay.
        faults: fault injection on replies.
        echo: echo every received byte back first (a half-duplex TTL adapter).
        log: text stream for one line per received (``rx``) and sent (``tx``) packet.
        control: (a readable file descriptor, a handler): each line read from it is
            handed to the handler between packets (``armlab emulate --control``).
    """

    network: ServoBus
    pace: bool = False
    faults: Faults = field(default_factory=Faults)
    echo: bool = False
    log: TextIO | None = None
    control: tuple[int, Callable[[str], None]] | None = None
    stats: EmulatorStats = field(default_factory=EmulatorStats)

    def __post_init__(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self._rng = random.Random(self.faults.seed)
        self._p = family(self.network.protocol).codec
        # a frame with a checksum (1.0, STS) keeps broken packets: a servo answers those
        self._parser = (self._p.PacketParser(collect_bad=True) if self._p is not p2
                        else p2.PacketParser())
        self._queue: list[tuple[float, bytes]] = []  # (due time, bytes), sorted
        self._wire_free = 0.0
        self._last_byte = 0.0
        self._t0 = time.monotonic()  # wall time of plant time 0 (moves when the plant slips)
        self._log_t0 = self._t0
        self._control_buf = b""

    def close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def serve(self, stop: Callable[[], bool]) -> None:
        """Answer packets until ``stop()`` returns True (checked at least every 5 ms)."""
        while not stop():
            now = time.monotonic()
            wait = 0.005
            if self._queue:
                wait = min(wait, max(0.0, self._queue[0][0] - now - 2e-4))
            fds = [self._master] + ([self.control[0]] if self.control else [])
            ready, _, _ = select.select(fds, [], [], wait)
            now = time.monotonic()
            if self.control is not None and self.control[0] in ready:
                self._read_control()
            if self._master in ready:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    data = b""
                if data:
                    self._receive(data, now)
            self._tick(now)
            self._flush_due()

    def _read_control(self) -> None:
        """Hand each whole line waiting on the control descriptor to its handler (before
        the packets that came with it: a person's hand moved the arm first)."""
        assert self.control is not None
        fd, handler = self.control
        try:
            self._control_buf += os.read(fd, 4096)
        except BlockingIOError:
            return
        *lines, self._control_buf = self._control_buf.split(b"\n")
        for line in lines:
            if line.strip():
                handler(line.decode(errors="replace").strip())

    def _tick(self, now: float) -> None:
        """Advance the plant to ``now``, at most MAX_CATCH_UP at a time (the rest slips)."""
        t = now - self._t0
        behind = t - self.network.t
        if behind > MAX_CATCH_UP:
            self._t0 += behind - MAX_CATCH_UP
            self.stats.slipped += behind - MAX_CATCH_UP
            t = now - self._t0
        self.network.tick(t)

    def _receive(self, data: bytes, now: float) -> None:
        if self.echo:
            self._write(data)
        if self._parser.pending and now - self._last_byte > PACKET_GAP:
            self._parser.discard()
        self._last_byte = now
        baud = line_baud(self._master)
        wire_baud = baud or 1_000_000.0
        for raw in self._parser.feed(data):
            self.stats.packets += 1
            self._log("rx", raw, now)
            if not any(s.hears(baud) for s in self.network.servos):
                self.stats.wrong_baud += 1
                continue
            try:
                packet = self._p.decode_instruction(raw)
            except (self._p.ProtocolError, p1.ProtocolError):  # a status packet: not ours
                continue
            self._tick(now)
            replies = self.network.handle(packet, baud=baud)
            self._schedule(raw, replies, now, wire_baud)
        bad = getattr(self._parser, "bad", [])  # protocol 1.0: broken checksums
        for raw in bad:
            self._schedule(raw, self.network.checksum_error(raw, baud=baud), now, wire_baud)
        bad.clear()

    def _schedule(self, request: bytes, replies: list,
                  now: float, baud: float) -> None:
        t = now
        if self.pace:
            t = max(self._wire_free, now) + p1.wire_time(len(request), baud)
            self._wire_free = t
        for servo, reply in replies:
            due = t + servo.return_delay
            if self.pace:
                due = max(due, self._wire_free) + p1.wire_time(len(reply), baud)
                self._wire_free = due
            t = due  # the next servo answers after this one (a protocol-2.0 group read)
            reply = self._inject(reply)
            if reply is None:
                continue
            if self.faults.delay and self._rng.random() < self.faults.delay:
                self.stats.delayed += 1
                due += self.faults.delay_time
            self._queue.append((due, reply))
        self._queue.sort(key=lambda x: x[0])
        self._flush_due()

    def _inject(self, reply: bytes) -> bytes | None:
        f = self.faults
        if f.drop and self._rng.random() < f.drop:
            self.stats.dropped += 1
            return None
        if f.corrupt and self._rng.random() < f.corrupt:
            self.stats.corrupted += 1
            b = bytearray(reply)
            i = self._rng.randrange(4, len(b))
            b[i] ^= self._rng.randrange(1, 256)
            return bytes(b)
        return reply

    def _flush_due(self) -> None:
        while self._queue:
            due, reply = self._queue[0]
            left = due - time.monotonic()
            if left > 3e-4:
                return
            while left > 0:  # spin the last fraction of a millisecond
                left = due - time.monotonic()
            self._queue.pop(0)
            self._log("tx", reply, time.monotonic())  # logged first: a reader of the log
            self._write(reply)  # who got the reply finds it there
            self.stats.replies += 1

    def _write(self, data: bytes) -> None:
        """Put bytes on the line; when nobody has read the line for kilobytes they are
        lost, as on a bus without a listener (never block the servos)."""
        try:
            os.write(self._master, data)
        except BlockingIOError:
            self.stats.lost_bytes += len(data)

    def _log(self, tag: str, raw: bytes, now: float) -> None:
        if self.log is not None:
            self.log.write(f"{now - self._log_t0:.6f} {tag} {raw.hex(' ')}\n")
            self.log.flush()


def pin(plant: Plant, j: int, angle: float) -> None:
    """Put joint ``j`` of ``plant`` at ``angle`` rad (of the plant), at rest, and tick its
    servo's firmware once there: the servo senses where the arm was put (its report is
    what it sensed at its last tick)."""
    q, qd = plant.q, plant.qd
    q[j], qd[j] = angle, 0.0
    plant.set_state(q, qd)
    plant.servos[j].update(plant.dt, plant.directions[j] * angle, 0.0)


class RestingPose:
    """Joints an emulator starts at a pose of a person's choosing (``armlab emulate
    --pose``): each stays where it was put, as an unpowered arm rests on its gears'
    friction where it was left, until its servo's torque first comes on; from then on the
    plant moves it. A physics class says where a joint lives (:meth:`_locate`)."""

    _resting: dict[int, float]  #: joint -> the angle it rests at, rad of the plant

    def _locate(self, joint: int) -> tuple[Plant, int]:
        """(plant, joint index in it) of emulated joint ``joint``; ValueError if none."""
        raise NotImplementedError

    def rest(self, joint: int, angle: float) -> None:
        """Put ``joint`` at ``angle`` rad and keep it there until its servo's torque
        comes on. ValueError for no such joint or a non-finite angle."""
        if not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle}")
        plant, j = self._locate(joint)
        pin(plant, j, float(angle))
        self._resting[joint] = float(angle)

    def _settle_resting(self) -> None:
        """After the plants stepped: joints still resting go back where they rest; one
        whose servo's torque is on is let go for good."""
        for joint, angle in list(self._resting.items()):
            plant, j = self._locate(joint)
            if plant.servos[j].regs.torque_enable:
                del self._resting[joint]
            else:
                pin(plant, j, angle)


class ArmPhysics(RestingPose):
    """A serial arm's emulated servos moved by its simulated plant, and an arm's gripper
    servo by the gripper's plant (:func:`armlab.hardware.backends.gripper.gripper_plant`):
    the servo whose ``joint`` is one past the arm's last. A family's physics
    (:class:`armlab.hardware.emulator.xseries.XPlantPhysics`,
    :class:`armlab.hardware.emulator.sts.StsPlantPhysics`) adds how its registers go in
    and its report comes back."""

    def __init__(self, plant: Plant, *, gripper: Plant | None = None) -> None:
        self.plant = plant
        self.gripper = gripper
        self._held: dict[int, float] = {}  # joint -> angle a hand holds it at, rad
        self._resting = {}

    def advance_to(self, t: float) -> None:
        self.plant.advance_to(t)
        if self.gripper is not None:
            self.gripper.advance_to(t)
        self._settle_resting()
        for joint, angle in self._held.items():
            pin(*self._locate(joint), angle)

    def hold(self, joint: int, angle: float | None) -> None:
        """Hold ``joint`` (the gripper's horn: one past the arm's last) at ``angle`` rad
        of the plant, as a person's hand moving the arm with its torque off would
        (``armlab emulate --control``); None lets go. ValueError for no such joint or a
        non-finite angle."""
        self._locate(joint)
        if angle is None:
            self._held.pop(joint, None)
        elif not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle}")
        else:
            self._held[joint] = float(angle)

    def _locate(self, joint: int) -> tuple[Plant, int]:
        if 0 <= joint < self.plant.n:
            return self.plant, joint
        if joint == self.plant.n and self.gripper is not None:
            return self.gripper, 0
        raise ValueError(f"no joint {joint} on this arm")

    def _model(self, s: TableImage) -> Any:
        """The simulated servo behind ``s``: an arm joint's, or the gripper's."""
        if s.joint == self.plant.n and self.gripper is not None:
            return self.gripper.servos[0]
        return self.plant.servos[s.joint]


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
    the simulated firmware's :class:`~armlab.hardware.sim.dynamixel_servo.ServoRegisters`; present
    values, the torque registers (an alarm shutdown clears them) and the
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
    positions = [plants[p].servos[j].present_position() for p, j in slots]  # type: ignore[union-attr]  # the plant's servos are of this table's family
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
