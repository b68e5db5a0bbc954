"""Control tables of the AX-12A and RX-24F (thesis Table 2.1, ROBOTIS e-manual).

Both models share one layout (addresses 0..49); they differ in defaults (baud,
temperature and voltage limits) and in their :class:`~armlab.hardware.servos.servo_spec.ServoSpec`.
An :class:`Item` knows its address, size, access, area, allowed range and
default; :class:`ControlTable` encodes and checks writes *before* any byte is
sent, and converts raw values to SI through the ServoSpec (one home for the
conversions). The thesis's Table 2.1 has a typo at address 29 (it is the CCW
compliance *slope*).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from armlab.hardware.servos.servo_spec import (
    AX12A,
    RETURN_DELAY_UNIT,
    RX24F,
    ServoSpec,
    baud_from_value,
    value_from_baud,
)

EEPROM = "EEPROM"
RAM = "RAM"
TABLE_SIZE = 50  #: addresses 0..49
LOCKED_WRITABLE = range(24, 36)  #: with Lock = 1 only addresses 24..35 accept writes
#: Thesis §2.3 "Set Compliance Margin and Slope": margins 0, slopes 64 (0x40).
THESIS_COMPLIANCE_MARGIN = 0
THESIS_COMPLIANCE_SLOPE = 64


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


def _items(*, baud: int, temperature_limit: int, max_voltage: int) -> tuple[Item, ...]:
    E, R = EEPROM, RAM
    return (
        Item("model_number", 0, 2, False, E, 0, 0xFFFF, None),
        Item("firmware_version", 2, 1, False, E, 0, 255, None),
        Item("id", 3, 1, True, E, 0, 253, 1),
        Item("baud_rate", 4, 1, True, E, 0, 254, baud, "baud"),
        Item("return_delay_time", 5, 1, True, E, 0, 254, 250, "delay"),
        Item("cw_angle_limit", 6, 2, True, E, 0, 1023, 0, "position"),
        Item("ccw_angle_limit", 8, 2, True, E, 0, 1023, 1023, "position"),
        Item("temperature_limit", 11, 1, True, E, 0, 150, temperature_limit, "celsius"),
        Item("min_voltage_limit", 12, 1, True, E, 50, 250, 60, "voltage"),
        Item("max_voltage_limit", 13, 1, True, E, 50, 250, max_voltage, "voltage"),
        Item("max_torque", 14, 2, True, E, 0, 1023, 1023, "torque"),
        Item("status_return_level", 16, 1, True, E, 0, 2, 2),
        Item("alarm_led", 17, 1, True, E, 0, 127, 36),
        Item("alarm_shutdown", 18, 1, True, E, 0, 127, 36),
        Item("torque_enable", 24, 1, True, R, 0, 1, 0),
        Item("led", 25, 1, True, R, 0, 1, 0),
        Item("cw_compliance_margin", 26, 1, True, R, 0, 255, 1),
        Item("ccw_compliance_margin", 27, 1, True, R, 0, 255, 1),
        Item("cw_compliance_slope", 28, 1, True, R, 0, 254, 32),
        Item("ccw_compliance_slope", 29, 1, True, R, 0, 254, 32),
        Item("goal_position", 30, 2, True, R, 0, 1023, None, "position"),
        Item("moving_speed", 32, 2, True, R, 0, 2047, 0, "speed_limit"),
        Item("torque_limit", 34, 2, True, R, 0, 1023, None, "torque"),
        Item("present_position", 36, 2, False, R, 0, 1023, None, "position"),
        Item("present_speed", 38, 2, False, R, 0, 2047, None, "present_speed"),
        Item("present_load", 40, 2, False, R, 0, 2047, None, "load"),
        Item("present_voltage", 42, 1, False, R, 0, 255, None, "voltage"),
        Item("present_temperature", 43, 1, False, R, 0, 255, None, "celsius"),
        Item("registered", 44, 1, False, R, 0, 1, 0),
        Item("moving", 46, 1, False, R, 0, 1, 0),
        Item("lock", 47, 1, True, R, 0, 1, 0),
        Item("punch", 48, 2, True, R, 0, 1023, 32),
    )


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
        """Power-on image of the table (50 bytes) with the factory EEPROM values.

        Goal position starts at the present position and the torque limit at
        max torque, as the servo copies them at power-on.
        """
        mem = bytearray(TABLE_SIZE)
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


AX12A_TABLE = ControlTable(AX12A, _items(baud=1, temperature_limit=70, max_voltage=140))
RX24F_TABLE = ControlTable(RX24F, _items(baud=34, temperature_limit=80, max_voltage=190))
TABLES = {t.spec.model_number: t for t in (AX12A_TABLE, RX24F_TABLE)}


def table_for(model: int | str | ServoSpec) -> ControlTable:
    """The table of a model given as number (12, 24), name ("AX-12A", "ax12a", "rx24f") or spec."""
    if isinstance(model, ServoSpec):
        model = model.model_number
    if isinstance(model, str):
        key = model.upper().replace("-", "").replace("_", "")
        for t in TABLES.values():
            if t.name.replace("-", "") == key or t.name.replace("-", "")[:4] == key:
                return t
        raise ValueError(f"unknown servo model {model!r}; known: AX-12A, RX-24F")
    if int(model) not in TABLES:
        raise ValueError(f"unknown servo model number {model}; known: 12 (AX-12A), 24 (RX-24F)")
    return TABLES[int(model)]
