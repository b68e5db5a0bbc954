"""What a servo family is (:class:`ServoFamily`) and the packet module each one has
(:class:`Codec`, its parser, status and instruction packets): the types every family's
entry and every part that speaks to servos share. The registry of the families the lab
drives is :mod:`armlab.hardware.servos.registry`; the families themselves are
:mod:`armlab.hardware.families`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from armlab.hardware.servos.control_table import ControlTable


class Parser(Protocol):
    """A family's stream parser: bytes in, whole packets out."""

    def feed(self, data: bytes) -> Iterable[bytes]: ...
    def discard(self) -> None: ...
    @property
    def pending(self) -> int: ...
    @property
    def broken(self) -> int: ...


class Status(Protocol):
    """A decoded status packet, as the bus reads it."""

    @property
    def servo_id(self) -> int: ...
    @property
    def error(self) -> Any: ...  # each family's own flags (ErrorBits, StatusError): falsy when none
    @property
    def params(self) -> bytes: ...


class Instruction(Protocol):
    """A decoded instruction packet, as the emulator reads it."""

    @property
    def servo_id(self) -> int: ...
    @property
    def instruction(self) -> int: ...
    @property
    def params(self) -> bytes: ...


class Codec(Protocol):
    """What the bus, the scan and the emulator call of a family's packet module (each
    family's module is one: its functions build packets, its parser splits a stream)."""

    @property
    def BROADCAST_ID(self) -> int: ...  # noqa: N802 - the module's constant
    @property
    def MAX_ID(self) -> int: ...  # noqa: N802 - the module's constant
    @property
    def ProtocolError(self) -> type[ValueError]: ...  # noqa: N802 - the module's class
    @property
    def PacketParser(self) -> Callable[..., Parser]: ...  # noqa: N802 - the module's class

    def ping(self, servo_id: int) -> bytes: ...
    def read(self, servo_id: int, address: int, length: int) -> bytes: ...
    def write(self, servo_id: int, address: int, data: bytes) -> bytes: ...
    def reg_write(self, servo_id: int, address: int, data: bytes) -> bytes: ...
    def action(self, servo_id: int = ...) -> bytes: ...
    def sync_write(self, address: int, length: int, data: Mapping[int, bytes]) -> bytes: ...
    def sync_read(self, address: int, length: int, ids: Sequence[int]) -> bytes: ...
    def status(self, servo_id: int, error: int = ..., params: bytes = ...) -> bytes: ...
    def decode_status(self, packet: bytes, *, checked: bool = ...) -> Status: ...
    def decode_instruction(self, packet: bytes) -> Instruction: ...
    def factory_reset(self, servo_id: int, level: Any = ..., *, confirm: bool = ...
                      ) -> bytes: ...
    def write_refusal(self, servo_id: int, status: Any, *, address: int, length: int
                      ) -> Exception | None: ...


@dataclass(frozen=True)
class ServoFamily:
    """One servo family.

    Attributes:
        key: short name ("dynamixel1", "xseries", "sts").
        title: what a person calls it ("Dynamixel protocol 1.0").
        protocol: the protocol tag a joint map, a scan and a bus use (1, 2, "sts").
        codec: the packet module (:class:`Codec`).
        tables: control tables by model number.
        default_table: the table a bus assumes for a servo not yet identified.
        table_for: model number or name -> its table (ValueError naming the known ones).
        model_address: where the model number lives (2 bytes).
        ping_data: bytes of data in the status packet answering a PING.
        status_overhead: bytes of a status packet around its data.
        id_offset: index of the ID byte in a packet.
        group_read: SYNC_READ reads many servos in one request.
        broadcast_ping: every servo answers a broadcast PING, one after the other.
        spec_type: the datasheet class of its models.
        firmware_item: the item holding the firmware version (a scan reports it).
        limit_items: the items holding the position limits, (low, high).
        replies_all_level: the status return level at which a servo answers every
            instruction (Dynamixel 2; Feetech's Response Status Level 1), below which it
            answers PING and READ only.
        servo_model: the firmware model the plant runs (its ``firmware.py``).
        reboot_packet: ``servo ID -> packet`` of its REBOOT (None: it has none).
        bulk_read_packet: ``[(servo ID, address, length), ...] -> packet`` of its BULK_READ
            (None: it has none).
        fault_flags: the alarms one of its emulated servos can be told to raise, by name
            (``armlab emulate --fault JOINT:FLAG@S``): the value its firmware model's
            ``inject_error`` takes (empty: none).
        drives_gripper: ``datasheet -> whether a servo of that model can drive an arm's
            gripper`` with a bounded grip (None: none of its servos can).
        grip_note: ``datasheet -> how its gripper servo holds the finger and bounds the
            grip``, in a person's words (the lesson's Teach tab).
    """

    key: str
    title: str
    protocol: int | str
    codec: Codec
    tables: Mapping[int, ControlTable] = field(repr=False)
    default_table: ControlTable = field(repr=False)
    table_for: Callable[[int | str], ControlTable]
    model_address: int
    ping_data: int
    status_overhead: int
    id_offset: int
    group_read: bool
    broadcast_ping: bool
    spec_type: type
    firmware_item: str
    limit_items: tuple[str, str]
    servo_model: type
    replies_all_level: int = 2
    aliases: tuple[str, ...] = field(default=())
    reboot_packet: Callable[[int], bytes] | None = None
    bulk_read_packet: Callable[[Sequence[tuple[int, int, int]]], bytes] | None = None
    fault_flags: Mapping[str, int] = field(default_factory=dict)
    drives_gripper: Callable[[Any], bool] | None = None
    grip_note: Callable[[Any], str] | None = None

    @property
    def label(self) -> str:
        """The protocol as a person reads it ("1.0", "2.0", "Feetech STS")."""
        return f"{self.protocol}.0" if isinstance(self.protocol, int) else self.title

    @property
    def protocol_name(self) -> str:
        """The protocol as a sentence names it ("protocol 1.0", "Feetech STS")."""
        return f"protocol {self.label}" if isinstance(self.protocol, int) else self.title

    def status_length(self, data_bytes: int = 0) -> int:
        """Bytes of a status packet carrying ``data_bytes`` of data (before any stuffing)."""
        return self.status_overhead + data_bytes

    def id_of(self, packet: bytes) -> int:
        """The ID an encoded packet is sent to (or comes from)."""
        return packet[self.id_offset]

    def knows(self, model: int | str) -> bool:
        """Whether ``model`` (number or name) is one of this family's."""
        try:
            self.table_for(model)
        except ValueError:
            return False
        return True


