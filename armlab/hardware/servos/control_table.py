"""A servo's control table: its items (address, size, access, area, range, default) and the
encoding and checking of writes before any byte is sent, raw values converted to SI
through the model's datasheet (one home for the conversions). Each family's tables are
built of these (:mod:`armlab.hardware.families`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from armlab.hardware.servos.servo_spec import (
    RETURN_DELAY_UNIT,
    ServoSpec,
    baud_from_value,
    value_from_baud,
)

EEPROM = "EEPROM"


RAM = "RAM"


@dataclass(frozen=True)
class Item:
    """One control-table item.

    Attributes:
        name: snake_case name, e.g. "present_position".
        address: first byte.
        size: 1 or 2 bytes (little-endian).
        writable: False for read-only items.
        area: "EEPROM" (kept across power cycles) or "RAM" (reset at power-on).
        lo, hi: allowed raw range for writes.
        default: factory/power-on value; None when it is copied at power-on
            (goal position <- present position, torque limit <- max torque).
        unit: how :meth:`ControlTable.to_si` converts it ("position", "speed_limit",
            "present_speed", "load", "torque", "voltage", "celsius", "delay", "baud",
            or "" for plain numbers).
        signed: the bytes hold a two's-complement value (X-series velocities, currents).
    """

    name: str
    address: int
    size: int
    writable: bool
    area: str
    lo: int
    hi: int
    default: int | None
    unit: str = ""
    signed: bool = False

    @property
    def addresses(self) -> range:
        return range(self.address, self.address + self.size)


@dataclass(frozen=True)
class ControlTable:
    """The control table of one servo model.

    Attributes:
        spec: the model's datasheet and raw<->SI conversions.
        items: every item, by address.
    """

    spec: ServoSpec
    items: tuple[Item, ...]
    _by_name: dict[str, Item] = field(init=False, repr=False, compare=False)
    _by_address: dict[int, Item] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_by_name", {i.name: i for i in self.items})
        object.__setattr__(
            self, "_by_address", {a: i for i in self.items for a in i.addresses}
        )

    @property
    def name(self) -> str:
        return self.spec.name

    def item(self, name: str) -> Item:
        """The item called ``name``; ValueError listing the known names otherwise."""
        try:
            return self._by_name[name]
        except KeyError:
            raise ValueError(
                f"unknown control-table item {name!r} for {self.name}; "
                f"known: {', '.join(self._by_name)}"
            ) from None

    def at(self, address: int) -> Item | None:
        """The item that owns byte ``address`` (None for reserved bytes)."""
        return self._by_address.get(address)

    def encode(self, name: str, value: int) -> tuple[int, bytes]:
        """(address, little-endian bytes) to WRITE ``value`` into item ``name``.

        Raises ValueError, before anything is sent, for read-only items and values
        outside the item's range.
        """
        item = self.item(name)
        if not item.writable:
            raise ValueError(f"{name} is read-only on the {self.name}")
        value = int(value)
        if not item.lo <= value <= item.hi:
            raise ValueError(
                f"{name}: {value} outside {item.lo}..{item.hi} on the {self.name}"
            )
        return item.address, value.to_bytes(item.size, "little", signed=item.signed)

    def decode(self, name: str, data: bytes) -> int:
        """Raw value of item ``name`` from the bytes read at its address."""
        item = self.item(name)
        return int.from_bytes(bytes(data[: item.size]), "little", signed=item.signed)

    def value_at(self, memory: bytes | bytearray, name: str) -> int:
        """Raw value of item ``name`` in a whole-table image ``memory`` (:meth:`decode` of
        its bytes: a family's own decoding holds here too)."""
        item = self.item(name)
        return self.decode(name, bytes(memory[item.address : item.address + item.size]))

    def defaults(self, *, firmware: int = 0, servo_id: int = 1, present_position: int = 512,
                 baud_value: int | None = None) -> bytearray:
        """Power-on image of the table (to its last item's end) with the factory EEPROM values.

        Goal position starts at the present position and the torque limit at
        max torque, as the servo copies them at power-on.
        """
        mem = bytearray(max(item.address + item.size for item in self.items))
        for item in self.items:
            value = item.default
            if item.name == "model_number":
                value = self.spec.model_number
            elif item.name == "firmware_version":
                value = firmware
            elif item.name == "id":
                value = servo_id
            elif item.name == "baud_rate" and baud_value is not None:
                value = baud_value
            elif item.name in ("goal_position", "present_position"):
                value = present_position
            if value is not None:
                mem[item.address : item.address + item.size] = int(value).to_bytes(
                    item.size, "little"
                )
        mem[34:36] = mem[14:16]  # torque limit <- max torque
        return mem

    def to_si(self, name: str, raw: int) -> float:
        """Raw register value -> SI: rad, rad/s, N·m, V, °C, s, bit/s (plain numbers as is)."""
        unit = self.item(name).unit
        s = self.spec
        raw = int(raw)
        if unit == "position":
            return s.raw_to_position(raw)
        if unit == "speed_limit":
            return s.raw_to_speed_limit(raw)
        if unit == "present_speed":
            return s.raw_to_present_speed(raw)
        if unit == "load":
            return s.raw_to_load(raw)
        if unit == "torque":
            return s.raw_to_torque_limit(raw)
        if unit == "voltage":
            return raw * 0.1
        if unit == "delay":
            return raw * RETURN_DELAY_UNIT
        if unit == "baud":
            return baud_from_value(raw)
        return float(raw)

    def from_si(self, name: str, value: float) -> int:
        """SI value -> raw register value for writing item ``name`` (range-checked by encode)."""
        unit = self.item(name).unit
        s = self.spec
        if unit == "position":
            return s.position_to_raw(value)
        if unit == "speed_limit":
            return s.speed_to_raw(value)
        if unit == "torque":
            return s.torque_limit_to_raw(value)
        if unit == "voltage":
            return int(round(value * 10.0))
        if unit == "delay":
            return int(round(value / RETURN_DELAY_UNIT))
        if unit in ("present_speed", "load"):
            raise ValueError(f"{name} is read-only on the {self.name}")
        if unit == "baud":
            return value_from_baud(value)
        return int(round(value))
