"""Dynamixel protocol 1.0: packets, checksum, status errors and a resynchronising parser.

Thesis §2.3.2 (instruction and status packets) and the ROBOTIS e-manual's
"Protocol 1.0" page; docs/serial.md says how the lab uses it.
An instruction packet is ``FF FF ID LEN INST P1..Pn CHK`` with LEN = n + 2 and
CHK = ~(ID + LEN + INST + ΣP) & 0xFF; a status packet has the error byte in
place of INST. Pure functions on bytes, no I/O: the bus, the emulator and the
tests share them.

Thesis example (goal position 0x252 = 594 × 300°/1023 = 174.2° to servo 1; the thesis
prints 207.9°, which is not what 0x252 means on a 300°, 10-bit servo)::

    >>> write(1, 30, bytes([0x52, 0x02])).hex(" ")
    'ff ff 01 05 03 1e 52 02 84'
    >>> decode_status(bytes.fromhex("ffff010200fc"))
    StatusPacket(servo_id=1, error=<ErrorBits: 0>, params=b'')
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

HEADER = b"\xff\xff"
BROADCAST_ID = 0xFE
MAX_ID = 0xFD  #: 253, the highest ID a servo can have
#: FF FF ID LEN INST/ERR CHK: bytes of a packet around its parameters.
OVERHEAD = 6


class Instruction(enum.IntEnum):
    """Protocol 1.0 instruction codes (the thesis's Table 2.6 lists READ as 0x01: a typo)."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    SYNC_WRITE = 0x83
    BULK_READ = 0x92  # MX series only; AX-12A and RX-24F answer it with an instruction error


class ErrorBits(enum.IntFlag):
    """The status packet's error byte (bit 7 is always 0)."""

    INPUT_VOLTAGE = 0x01
    ANGLE_LIMIT = 0x02
    OVERHEATING = 0x04
    RANGE = 0x08
    CHECKSUM = 0x10
    OVERLOAD = 0x20
    INSTRUCTION = 0x40


_ERROR_TEXT = {
    ErrorBits.INPUT_VOLTAGE: "input voltage out of range",
    ErrorBits.ANGLE_LIMIT: "goal outside the CW/CCW angle limits",
    ErrorBits.OVERHEATING: "overheating",
    ErrorBits.RANGE: "value out of range",
    ErrorBits.CHECKSUM: "checksum error in the instruction",
    ErrorBits.OVERLOAD: "overload (load beyond the torque limit)",
    ErrorBits.INSTRUCTION: "undefined instruction (or ACTION without REG_WRITE)",
}


def error_names(error: int) -> str:
    """Short names of the set bits, lowest bit first ("overheating, overload"); "ok" when 0."""
    if not int(error) & 0x7F:
        return "ok"
    flags = ErrorBits(int(error) & 0x7F)
    names = [bit.name.lower().replace("_", " ") for bit in ErrorBits if bit in flags]  # type: ignore[union-attr]  # an enum member's name is never None
    return ", ".join(names)


def describe_errors(error: int) -> str:
    """Human text for an error byte, e.g. "overload (...), overheating"; "ok" when 0."""
    flags = ErrorBits(int(error) & 0x7F)
    if not flags:
        return "ok"
    return ", ".join(text for bit, text in _ERROR_TEXT.items() if bit in flags)


class ProtocolError(ValueError):
    """Bytes that are not a valid protocol 1.0 packet (bad header, length or checksum)."""


#: Error bits that mean "this write was refused" (the others describe the servo's state).
REFUSED = ErrorBits.RANGE | ErrorBits.INSTRUCTION | ErrorBits.CHECKSUM
#: The goal position's addresses (30, 31): a write reaching them is refused by the
#: angle-limit bit too (a goal outside the CW/CCW limits)
GOAL_ADDRESSES = range(30, 32)


class ServoError(RuntimeError):
    """A servo answered with error bits set.

    Attributes:
        servo_id: the servo that reported.
        error: the error bits.
    """

    def __init__(self, servo_id: int, error: int):
        self.servo_id = int(servo_id)
        self.error = ErrorBits(int(error) & 0x7F)
        super().__init__(f"servo {self.servo_id} reports {describe_errors(self.error)}")


@dataclass(frozen=True)
class InstructionPacket:
    """A decoded instruction packet (what the emulator receives)."""

    servo_id: int
    instruction: int
    params: bytes

    def encode(self) -> bytes:
        return encode_packet(self.servo_id, self.instruction, self.params)


@dataclass(frozen=True)
class StatusPacket:
    """A decoded status packet (what a servo answers)."""

    servo_id: int
    error: ErrorBits
    params: bytes

    def encode(self) -> bytes:
        return encode_packet(self.servo_id, int(self.error), self.params)

    def check(self) -> StatusPacket:
        """Return self, or raise :class:`ServoError` when any error bit is set."""
        if self.error:
            raise ServoError(self.servo_id, self.error)
        return self


def checksum(body: bytes | Iterable[int]) -> int:
    """Protocol 1.0 checksum of ID, LEN, INST/ERR and parameters: ~(sum) & 0xFF (thesis §2.3.2)."""
    return ~sum(body) & 0xFF


def encode_packet(servo_id: int, code: int, params: bytes | Iterable[int] = b"") -> bytes:
    """``FF FF ID LEN code P.. CHK`` for an instruction (code = INST) or a status (code = ERR)."""
    params = bytes(params)
    if not 0 <= servo_id <= BROADCAST_ID:
        raise ValueError(f"servo_id {servo_id} outside 0..{BROADCAST_ID}")
    if not 0 <= code <= 0xFF:
        raise ValueError(f"instruction/error code {code} is not a byte")
    if len(params) > 253:
        raise ValueError(f"params: {len(params)} bytes, at most 253 fit in a packet")
    body = bytes((servo_id, len(params) + 2, code)) + params
    return HEADER + body + bytes((checksum(body),))


def ping(servo_id: int) -> bytes:
    """PING (0x01): a servo answers with an empty status packet whatever its return level."""
    return encode_packet(servo_id, Instruction.PING)


def read(servo_id: int, address: int, length: int) -> bytes:
    """READ (0x02) ``length`` bytes from ``address``."""
    _check_span(address, length)
    return encode_packet(servo_id, Instruction.READ, (address, length))


def write(servo_id: int, address: int, data: bytes) -> bytes:
    """WRITE (0x03) ``data`` starting at ``address`` (little-endian words)."""
    _check_span(address, len(data))
    return encode_packet(servo_id, Instruction.WRITE, bytes((address,)) + bytes(data))


def reg_write(servo_id: int, address: int, data: bytes) -> bytes:
    """REG_WRITE (0x04): like WRITE, held until ACTION."""
    _check_span(address, len(data))
    return encode_packet(servo_id, Instruction.REG_WRITE, bytes((address,)) + bytes(data))


def action(servo_id: int = BROADCAST_ID) -> bytes:
    """ACTION (0x05): apply the registered REG_WRITE (usually broadcast)."""
    return encode_packet(servo_id, Instruction.ACTION)


def factory_reset(servo_id: int, level: int | None = None, *, confirm: bool = False) -> bytes:
    """FACTORY_RESET (0x06): the servo forgets ID, baud and limits (ID becomes 1).

    Refused unless ``confirm=True``: a reset arm may no longer answer at its ID or baud.
    Protocol 1.0 resets everything: ``level`` (protocol 2.0's) must be None.
    """
    if level is not None:
        raise ValueError("level: protocol 1.0's FACTORY_RESET resets everything (a level "
                         "is protocol 2.0's)")
    if confirm is not True:
        raise ValueError(
            "confirm: FACTORY_RESET erases the servo's ID, baud and angle limits; "
            "pass confirm=True to send it"
        )
    return encode_packet(servo_id, Instruction.FACTORY_RESET)


def sync_write(address: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """SYNC_WRITE (0x83) to broadcast: ``length`` bytes at ``address`` for each servo.

    Args:
        address: first control-table address.
        length: bytes per servo (L).
        data: servo ID -> its L bytes, in the order they go on the wire.

    LEN = (L + 1)·N + 4; e.g. goal position + moving speed (L = 4) to three servos
    is a 23-byte packet.
    """
    _check_span(address, length)
    params = bytearray((address, length))
    for servo_id, chunk in data.items():
        if not 0 <= servo_id <= MAX_ID:
            raise ValueError(f"servo_id {servo_id} outside 0..{MAX_ID}")
        if len(chunk) != length:
            raise ValueError(f"data[{servo_id}]: {len(chunk)} bytes, expected {length}")
        params.append(servo_id)
        params += chunk
    if not data:
        raise ValueError("data: SYNC_WRITE needs at least one servo")
    return encode_packet(BROADCAST_ID, Instruction.SYNC_WRITE, params)


def sync_read(address: int, length: int, ids: Sequence[int]) -> bytes:
    """Protocol 1.0 has no SYNC_READ (a servo is read on its own: :func:`read`); raises
    :class:`ProtocolError` saying so (the family's ``group_read`` is False)."""
    raise ProtocolError("protocol 1.0 has no SYNC_READ: read each servo")


def status(servo_id: int, error: int = 0, params: bytes = b"") -> bytes:
    """A status packet (what the emulator sends back)."""
    return encode_packet(servo_id, int(error) & 0x7F, params)


def decode_status(packet: bytes, *, checked: bool = False) -> StatusPacket:
    """Parse one complete status packet; :class:`ProtocolError` if it is malformed.

    ``checked``: its checksum is known to be right (a :class:`PacketParser` returned it),
    so it is not summed again."""
    servo_id, code, params = _split(packet, checked=checked)
    return StatusPacket(servo_id, ErrorBits(code & 0x7F), params)


def decode_instruction(packet: bytes) -> InstructionPacket:
    """Parse one complete instruction packet; :class:`ProtocolError` if it is malformed."""
    servo_id, code, params = _split(packet)
    return InstructionPacket(servo_id, code, params)


def write_refusal(servo_id: int, status: StatusPacket, *, address: int, length: int
                  ) -> ServoError | None:
    """The error the answer ``status`` to a WRITE of ``length`` bytes at ``address`` says
    the servo refused it with (range, instruction, checksum; the angle limit on a goal),
    or None: it was carried out (its other bits describe the servo's state)."""
    refused = status.error & REFUSED
    if address < GOAL_ADDRESSES.stop and address + length > GOAL_ADDRESSES.start:
        refused |= status.error & ErrorBits.ANGLE_LIMIT
    return ServoError(servo_id, refused) if refused else None


def word(value: int) -> bytes:
    """A 16-bit value as its two little-endian bytes (L, H), as the control table stores it."""
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"value {value} does not fit in two bytes")
    return bytes((value & 0xFF, value >> 8))


def _check_span(address: int, length: int) -> None:
    if not 0 <= address <= 0xFF or not 0 <= length <= 0xFF:
        raise ValueError(f"address {address} / length {length} must be bytes")


def _split(packet: bytes, *, checked: bool = False) -> tuple[int, int, bytes]:
    packet = bytes(packet)
    if len(packet) < OVERHEAD or packet[:2] != HEADER:
        raise ProtocolError(f"not a packet: {packet.hex(' ')}")
    servo_id, length = packet[2], packet[3]
    if length < 2 or len(packet) != length + 4:
        raise ProtocolError(f"length byte {length} does not match {len(packet)} bytes")
    if not checked and checksum(packet[2:-1]) != packet[-1]:
        raise ProtocolError(f"bad checksum in {packet.hex(' ')}")
    return servo_id, packet[4], packet[5:-1]


@dataclass
class ParserStats:
    """What a :class:`PacketParser` threw away."""

    packets: int = 0
    discarded_bytes: int = 0
    bad_checksums: int = 0


class PacketParser:
    """Splits a byte stream into protocol 1.0 packets, resynchronising after garbage.

    Feed it bytes as they arrive; it returns each complete packet whose checksum
    is right. On a bad checksum it drops one byte and searches for the next
    ``FF FF`` header, so a broken or truncated packet costs only itself. ID 0xFF is
    not a valid ID, so ``FF FF FF`` means the header starts one byte later.
    ``discard()`` drops a partial packet (a servo does that after a 100 ms gap).
    A candidate never spans more than 259 bytes, so the buffer stays small.

    Args:
        collect_bad: keep each complete candidate whose checksum failed in
            :attr:`bad` (a servo answers those with the checksum error bit).
    """

    def __init__(self, *, collect_bad: bool = False) -> None:
        self._buf = bytearray()
        self._collect_bad = collect_bad
        self.stats = ParserStats()
        self.bad: list[bytes] = []

    @property
    def pending(self) -> int:
        """Bytes held while waiting for the rest of a packet."""
        return len(self._buf)

    @property
    def broken(self) -> int:
        """Packets dropped so far for a bad checksum (a reply broken on the wire)."""
        return self.stats.bad_checksums

    def discard(self) -> None:
        """Forget any partial packet (the 100 ms inter-byte gap rule, or after a timeout)."""
        self.stats.discarded_bytes += len(self._buf)
        self._buf.clear()

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; return the complete, checksum-valid packets found, in order."""
        self._buf += data
        out: list[bytes] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # keep a trailing FF: it may be the first half of a header
                keep = 1 if buf.endswith(b"\xff") else 0
                self.stats.discarded_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if start:
                self.stats.discarded_bytes += start
                del buf[:start]
            if len(buf) < 4:
                break
            if buf[2] == 0xFF:  # FF FF FF: the header starts one byte later
                self.stats.discarded_bytes += 1
                del buf[0]
                continue
            length = buf[3]
            if length < 2:
                self.stats.discarded_bytes += 1
                del buf[0]
                continue
            total = length + 4
            if len(buf) < total:
                break
            if checksum(buf[2 : total - 1]) != buf[total - 1]:
                self.stats.bad_checksums += 1
                self.stats.discarded_bytes += 1
                if self._collect_bad:
                    self.bad.append(bytes(buf[:total]))
                del buf[0]
                continue
            out.append(bytes(buf[:total]))
            self.stats.packets += 1
            del buf[:total]
        return out
