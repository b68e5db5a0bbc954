"""Dynamixel protocol 2.0: packets, CRC-16, byte stuffing, status errors and a resynchronising
parser.

The ROBOTIS e-manual's "Protocol 2.0" page; docs/serial.md says how the lab uses it.
An instruction packet is ``FF FF FD 00 ID LEN_L LEN_H INST P1..Pn CRC_L CRC_H`` with
LEN = n + 3 (INST, the parameters and the two CRC bytes); a status packet has INST 0x55
and an ERROR byte before its data. The CRC is CRC-16 with polynomial 0x8005 (init 0, no
reflection: "CRC-16/BUYPASS") over every byte from the first FF to the last parameter.
Inside INST..parameters the header pattern ``FF FF FD`` is sent as ``FF FF FD FD`` (byte
stuffing); LEN and CRC count the stuffed bytes. Pure functions on bytes, no I/O, like
:mod:`armlab.hardware.families.dynamixel1.packets`.

The e-manual's PING example and its answer from a model-1030 servo (firmware 0x26)::

    >>> ping(1).hex(" ")
    'ff ff fd 00 01 03 00 01 19 4e'
    >>> decode_status(bytes.fromhex("ff ff fd 00 01 07 00 55 00 06 04 26 65 5d"))
    StatusPacket(servo_id=1, error=StatusError(number=0, alert=False), params=b'\\x06\\x04&')
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
MAX_ID = 0xFC  #: 252, the highest ID a servo can have
STATUS = 0x55  #: the INST byte of every status packet
#: FF FF FD 00 ID LEN_L LEN_H: bytes before INST; + 2 CRC bytes after the parameters.
PREFIX = 7
#: Longest LEN the parser waits for (the e-manual's servos take far shorter packets): a
#: garbage LEN never makes it hold the stream for more.
MAX_LENGTH = 1024
_STUFF_FROM = b"\xff\xff\xfd"
_STUFF_TO = b"\xff\xff\xfd\xfd"


class Instruction(enum.IntEnum):
    """Protocol 2.0 instruction codes (e-manual, "Instruction")."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93


class ErrorNumber(enum.IntEnum):
    """The status packet's error number (bits 0..6 of its ERROR byte; e-manual, "Error")."""

    NONE = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


_ERROR_TEXT = {
    ErrorNumber.RESULT_FAIL: "the servo failed to process the instruction",
    ErrorNumber.INSTRUCTION: "undefined instruction (or ACTION without REG_WRITE)",
    ErrorNumber.CRC: "CRC error in the instruction",
    ErrorNumber.DATA_RANGE: "data too long for the address range",
    ErrorNumber.DATA_LENGTH: "data shorter than the item",
    ErrorNumber.DATA_LIMIT: "value outside the item's limits",
    ErrorNumber.ACCESS: "access error (read-only item, or EEPROM with torque on)",
}

#: Bit 7 of the ERROR byte: the servo has a hardware alert (see Hardware Error Status).
ALERT = 0x80


class HardwareError(enum.IntFlag):
    """Hardware Error Status (X-series address 70; e-manual, "Shutdown" and "Hardware Error
    Status"): why a servo raised its alert. The bits set in its Shutdown register (63;
    0x34 from the factory on the XM430 and XL430: Overheating, Electrical Shock, Overload)
    also switch its torque off; only a REBOOT clears the status and lets the torque on
    again."""

    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20


#: Each bit's name in the e-manual's table (its "... Error").
_HARDWARE_NAMES = {
    HardwareError.INPUT_VOLTAGE: "Input Voltage",
    HardwareError.OVERHEATING: "Overheating",
    HardwareError.MOTOR_ENCODER: "Motor Encoder",
    HardwareError.ELECTRICAL_SHOCK: "Electrical Shock",
    HardwareError.OVERLOAD: "Overload",
}
HARDWARE_ERROR_BITS = sum(_HARDWARE_NAMES)  #: 0x3D, the bits a Hardware Error Status uses


