"""Feetech STS/SMS serial-bus protocol (the STS3215 of the SO-101): packets and encodings.

The frame is Dynamixel protocol 1.0's: ``FF FF ID LEN INST P1..Pn CHK`` with LEN = n + 2
and CHK = ~(ID + LEN + INST + ΣP) & 0xFF; a status packet carries the error byte in
place of INST. This module builds the frames with
:mod:`armlab.hardware.families.dynamixel1.packets`'s
encoder and parser (one implementation of the frame) and adds what differs:

- the instruction set: PING 0x01, READ 0x02, WRITE 0x03, REG_WRITE 0x04, ACTION 0x05,
  RESET 0x0A (not protocol 1.0's FACTORY_RESET 0x06), SYNC_READ 0x82 and
  SYNC_WRITE 0x83 (Feetech's FTServo SDK, ``scservo_sdk/scservo_def.py``:
  ``INST_*``; github.com/ftservo/FTServo_Python at a203373);
- SYNC_READ ``FF FF FE LEN 82 addr L id1..idN CHK``, LEN = N + 4: each named servo
  answers with its own status packet of L data bytes (``protocol_packet_handler.py``,
  ``syncReadTx``/``syncReadRx``);
- the status error bits: 0x01 voltage, 0x02 angle (sensor), 0x04 overheat,
  0x08 over-current, 0x20 overload (``protocol_packet_handler.py``, ``ERRBIT_*``);
  a servo does not flag refused writes (there is no range or instruction bit);
- IDs 0..252 (``MAX_ID = 0xFC``), broadcast 0xFE;
- words little-endian on the STS/SMS series (the SDK's ``scs_end`` 0; the older SCS
  series is big-endian and is not driven here);
- sign-magnitude values: bit 15 of a position or speed word, bit 10 of Present Load,
  bit 11 of Homing Offset is the sign, the rest the magnitude (the SDK's
  ``scs_toscs``/``scs_tohost``; LeRobot ``src/lerobot/motors/feetech/tables.py``,
  ``STS_SMS_SERIES_ENCODINGS_TABLE``, at 7427f31).

Byte example (checked by hand from the format above)::

    >>> ping(1).hex(" ")
    'ff ff 01 02 01 fb'
    >>> write(1, 42, (2048).to_bytes(2, "little")).hex(" ")
    'ff ff 01 05 03 2a 00 08 c4'
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from armlab.hardware.families.dynamixel1 import packets as _frame

# the frame is protocol 1.0's, and so are these parts of the family's codec (re-exported)
from armlab.hardware.families.dynamixel1.packets import OVERHEAD as OVERHEAD
from armlab.hardware.families.dynamixel1.packets import InstructionPacket as InstructionPacket
from armlab.hardware.families.dynamixel1.packets import PacketParser as PacketParser
from armlab.hardware.families.dynamixel1.packets import ParserStats as ParserStats
from armlab.hardware.families.dynamixel1.packets import ProtocolError as ProtocolError
from armlab.hardware.families.dynamixel1.packets import checksum as checksum
from armlab.hardware.families.dynamixel1.packets import decode_instruction as decode_instruction
from armlab.hardware.families.dynamixel1.packets import encode_packet

BROADCAST_ID = 0xFE
MAX_ID = 0xFC  #: 252, the highest ID (FTServo SDK, ``scservo_def.py``)


class Instruction(enum.IntEnum):
    """STS/SMS instruction codes (FTServo SDK ``INST_*``)."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x0A
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83


class ErrorBits(enum.IntFlag):
    """The status packet's error byte (FTServo SDK ``ERRBIT_*``): the servo's state."""

    VOLTAGE = 0x01
    ANGLE = 0x02
    OVERHEAT = 0x04
    OVERCURRENT = 0x08
    OVERLOAD = 0x20


_ERROR_TEXT = {
    ErrorBits.VOLTAGE: "input voltage out of range",
    ErrorBits.ANGLE: "angle sensor error",
    ErrorBits.OVERHEAT: "overheating",
    ErrorBits.OVERCURRENT: "over-current",
    ErrorBits.OVERLOAD: "overload",
}


def describe_errors(error: int) -> str:
    """The error bits as words, e.g. "overheating, overload (0x24)"; "no error" for 0."""
    if not error:
        return "no error"
    words = [text for bit, text in _ERROR_TEXT.items() if error & bit]
    unknown = error & ~sum(_ERROR_TEXT) & 0xFF
    if unknown:
        words.append(f"unknown bits 0x{unknown:02x}")
    return f"{', '.join(words)} (0x{error:02x})"


class ServoError(RuntimeError):
    """A servo's status packet carries error bits (its state: a Feetech servo does not
    refuse writes in its status packet)."""

    def __init__(self, servo_id: int, error: int):
        self.servo_id = int(servo_id)
        self.error = ErrorBits(int(error) & 0x7F)
        super().__init__(f"servo {self.servo_id} reports {describe_errors(self.error)}")


@dataclass(frozen=True)
class StatusPacket(_frame.StatusPacket):
    """A decoded status packet (what a servo answers): protocol 1.0's frame and fields
    (its ``encode``), the error byte Feetech's :class:`ErrorBits`."""

    error: ErrorBits  # type: ignore[assignment]  # Feetech's error bits in place of 1.0's (same frame)

    def check(self) -> StatusPacket:
        """Return self, or raise :class:`ServoError` when any error bit is set."""
        if self.error:
            raise ServoError(self.servo_id, self.error)
        return self


