"""Servo families: everything the lab knows about one kind of servo, in one entry.

A family is a packet codec (the module that builds and parses its packets), its control
tables by model number, its firmware model for the simulation, its backends (real and
simulated) and its emulator. The bus, the scan, the joint map, the plant, the backend
factories and the emulator ask :func:`family` (by protocol, name or model) instead of
testing a protocol number, so adding a family is its own modules plus one entry in
:data:`FAMILIES`.

A family's packet module is typed by :class:`Codec` (each of ``wire/protocol1.py``,
``wire/protocol2.py`` and ``wire/feetech.py`` is one, checked by mypy) and its firmware
model is a class here. Its backends and emulator stand above the bus that imports this
module: :mod:`armlab.hardware.family_parts` names them per family.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from armlab.hardware.servos.control_table import RX24F_TABLE, TABLES, ControlTable, table_for
from armlab.hardware.servos.sts import STS3215_TABLE, STS_TABLES, sts_table_for
from armlab.hardware.servos.xseries import X_TABLES, XM430_W350_TABLE, x_table_for
from armlab.hardware.sim.dynamixel_servo import ServoModel
from armlab.hardware.sim.sts_servo import StsServoModel
from armlab.hardware.sim.xseries_servo import XServoModel
from armlab.hardware.wire import feetech as ft
from armlab.hardware.wire import protocol1 as p1
from armlab.hardware.wire import protocol2 as p2


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
        servo_model: the firmware model the plant runs (a class of ``armlab.hardware.sim``).
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

    @property
    def label(self) -> str:
        """The protocol as a person reads it ("1.0", "2.0", "Feetech STS")."""
        return f"{self.protocol}.0" if isinstance(self.protocol, int) else self.title

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


def _spec_type(table: ControlTable) -> type:
    return type(table.spec)


DYNAMIXEL1 = ServoFamily(
    key="dynamixel1", title="Dynamixel protocol 1.0", protocol=1, codec=p1, tables=TABLES,
    default_table=RX24F_TABLE, table_for=table_for, model_address=0, ping_data=0,
    status_overhead=p1.OVERHEAD, id_offset=2, group_read=False, broadcast_ping=False,
    spec_type=_spec_type(RX24F_TABLE), firmware_item="firmware_version",
    limit_items=("cw_angle_limit", "ccw_angle_limit"),
    servo_model=ServoModel,
    aliases=("1", "1.0", "protocol1"),
)
XSERIES = ServoFamily(
    key="xseries", title="Dynamixel X-series (protocol 2.0)", protocol=2, codec=p2,
    tables=X_TABLES, default_table=XM430_W350_TABLE, table_for=x_table_for, model_address=0,
    ping_data=3, status_overhead=p2.status_length(0), id_offset=4, group_read=True,
    broadcast_ping=True, spec_type=_spec_type(XM430_W350_TABLE),
    firmware_item="firmware_version", limit_items=("min_position_limit", "max_position_limit"),
    servo_model=XServoModel,
    aliases=("2", "2.0", "protocol2", "dynamixel2"),
)
STS = ServoFamily(
    key="sts", title="Feetech STS", protocol="sts", codec=ft, tables=STS_TABLES,
    default_table=STS3215_TABLE, table_for=sts_table_for, model_address=3, ping_data=0,
    status_overhead=ft.OVERHEAD, id_offset=2, group_read=True, broadcast_ping=False,
    spec_type=_spec_type(STS3215_TABLE), firmware_item="firmware_major",
    limit_items=("min_position_limit", "max_position_limit"),
    servo_model=StsServoModel,
    replies_all_level=1,
    aliases=("feetech", "scs", "sms_sts"),
)
#: Every family the lab drives, in the order a scan tries them.
FAMILIES: tuple[ServoFamily, ...] = (DYNAMIXEL1, XSERIES, STS)


def family(which: int | float | str | ServoFamily) -> ServoFamily:
    """The family named by a protocol tag (1, 2.0, "sts"), a key or alias, or a family
    itself; ValueError listing the known ones otherwise."""
    if isinstance(which, ServoFamily):
        return which
    if isinstance(which, float) and which.is_integer():
        which = int(which)
    for f in FAMILIES:
        if which == f.protocol or (isinstance(which, str) and
                                   which.lower() in (f.key, str(f.protocol), *f.aliases)):
            return f
    raise ValueError(f"unknown servo family or protocol {which!r}; known: "
                     + ", ".join(f"{f.protocol!r} ({f.title})" for f in FAMILIES))


def family_of_model(model: int | str) -> ServoFamily:
    """The family one model (number or name) belongs to; ValueError listing every model."""
    for f in FAMILIES:
        if f.knows(model):
            return f
    tables = [t for f in FAMILIES for t in f.tables.values()]
    if isinstance(model, str):
        raise ValueError(f"unknown servo model {model!r}; known: "
                         f"{', '.join(t.name for t in tables)}")
    raise ValueError(f"unknown servo model number {model}; known: " + ", ".join(
        f"{t.spec.model_number} ({t.name})" for t in tables))


def family_of_spec(spec: object) -> ServoFamily:
    """The family of a datasheet object (a ``ServoSpec``, ``XSpec`` or ``StsSpec``)."""
    for f in FAMILIES:
        if isinstance(spec, f.spec_type):
            return f
    raise ValueError(f"{spec!r} is no servo datasheet the lab knows")


def servo_table(model: int | str) -> ControlTable:
    """The control table of any model the lab knows (number or name)."""
    return family_of_model(model).table_for(model)
