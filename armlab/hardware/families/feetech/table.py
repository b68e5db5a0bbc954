"""Feetech STS3215 (the SO-101's servo): its datasheet and its control table.

Addresses and sizes: Feetech's FTServo SDK (``scservo_sdk/sms_sts.py``, the ``SMS_STS_*``
addresses; github.com/ftservo/FTServo_Python at a203373) and LeRobot's
``src/lerobot/motors/feetech/tables.py`` (``STS_SMS_SERIES_CONTROL_TABLE``; github.com/
huggingface/lerobot at 7427f31), which agree on every address used here: model number 3
(2 bytes; 777 = STS3215, LeRobot ``MODEL_NUMBER_TABLE``), ID 5, baud 6, return delay 7,
response status level 8, min/max position limit 9/11, max temperature 13, max/min voltage
14/15, max torque 16, P/D/I coefficients 21/22/23, protection current 28, homing offset
31, operating mode 33, overload torque 36, torque enable 40, acceleration 41, goal
position 42, goal time 44, goal speed 46, torque limit 48, lock 55, present position 56,
speed 58, load 60, voltage 62, temperature 63, status 65, moving 66, present current 69.

Encodings (LeRobot ``STS_SMS_SERIES_ENCODINGS_TABLE``; the SDK's ``scs_toscs(value,
15)`` for positions and speeds): sign-magnitude, the sign in bit 15 of positions and
speeds, bit 11 of Homing Offset and bit 10 of Present Load (not bit 15: the load's
magnitude is 0..1000). Units: position 4096 counts a turn (LeRobot ``MODEL_RESOLUTION``),
speed in counts per second (50 counts/s = 0.732 rpm), load and torque limits in 0.1 % of
the maximum torque, voltage 0.1 V, current 6.5 mA a count (Feetech's memory table, as
quoted by the SO-101 community; not checked against a Feetech PDF here).

Baud codes: the SDK's ``SMS_STS_1M`` ... ``SMS_STS_38400`` (0 = 1 Mbps, 1 = 500 k,
2 = 250 k, 3 = 128 k, 4 = 115 200, 5 = 76 800, 6 = 57 600, 7 = 38 400). LeRobot's
``STS_SMS_SERIES_BAUDRATE_TABLE`` has 5 = 57 600, 6 = 38 400, 7 = 19 200 instead; the
lab follows the manufacturer's SDK.

Factory values of items neither source states (limits, coefficients other than P) are
the emulator's assumptions, marked as such below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from armlab.hardware.families.feetech.packets import (
    ErrorBits,
    decode_sign_magnitude,
    describe_errors,
    encode_sign_magnitude,
)
from armlab.hardware.servos.control_table import EEPROM, RAM, ControlTable, Item
from armlab.hardware.servos.servo_spec import (  # the 4096-count encoder's, one home
    CENTRE,
    COUNTS,
    POSITION_UNIT,
    RETURN_DELAY_UNIT,
    RPM,
    TurnEncoder,
)

SPEED_UNIT = POSITION_UNIT  #: rad/s per Goal/Present Speed count (counts per second)
LOAD_UNIT = 0.001  #: fraction of the maximum torque per load/torque-limit count
CURRENT_UNIT = 6.5e-3  #: A per Present Current count
KGF_CM = 0.0980665  #: N·m per kgf·cm
#: Baud Rate (address 6) value -> bit/s (FTServo SDK ``sms_sts.py``).
BAUDS = {0: 1_000_000, 1: 500_000, 2: 250_000, 3: 128_000, 4: 115_200, 5: 76_800,
         6: 57_600, 7: 38_400}
#: Item -> its sign bit (sign-magnitude items).
SIGN_BITS = {"homing_offset": 11, "goal_position": 15, "goal_speed": 15,
             "present_position": 15, "present_speed": 15, "present_load": 10}


class OperatingMode:
    """Operating Mode (address 33) values (LeRobot ``feetech.OperatingMode``)."""

    POSITION = 0
    VELOCITY = 1
    PWM = 2
    STEP = 3


@dataclass(frozen=True)
class StsSpec(TurnEncoder):
    """Datasheet of one STS model.

    Attributes:
        name: "STS3215".
        model_number: address 3's value (777).
        stall_torque: N·m at ``voltage``.
        stall_current: A at ``voltage``.
        no_load_speed: rad/s at the horn at ``voltage``.
        voltage: the supply the figures are given at, V.
        gear_ratio: motor turns per horn turn.
    """

    name: str
    model_number: int
    stall_torque: float
    stall_current: float
    no_load_speed: float
    voltage: float
    gear_ratio: float

    current_unit = CURRENT_UNIT
    has_current = True

    @property
    def torque_constant(self) -> float:
        """N·m per A at the horn (stall torque / stall current)."""
        return self.stall_torque / self.stall_current

    def speed_to_raw(self, speed: float) -> int:
        """rad/s -> speed count (signed; 0 = the servo's maximum as a goal)."""
        return int(round(speed / SPEED_UNIT))

    def raw_to_speed(self, raw: int) -> float:
        """Speed count (signed) -> rad/s, CCW positive."""
        return int(raw) * SPEED_UNIT

    def raw_to_current(self, raw: int) -> float:
        """Present Current count -> A."""
        return int(raw) * CURRENT_UNIT

    def raw_to_torque(self, raw: int) -> float:
        """Present Current count -> N·m at the horn through the torque constant."""
        return self.raw_to_current(raw) * self.torque_constant

    def signed_torque(self, current: int, load: int) -> float:
        """N·m at the horn from Present Current (a magnitude) signed as Present Load (the
        PWM duty): the servo's torque reading (*interpretation*: Feetech documents no
        sign for the current); 0 while the duty is 0."""
        return math.copysign(self.raw_to_torque(current), load) if load else 0.0

    def goal_speed_to_raw(self, speed: float) -> int:
        """A goal's speed rad/s -> Goal Speed counts: its magnitude, at least 1 count, at
        most the 15-bit field; 0 stays 0 (no limit, as on the Dynamixels)."""
        if speed == 0:
            return 0
        return min(max(round(abs(speed) / SPEED_UNIT), 1), (1 << 15) - 1)

    def raw_to_load(self, raw: int) -> float:
        """Present Load / Torque Limit count (0.1 % of the maximum, signed) -> N·m."""
        return int(raw) * LOAD_UNIT * self.stall_torque


#: STS3215, the 7.4 V version with the 1:345 gear (C001) the SO-101 follower uses
#: (LeRobot docs/source/so101.mdx: "6x STS3215 motors with 1/345 gearing").
#: Stall torque 16.5 kgf·cm at 6 V: TheRobotStudio SO-ARM100 README ("The 7.4V has a stall
#: torque of 16.5kg.cm at 6V"); the arm runs from a 5 V supply (same README), which the
#: simulation scales to. No-load speed 45 rpm (0.222 s/60°): Feetech's figure for the
#: 12 V STS3215 (C018, same 1:345 gear), as quoted by Robonine's test of the servo; taken
#: here at 6 V for the 7.4 V motor — an *estimate*. Stall current 2.7 A: Waveshare's ST3215
#: page (12 V version), also an *estimate* for this motor; it sets the torque constant the
#: current reading is turned into N·m with.
STS3215 = StsSpec("STS3215", 777, stall_torque=16.5 * KGF_CM, stall_current=2.7,
                  no_load_speed=45 * RPM, voltage=6.0, gear_ratio=345.0)


@dataclass(frozen=True)
class StsItem(Item):
    """A control-table item; ``sign_bit``: the bit holding the sign of a sign-magnitude
    value (None: unsigned)."""

    sign_bit: int | None = None


TABLE_SIZE = 71  #: addresses 0..70 (the image the emulator keeps)


def _items() -> tuple[Item, ...]:
    E, R = EEPROM, RAM

    def item(name: str, address: int, size: int, writable: bool, area: str, lo: int,
             hi: int, default: int | None, unit: str = "") -> StsItem:
        sign = SIGN_BITS.get(name)
        return StsItem(name, address, size, writable, area, lo, hi, default, unit,
                       sign_bit=sign)

    top = (1 << 15) - 1
    return (
        item("firmware_major", 0, 1, False, E, 0, 255, None),
        item("firmware_minor", 1, 1, False, E, 0, 255, None),
        item("model_number", 3, 2, False, E, 0, 0xFFFF, None),
        item("id", 5, 1, True, E, 0, 252, 1),
        item("baud_rate", 6, 1, True, E, 0, 7, 0, "baud"),
        item("return_delay_time", 7, 1, True, E, 0, 254, 0, "delay"),  # assumed 0
        item("status_return_level", 8, 1, True, E, 0, 1, 1),
        item("min_position_limit", 9, 2, True, E, 0, COUNTS - 1, 0, "position"),
        item("max_position_limit", 11, 2, True, E, 0, COUNTS - 1, COUNTS - 1, "position"),
        item("temperature_limit", 13, 1, True, E, 0, 100, 70, "celsius"),  # assumed
        item("max_voltage_limit", 14, 1, True, E, 0, 254, 80, "voltage"),  # assumed
        item("min_voltage_limit", 15, 1, True, E, 0, 254, 40, "voltage"),  # assumed
        item("max_torque", 16, 2, True, E, 0, 1000, 1000, "load"),
        item("p_coefficient", 21, 1, True, E, 0, 254, 32),
        item("d_coefficient", 22, 1, True, E, 0, 254, 32),  # assumed
        item("i_coefficient", 23, 1, True, E, 0, 254, 0),  # assumed
        item("protection_current", 28, 2, True, E, 0, 511, 500, "current"),
        item("homing_offset", 31, 2, True, E, -2047, 2047, 0),
        item("operating_mode", 33, 1, True, E, 0, 3, OperatingMode.POSITION),
        item("overload_torque", 36, 1, True, E, 0, 100, 80),  # % of max, assumed
        item("torque_enable", 40, 1, True, R, 0, 1, 0),
        item("acceleration", 41, 1, True, R, 0, 254, 0),
        item("goal_position", 42, 2, True, R, -top, top, None, "position"),
        item("goal_time", 44, 2, True, R, 0, 0xFFFF, 0),
        item("goal_speed", 46, 2, True, R, -top, top, 0, "speed"),
        item("torque_limit", 48, 2, True, R, 0, 1000, None, "load"),
        item("lock", 55, 1, True, R, 0, 1, 1),
        item("present_position", 56, 2, False, R, -top, top, None, "position"),
        item("present_speed", 58, 2, False, R, -top, top, None, "speed"),
        item("present_load", 60, 2, False, R, -1023, 1023, None, "load"),
        item("present_voltage", 62, 1, False, R, 0, 255, None, "voltage"),
        item("present_temperature", 63, 1, False, R, 0, 255, None, "celsius"),
        item("status", 65, 1, False, R, 0, 255, 0),
        item("moving", 66, 1, False, R, 0, 1, 0),
        item("present_current", 69, 2, False, R, 0, 0xFFFF, None, "current"),
    )


@dataclass(frozen=True)
class StsControlTable(ControlTable):
    """The control table of an STS model: named access and range checks from
    :class:`ControlTable`, with sign-magnitude items and its own units."""

    if TYPE_CHECKING:  # for mypy only: the dataclass's fields stay the base's
        spec: StsSpec  # type: ignore[assignment]  # a family's table holds its own spec class

    def _raw(self, item: Item, value: int) -> int:
        sign = getattr(item, "sign_bit", None)
        return int(value) if sign is None else encode_sign_magnitude(value, sign)

    def encode(self, name: str, value: int) -> tuple[int, bytes]:
        """(address, little-endian bytes) for WRITE; ValueError, before anything is sent,
        for read-only items and values out of range."""
        item = self.item(name)
        if not item.writable:
            raise ValueError(f"{name} is read-only on the {self.name}")
        value = int(value)
        if not item.lo <= value <= item.hi:
            raise ValueError(f"{name}: {value} outside {item.lo}..{item.hi} on the {self.name}")
        return item.address, self._raw(item, value).to_bytes(item.size, "little")

    def decode(self, name: str, data: bytes) -> int:
        """Raw (signed where sign-magnitude) value of ``name`` from the bytes at its address."""
        item = self.item(name)
        raw = int.from_bytes(bytes(data[: item.size]), "little")
        sign = getattr(item, "sign_bit", None)
        return raw if sign is None else decode_sign_magnitude(raw, sign)

    def put(self, memory: bytearray, name: str, value: int) -> None:
        """Store ``value`` of ``name`` into a table image (no access or range check)."""
        item = self.item(name)
        memory[item.address : item.address + item.size] = \
            self._raw(item, value).to_bytes(item.size, "little")

    def defaults(self, *, firmware: int = 0, servo_id: int = 1,
                 present_position: int = CENTRE, baud_value: int | None = None) -> bytearray:
        """Power-on image (71 bytes): the factory values; goal position at the present
        position, torque limit at max torque."""
        mem = bytearray(TABLE_SIZE)
        given = {"model_number": self.spec.model_number, "firmware_major": firmware >> 8,
                 "firmware_minor": firmware & 0xFF, "id": servo_id,
                 "goal_position": present_position, "present_position": present_position,
                 "torque_limit": self.item("max_torque").default}
        if baud_value is not None:
            given["baud_rate"] = baud_value
        for item in self.items:
            value = given.get(item.name, item.default)
            if value is not None:
                self.put(mem, item.name, value)
        return mem

    def to_si(self, name: str, raw: int) -> float:
        """Raw value -> SI: rad, rad/s, N·m, A, V, °C, s, bit/s (plain numbers as is)."""
        unit = self.item(name).unit
        s: StsSpec = self.spec
        raw = int(raw)
        if unit == "position":
            return s.raw_to_position(raw)
        if unit == "speed":
            return s.raw_to_speed(raw)
        if unit == "load":
            return s.raw_to_load(raw)
        if unit == "current":
            return s.raw_to_current(raw)
        if unit == "voltage":
            return raw * 0.1
        if unit == "delay":
            return raw * RETURN_DELAY_UNIT
        if unit == "baud":
            return float(BAUDS[raw])
        return float(raw)

    def from_si(self, name: str, value: float) -> int:
        """SI value -> raw value for writing ``name`` (range-checked by :meth:`encode`)."""
        unit = self.item(name).unit
        s: StsSpec = self.spec
        if unit == "position":
            return s.position_to_raw(value)
        if unit == "speed":
            return s.speed_to_raw(value)
        if unit == "load":
            return int(round(value / s.stall_torque / LOAD_UNIT))
        if unit == "current":
            return int(round(value / CURRENT_UNIT))
        if unit == "voltage":
            return int(round(value * 10.0))
        if unit == "delay":
            return int(round(value / RETURN_DELAY_UNIT))
        if unit == "baud":
            for k, b in BAUDS.items():
                if abs(b - value) <= 0.03 * b:
                    return k
            raise ValueError(f"{value:g} bit/s is not an STS baud rate "
                             f"({', '.join(map(str, BAUDS.values()))})")
        return int(round(value))


#: The P coefficient the lab configures (LeRobot's for the SO-101, ``so_follower.py``
#: ``configure``: 16, "to avoid shakiness"; the factory's 32), with the factory D and I 0.
LAB_P_COEFFICIENT = 16
LAB_D_COEFFICIENT = 32
LAB_I_COEFFICIENT = 0
def lab_settings(table: StsControlTable, *, torque_limit: float
                 ) -> tuple[tuple[str, int, str], ...]:
    """The items the lab sets on an STS servo of ``table``'s model, as (item, raw value, a
    line for the log): position mode, the position loop's P, D, I coefficients, no
    acceleration limit (every goal comes with its speed) and Torque Limit at
    ``torque_limit`` (a fraction) of the maximum. The STS backend writes them to real
    servos (the EEPROM ones only when they differ); the simulator sets them in its
    firmware model's registers."""
    raw = round(torque_limit * table.item("max_torque").default)  # type: ignore[operator]  # the tables give these items a default
    return (
        ("operating_mode", OperatingMode.POSITION, "operating mode 0 (position)"),
        ("p_coefficient", LAB_P_COEFFICIENT,
         f"P coefficient {LAB_P_COEFFICIENT} (LeRobot's for the SO-101; factory 32)"),
        ("d_coefficient", LAB_D_COEFFICIENT, f"D coefficient {LAB_D_COEFFICIENT}"),
        ("i_coefficient", LAB_I_COEFFICIENT, f"I coefficient {LAB_I_COEFFICIENT}"),
        ("acceleration", 0, "acceleration 0 (no limit: each goal has its speed)"),
        ("torque_limit", raw, f"torque limit {torque_limit:.0%} ({raw} of 1000)"),
    )


#: What to do about each status error bit (an STS status byte flags the servo's state,
#: never a refused write; the lab stops the arm on any of them).
_WAY_BACK = {"overload": "switch its torque off and on (Reset) once the load is gone",
             "overheat": "let it cool, then Reset",
             "voltage": "check the supply (the SO-101's is 5 V), then Reset",
             "angle": "its position sensor failed: power it off and check it",
             "overcurrent": "check the load and the wiring, then Reset"}


def sts_alarm(bits: int, *, servo_id: int | None = None) -> str:
    """What a person is told about an STS servo's status error ``bits``: the servo, the
    flags and what to do, e.g. "servo 2: overload (0x20): switch its torque off and on
    (Reset) once the load is gone"; "" for no bits."""
    if not bits:
        return ""
    who = "" if servo_id is None else f"servo {servo_id}: "
    flags = ErrorBits(int(bits) & 0x7F)
    ways = [way for name, way in _WAY_BACK.items() if ErrorBits[name.upper()] in flags]
    return f"{who}{describe_errors(bits)}" + (f": {'; '.join(ways)}" if ways else "")


STS3215_TABLE = StsControlTable(STS3215, _items())
STS_TABLES = {t.spec.model_number: t for t in (STS3215_TABLE,)}


def sts_table_for(model: int | str) -> StsControlTable:
    """The table of an STS model given as number (777) or name ("STS3215", "sts3215")."""
    if isinstance(model, str):
        key = model.upper().replace("-", "").replace("_", "")
        for t in STS_TABLES.values():
            if t.name == key:
                return t
        raise ValueError(f"unknown STS model {model!r}; known: "
                         f"{', '.join(t.name for t in STS_TABLES.values())}")
    if int(model) not in STS_TABLES:
        raise ValueError(f"unknown STS model number {model}; known: "
                         f"{', '.join(f'{k} ({t.name})' for k, t in STS_TABLES.items())}")
    return STS_TABLES[int(model)]