def describe_hardware_error(bits: int) -> str:
    """A Hardware Error Status value by its bits' e-manual names and the value, e.g.
    "Overheating, Overload (Hardware Error Status 0x24)"; "ok" when clear."""
    flags = HardwareError(int(bits) & HARDWARE_ERROR_BITS)
    if not flags:
        return "ok"
    names = ", ".join(name for bit, name in _HARDWARE_NAMES.items() if bit in flags)
    return f"{names} (Hardware Error Status {int(bits):#04x})"


@dataclass(frozen=True)
class StatusError:
    """A status packet's ERROR byte: the error number and the hardware-alert bit.

    Attributes:
        number: :class:`ErrorNumber` (0: the instruction was carried out).
        alert: the servo has a hardware error (read Hardware Error Status to learn which).
    """

    number: int = 0
    alert: bool = False

    @classmethod
    def of(cls, byte: int) -> StatusError:
        """The ERROR byte's meaning (one shared, frozen instance per byte value)."""
        return _STATUS_ERRORS[int(byte) & 0xFF]

    @property
    def byte(self) -> int:
        return (int(self.number) & 0x7F) | (ALERT if self.alert else 0)

    def __bool__(self) -> bool:
        return bool(self.number) or self.alert

    def describe(self) -> str:
        """Human text ("CRC error in the instruction; hardware alert"); "ok" when clear."""
        parts = []
        if self.number:
            try:
                parts.append(_ERROR_TEXT[ErrorNumber(self.number)])
            except ValueError:
                parts.append(f"error number {self.number}")
        if self.alert:
            parts.append("hardware alert (see Hardware Error Status)")
        return "; ".join(parts) or "ok"


_STATUS_ERRORS = tuple(StatusError(b & 0x7F, bool(b & ALERT)) for b in range(256))


class ProtocolError(ValueError):
    """Bytes that are not a valid protocol 2.0 packet (header, length, CRC or stuffing)."""


class ServoError(RuntimeError):
    """A servo answered with an error number or its hardware alert set.

    Attributes:
        servo_id: the servo that reported.
        error: its :class:`StatusError`.
    """

    def __init__(self, servo_id: int, error: StatusError):
        self.servo_id = int(servo_id)
        self.error = error
        super().__init__(f"servo {self.servo_id} reports {error.describe()}")


def write_refusal(servo_id: int, status: StatusPacket, *, address: int, length: int
                  ) -> ServoError | None:
    """The error the answer ``status`` to a WRITE says the servo refused it with (any error
    number), or None. A hardware alert alone is no refusal: the write was carried out.
    ``address`` and ``length`` are the write's (protocol 2.0 does not need them)."""
    if status.error.number:
        return ServoError(servo_id, StatusError(status.error.number))
    return None


@dataclass(frozen=True)
class InstructionPacket:
    """A decoded instruction packet (what the emulator receives); ``params`` unstuffed."""

    servo_id: int
    instruction: int
    params: bytes

    def encode(self) -> bytes:
        return encode_packet(self.servo_id, self.instruction, self.params)


@dataclass(frozen=True)
class StatusPacket:
    """A decoded status packet (what a servo answers); ``params`` unstuffed, after ERROR."""

    servo_id: int
    error: StatusError
    params: bytes

    def encode(self) -> bytes:
        return status(self.servo_id, self.error.byte, self.params)

    def check(self) -> StatusPacket:
        """Return self, or raise :class:`ServoError` when the error number or alert is set."""
        if self.error:
            raise ServoError(self.servo_id, self.error)
        return self


# ---------------------------------------------------------------- CRC and stuffing


def _crc_table() -> tuple[int, ...]:
    """The e-manual's ``crc_table``: the CRC-16 of each byte value shifted through."""
    table = []
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = (c << 1) ^ 0x8005 if c & 0x8000 else c << 1
        table.append(c & 0xFFFF)
    return tuple(table)


