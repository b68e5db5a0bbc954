"""A servo's control table read and written by name through a bus: raw values, SI values,
a span of items in one READ, SYNC_WRITE chunks packed from raw values, and the servo's
model identified from its model number.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import TYPE_CHECKING

from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import ServoFamily, Status
from armlab.hardware.wire.errors import WrongModel


def sync_data(values: dict[int, tuple[int, ...]], sizes: tuple[int, ...]) -> dict[int, bytes]:
    """Pack raw item values per servo into SYNC_WRITE chunks (little-endian, given sizes)."""
    out = {}
    for servo_id, vals in values.items():
        out[servo_id] = b"".join(struct.pack("<H" if s == 2 else "<B", v)
                                 for v, s in zip(vals, sizes, strict=True))
    return out


class NamedItems:
    """A bus's reads and writes of control-table items by name (mixed into
    :class:`~armlab.hardware.wire.bus.Bus`, whose transactions it calls)."""

    if TYPE_CHECKING:  # the bus's, for mypy only
        family: ServoFamily
        table: ControlTable
        tables: dict[int, ControlTable]
        status_return_level: dict[int, int]
        return_delay: dict[int, int]

        def read_bytes(self, servo_id: int, address: int, length: int) -> bytes: ...
        def write_bytes(self, servo_id: int, address: int, data: bytes) -> Status | None: ...
        def write_unanswered(self, servo_id: int, address: int, data: bytes) -> None: ...

    def table_of(self, servo_id: int) -> ControlTable:
        """The control table of an identified servo, else the bus's default table."""
        return self.tables.get(servo_id, self.table)

    def read(self, servo_id: int, name: str) -> int:
        """Raw value of a control-table item, e.g. ``bus.read(1, "present_position")``."""
        table = self.table_of(servo_id)
        item = table.item(name)
        return table.decode(name, self.read_bytes(servo_id, item.address, item.size))

    def read_items(self, servo_id: int, names: Sequence[str]) -> dict[str, int]:
        """Raw values of control-table items ``names`` (in address order) in one READ of the
        span from the first to the last: a reply of the span's own length, which a late
        answer to an earlier, shorter request cannot pass for (limits read one by one
        could take another servo's word for a limit)."""
        table = self.table_of(servo_id)
        first, last = table.item(names[0]), table.item(names[-1])
        raw = self.read_bytes(servo_id, first.address,
                              last.address + last.size - first.address)
        return {n: table.decode(n, raw[table.item(n).address - first.address:]) for n in names}

    def read_si(self, servo_id: int, name: str) -> float:
        """An item converted to SI (rad, rad/s, N·m, V, °C, s, bit/s)."""
        return self.table_of(servo_id).to_si(name, self.read(servo_id, name))

    def write(self, servo_id: int, name: str, value: int) -> None:
        """Write a raw value to an item; ValueError (nothing sent) if read-only or out of range.

        The status return level is written without waiting for a reply (whether
        the servo answers that very write depends on the level it is changing).
        """
        table = self.table_of(servo_id)
        address, data = table.encode(name, value)
        if name == "status_return_level":
            self.write_unanswered(servo_id, address, data)
            self.status_return_level[servo_id] = int(value)
            return
        self.write_bytes(servo_id, address, data)
        if name == "return_delay_time":
            self.return_delay[servo_id] = int(value)

    def write_si(self, servo_id: int, name: str, value: float) -> None:
        """Write an SI value (converted by the servo's ServoSpec) to an item."""
        self.write(servo_id, name, self.table_of(servo_id).from_si(name, value))

    def identify(self, servo_id: int, *, expect: int | str | None = None) -> ControlTable:
        """Read the model number of ``servo_id`` and remember its table.

        Raises :class:`WrongModel` when ``expect`` (model number or name) differs.
        """
        model = self.read(servo_id, "model_number")  # same address across a family
        known = self.family.tables
        if expect is not None:
            want = self.family.table_for(expect)
            if model != want.spec.model_number:
                found = known[model].name if model in known else "unknown model"
                raise WrongModel(
                    f"servo {servo_id} is a {found} (model number {model}), expected a "
                    f"{want.name} ({want.spec.model_number}): fix the joint map or --servo"
                )
        if model not in known:
            names = " or ".join(f"{t.name} ({k})" for k, t in known.items())
            raise WrongModel(
                f"servo {servo_id} has model number {model}, not a "
                f"{self.family.title} servo the lab knows: {names}"
            )
        table = known[model]
        self.tables[servo_id] = table
        return table