def _span(address: int, length: int) -> None:
    if not 0 <= address <= 0xFF or not 0 <= length <= 0xFF:
        raise ValueError(f"address {address} / length {length} must be bytes")


def _target(servo_id: int) -> None:
    if not (0 <= servo_id <= MAX_ID or servo_id == BROADCAST_ID):
        raise ValueError(f"servo_id {servo_id} outside 0..{MAX_ID} (or {BROADCAST_ID})")


def ping(servo_id: int) -> bytes:
    """PING (0x01): the servo answers with an empty status packet."""
    _target(servo_id)
    return encode_packet(servo_id, Instruction.PING)


def read(servo_id: int, address: int, length: int) -> bytes:
    """READ (0x02) ``length`` bytes from ``address``."""
    _target(servo_id)
    _span(address, length)
    return encode_packet(servo_id, Instruction.READ, (address, length))


def write(servo_id: int, address: int, data: bytes) -> bytes:
    """WRITE (0x03) ``data`` from ``address``."""
    _target(servo_id)
    _span(address, len(data))
    return encode_packet(servo_id, Instruction.WRITE, bytes((address,)) + bytes(data))


def reg_write(servo_id: int, address: int, data: bytes) -> bytes:
    """REG_WRITE (0x04): as WRITE, held until ACTION."""
    _target(servo_id)
    _span(address, len(data))
    return encode_packet(servo_id, Instruction.REG_WRITE, bytes((address,)) + bytes(data))


def action(servo_id: int = BROADCAST_ID) -> bytes:
    """ACTION (0x05): apply the registered REG_WRITE (usually broadcast)."""
    return encode_packet(servo_id, Instruction.ACTION)


def reset(servo_id: int, *, confirm: bool = False) -> bytes:
    """RESET (0x0A): the servo's EEPROM back to the factory's. Refused unless ``confirm``."""
    if confirm is not True:
        raise ValueError("confirm: RESET erases the servo's settings; pass confirm=True")
    _target(servo_id)
    return encode_packet(servo_id, Instruction.RESET)


def factory_reset(servo_id: int, level: int | None = None, *, confirm: bool = False) -> bytes:
    """:func:`reset` by the name every family's codec has; ``level`` (protocol 2.0's) must
    be None: RESET restores everything."""
    if level is not None:
        raise ValueError("level: Feetech's RESET restores everything (a level is protocol "
                         "2.0's)")
    return reset(servo_id, confirm=confirm)


def write_refusal(servo_id: int, status: StatusPacket, *, address: int, length: int
                  ) -> ServoError | None:
    """None: a Feetech servo's status bits describe its state, never a refused write
    (they stay in the bus's ``errors``)."""
    return None


def sync_write(address: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """SYNC_WRITE (0x83) to broadcast: ``length`` bytes at ``address`` for each servo
    (``data``: ID -> its bytes, in wire order). LEN = (L + 1)·N + 4."""
    _span(address, length)
    if not data:
        raise ValueError("data: SYNC_WRITE needs at least one servo")
    params = bytearray((address, length))
    for servo_id, chunk in data.items():
        if not 0 <= servo_id <= MAX_ID:
            raise ValueError(f"servo_id {servo_id} outside 0..{MAX_ID}")
        if len(chunk) != length:
            raise ValueError(f"data[{servo_id}]: {len(chunk)} bytes, expected {length}")
        params += bytes((servo_id,)) + bytes(chunk)
    return encode_packet(BROADCAST_ID, Instruction.SYNC_WRITE, params)


def sync_read(address: int, length: int, ids: Sequence[int]) -> bytes:
    """SYNC_READ (0x82) to broadcast: ``length`` bytes at ``address`` from each of ``ids``,
    which answer one status packet each. LEN = N + 4."""
    _span(address, length)
    if not ids:
        raise ValueError("ids: SYNC_READ needs at least one servo")
    for servo_id in ids:
        if not 0 <= servo_id <= MAX_ID:
            raise ValueError(f"servo_id {servo_id} outside 0..{MAX_ID}")
    return encode_packet(BROADCAST_ID, Instruction.SYNC_READ,
                         bytes((address, length)) + bytes(ids))


def status(servo_id: int, error: int = 0, params: bytes = b"") -> bytes:
    """A status packet (what the emulator sends back)."""
    return encode_packet(servo_id, int(error) & 0x7F, params)


def decode_status(packet: bytes, *, checked: bool = False) -> StatusPacket:
    """Parse one status packet; :class:`ProtocolError` when it is malformed."""
    raw = _frame.decode_status(packet, checked=checked)
    return StatusPacket(raw.servo_id, ErrorBits(int(raw.error) & 0x7F), raw.params)


def encode_sign_magnitude(value: int, sign_bit: int) -> int:
    """A signed value -> its sign-magnitude word: |value| in the bits below ``sign_bit``,
    ``sign_bit`` set when negative. ValueError when |value| does not fit."""
    value = int(value)
    most = (1 << sign_bit) - 1
    if abs(value) > most:
        raise ValueError(f"{value} does not fit in {sign_bit} bits of magnitude (±{most})")
    return abs(value) | (1 << sign_bit if value < 0 else 0)


def decode_sign_magnitude(raw: int, sign_bit: int) -> int:
    """A sign-magnitude word -> the signed value (bits above ``sign_bit`` ignored)."""
    raw = int(raw)
    magnitude = raw & ((1 << sign_bit) - 1)
    return -magnitude if raw >> sign_bit & 1 else magnitude