def _crc_table16(table: tuple[int, ...]) -> list[int]:
    """The CRC-16 register after two bytes ``w >> 8``, ``w & 0xFF`` from 0, for every
    16-bit ``w``: a 16-bit register is all replaced by two bytes, so the register after them
    is this table at (register XOR the two bytes), half the loop of the e-manual's
    ``update_crc`` (built with numpy in ~1 ms)."""
    import numpy as np

    t = np.asarray(table, dtype=np.uint32)
    w = np.arange(1 << 16, dtype=np.uint32)
    first = t[w >> 8]
    return (((first << 8) & 0xFFFF) ^ t[(first >> 8) ^ (w & 0xFF)]).tolist()


_CRC_TABLE = _crc_table()
_CRC_TABLE16 = _crc_table16(_CRC_TABLE)


def crc16(data: bytes | Iterable[int], crc: int = 0) -> int:
    """CRC-16 (polynomial 0x8005, init ``crc``, MSB first) of ``data``: the e-manual's
    ``update_crc``, table-driven two bytes at a time."""
    data = bytes(data)
    n = len(data)
    if n & 1:
        crc = ((crc << 8) & 0xFF00) ^ _CRC_TABLE[(crc >> 8) ^ data[0]]
        data = data[1:]
    table = _CRC_TABLE16
    for w in struct.unpack(f">{n >> 1}H", data):
        crc = table[crc ^ w]
    return crc


def stuff(body: bytes) -> bytes:
    """INST..parameters as sent: every ``FF FF FD`` followed by an extra ``FD``."""
    return bytes(body).replace(_STUFF_FROM, _STUFF_TO)


def unstuff(body: bytes) -> bytes:
    """The inverse of :func:`stuff`: every ``FF FF FD FD`` back to ``FF FF FD``."""
    return bytes(body).replace(_STUFF_TO, _STUFF_FROM)


# ---------------------------------------------------------------- packets


def encode_packet(servo_id: int, instruction: int, params: bytes | Iterable[int] = b"") -> bytes:
    """``FF FF FD 00 ID LEN INST P.. CRC`` with ``params`` stuffed (for a status packet,
    ``instruction`` is 0x55 and ``params`` starts with the ERROR byte)."""
    if not 0 <= servo_id <= BROADCAST_ID:
        raise ValueError(f"servo_id {servo_id} outside 0..{BROADCAST_ID}")
    if not 0 <= instruction <= 0xFF:
        raise ValueError(f"instruction {instruction} is not a byte")
    body = stuff(bytes((instruction,)) + bytes(params))
    length = len(body) + 2
    if length > 0xFFFF:
        raise ValueError(f"params: {len(body)} bytes do not fit in one packet")
    packet = HEADER + bytes((servo_id, length & 0xFF, length >> 8)) + body
    return packet + crc16(packet).to_bytes(2, "little")


def ping(servo_id: int) -> bytes:
    """PING (0x01): a servo answers with its model number (2 bytes) and firmware version."""
    return encode_packet(servo_id, Instruction.PING)


def read(servo_id: int, address: int, length: int) -> bytes:
    """READ (0x02) ``length`` bytes from ``address`` (both 2-byte little-endian)."""
    return encode_packet(servo_id, Instruction.READ, _u16(address) + _u16(length))


def write(servo_id: int, address: int, data: bytes) -> bytes:
    """WRITE (0x03) ``data`` starting at ``address`` (little-endian values)."""
    return encode_packet(servo_id, Instruction.WRITE, _u16(address) + bytes(data))


def reg_write(servo_id: int, address: int, data: bytes) -> bytes:
    """REG_WRITE (0x04): like WRITE, held until ACTION."""
    return encode_packet(servo_id, Instruction.REG_WRITE, _u16(address) + bytes(data))


def action(servo_id: int = BROADCAST_ID) -> bytes:
    """ACTION (0x05): apply the registered REG_WRITE (usually broadcast)."""
    return encode_packet(servo_id, Instruction.ACTION)


def reboot(servo_id: int) -> bytes:
    """REBOOT (0x08): restart the servo (the way to clear a hardware error; torque off)."""
    return encode_packet(servo_id, Instruction.REBOOT)


class ResetLevel(enum.IntEnum):
    """FACTORY_RESET's parameter: what the reset keeps."""

    ALL = 0xFF  #: everything, ID becomes 1 and the baud rate 57600
    KEEP_ID = 0x01  #: everything but the ID
    KEEP_ID_AND_BAUD = 0x02  #: everything but the ID and the baud rate


def factory_reset(servo_id: int, level: int | None = ResetLevel.ALL, *,
                  confirm: bool = False) -> bytes:
    """FACTORY_RESET (0x06): the servo forgets its settings (limits, modes, gains; the ID
    and baud rate too at :attr:`ResetLevel.ALL`, which None means too).

    Refused unless ``confirm=True``: a reset arm may no longer answer at its ID or baud,
    and its limits no longer keep it off its own body.
    """
    if confirm is not True:
        raise ValueError(
            "confirm: FACTORY_RESET erases the servo's limits and settings (at level ALL "
            "its ID and baud too); pass confirm=True to send it")
    level = ResetLevel.ALL if level is None else ResetLevel(level)
    return encode_packet(servo_id, Instruction.FACTORY_RESET, bytes((level,)))


def sync_read(address: int, length: int, ids: Sequence[int]) -> bytes:
    """SYNC_READ (0x82) to broadcast: ``length`` bytes at ``address`` from each of ``ids``;
    each servo answers with its own status packet, in the order of ``ids``."""
    if not ids:
        raise ValueError("ids: SYNC_READ needs at least one servo")
    return encode_packet(BROADCAST_ID, Instruction.SYNC_READ,
                         _u16(address) + _u16(length) + bytes(_ids(ids)))


def sync_write(address: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """SYNC_WRITE (0x83) to broadcast: ``length`` bytes at ``address`` for each servo
    (``data``: servo ID -> its bytes, in the order they go on the wire)."""
    if not data:
        raise ValueError("data: SYNC_WRITE needs at least one servo")
    params = bytearray(_u16(address) + _u16(length))
    for servo_id, chunk in data.items():
        _ids((servo_id,))
        if len(chunk) != length:
            raise ValueError(f"data[{servo_id}]: {len(chunk)} bytes, expected {length}")
        params.append(servo_id)
        params += chunk
    return encode_packet(BROADCAST_ID, Instruction.SYNC_WRITE, params)


def bulk_read(requests: Sequence[tuple[int, int, int]]) -> bytes:
    """BULK_READ (0x92) to broadcast: ``(servo ID, address, length)`` for each servo, each
    its own item; the servos answer in that order."""
    if not requests:
        raise ValueError("requests: BULK_READ needs at least one servo")
    params = bytearray()
    for servo_id, address, length in requests:
        _ids((servo_id,))
        params += bytes((servo_id,)) + _u16(address) + _u16(length)
    return encode_packet(BROADCAST_ID, Instruction.BULK_READ, params)


def status(servo_id: int, error: int = 0, params: bytes = b"") -> bytes:
    """A status packet (what the emulator sends back): INST 0x55, ERROR, data."""
    return encode_packet(servo_id, STATUS, bytes((int(error) & 0xFF,)) + bytes(params))


def decode_status(packet: bytes, *, checked: bool = False) -> StatusPacket:
    """Parse one complete status packet; :class:`ProtocolError` if it is malformed.

    ``checked``: its CRC is known to be right (a :class:`PacketParser` returned it), so it
    is not computed again."""
    servo_id, inst, params = _split(packet, checked=checked)
    if inst != STATUS or not params:
        raise ProtocolError(f"not a status packet: {bytes(packet).hex(' ')}")
    return StatusPacket(servo_id, StatusError.of(params[0]), params[1:])


def decode_instruction(packet: bytes) -> InstructionPacket:
    """Parse one complete instruction packet; :class:`ProtocolError` if it is malformed."""
    servo_id, inst, params = _split(packet)
    if inst == STATUS:
        raise ProtocolError(f"a status packet, not an instruction: {bytes(packet).hex(' ')}")
    return InstructionPacket(servo_id, inst, params)


def status_length(data_bytes: int) -> int:
    """Bytes of a status packet carrying ``data_bytes`` of data (before any stuffing):
    11 + data (a PING's answer: 14)."""
    return PREFIX + 2 + 2 + data_bytes


def _u16(value: int) -> bytes:
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"{value} does not fit in two bytes")
    return int(value).to_bytes(2, "little")


def _ids(ids: Iterable[int]) -> list[int]:
    out = [int(i) for i in ids]
    for i in out:
        if not 0 <= i <= MAX_ID:
            raise ValueError(f"servo_id {i} outside 0..{MAX_ID}")
    return out


def _split(packet: bytes, *, checked: bool = False) -> tuple[int, int, bytes]:
    packet = bytes(packet)
    if len(packet) < PREFIX + 3 or packet[:4] != HEADER:
        raise ProtocolError(f"not a packet: {packet.hex(' ')}")
    length = packet[5] | packet[6] << 8
    if length < 3 or len(packet) != PREFIX + length:
        raise ProtocolError(f"length {length} does not match {len(packet)} bytes")
    if not checked and crc16(packet[:-2]) != int.from_bytes(packet[-2:], "little"):
        raise ProtocolError(f"bad CRC in {packet.hex(' ')}")
    body = unstuff(packet[PREFIX:-2])
    return packet[4], body[0], body[1:]


# ---------------------------------------------------------------- stream parser


@dataclass
class ParserStats:
    """What a :class:`PacketParser` threw away."""

    packets: int = 0
    discarded_bytes: int = 0
    bad_crcs: int = 0


class PacketParser:
    """Splits a byte stream into protocol 2.0 packets, resynchronising after garbage.

    Feed it bytes as they arrive; it returns each complete packet whose CRC is right
    (still stuffed: :func:`decode_status` / :func:`decode_instruction` unstuff). On a
    bad CRC or an impossible length it drops one byte and searches for the next
    ``FF FF FD 00`` header, so a broken or truncated packet costs only itself. A
    candidate never spans more than ``7 + MAX_LENGTH`` bytes.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.stats = ParserStats()

    @property
    def pending(self) -> int:
        """Bytes held while waiting for the rest of a packet."""
        return len(self._buf)

    @property
    def broken(self) -> int:
        """Packets dropped so far for a bad CRC (a reply broken on the wire)."""
        return self.stats.bad_crcs

    def discard(self) -> None:
        """Forget any partial packet (after a timeout)."""
        self.stats.discarded_bytes += len(self._buf)
        self._buf.clear()

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; return the complete, CRC-valid packets found, in order."""
        self._buf += data
        out: list[bytes] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                keep = _header_prefix(buf)  # a header may be arriving
                self.stats.discarded_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if start:
                self.stats.discarded_bytes += start
                del buf[:start]
            if len(buf) < PREFIX:
                break
            length = buf[5] | buf[6] << 8
            if not 3 <= length <= MAX_LENGTH or buf[4] == 0xFF:
                self.stats.discarded_bytes += 1
                del buf[0]
                continue
            total = PREFIX + length
            if len(buf) < total:
                break
            if crc16(buf[: total - 2]) != int.from_bytes(buf[total - 2 : total], "little"):
                self.stats.bad_crcs += 1
                self.stats.discarded_bytes += 1
                del buf[0]
                continue
            out.append(bytes(buf[:total]))
            self.stats.packets += 1
            del buf[:total]
        return out


def _header_prefix(buf: bytearray) -> int:
    """How many trailing bytes of ``buf`` could be the start of a header."""
    for k in (3, 2, 1):
        if len(buf) >= k and bytes(buf[-k:]) == HEADER[:k]:
            return k
    return 0
