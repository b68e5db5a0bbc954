"""Dynamixel RX-24F and AX-12A: datasheet numbers and raw-register conversions.

One home for the datasheet numbers (ROBOTIS e-manual, RX-24F and AX-12A pages;
docs/servo-model.md), used by the servo model, the control tables, the emulator
and the backends. A *joint-side* angle
here is the servo horn's angle from its centre (raw 512), counter-clockwise
positive (raw counts increase CCW); mapping servo to robot joint (direction
sign, zero offset) is the backend's business.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

RPM = 2.0 * np.pi / 60.0  #: rad/s per rpm
DIRECTION_BIT = 1 << 10  #: bit 10 of Present Speed / Present Load: 1 = clockwise
RETURN_DELAY_UNIT = 2e-6  #: s per Return Delay Time unit (address 5, thesis §2.3)


def wire_time(n_bytes: int, baud: float) -> float:
    """Seconds ``n_bytes`` take on an 8N1 line (10 bits a byte): 10 µs a byte at 1 Mbps."""
    return n_bytes * 10.0 / baud


#: A 12-bit magnetic encoder (the X-series', Feetech STS's): position counts per turn,
#: the horn's centre, rad per count (0.088°).
COUNTS = 4096
CENTRE = 2048
POSITION_UNIT = 2.0 * math.pi / COUNTS


class TurnEncoder:
    """The position conversions of a servo whose 12-bit magnetic encoder counts 4096 a
    turn, 2048 at the horn's centre (the X-series, Feetech's STS): one home for both
    families' datasheet classes."""

    position_unit = POSITION_UNIT
    position_range = 2.0 * math.pi  #: rad covered by 0..4095 (one turn)

    def position_to_raw(self, angle: float) -> int:
        """Horn angle from the centre, rad -> position count (not clamped)."""
        return int(round(CENTRE + angle / POSITION_UNIT))

    def raw_to_position(self, raw: int) -> float:
        """Position count (signed) -> horn angle from the centre, rad."""
        return (int(raw) - CENTRE) * POSITION_UNIT


def signed_word(units: float) -> int:
    """Signed magnitude in register units -> Present Speed/Load word (0..1023, bit 10 = CW)."""
    a = abs(units)
    mag = 1023 if a >= 1023.0 else round(a)  # round: half to even, as np.rint
    return mag | (DIRECTION_BIT if units < 0 and mag else 0)


def clamped_count(units: float, lo: int, hi: int) -> int:
    """``units`` rounded half to even (as ``np.rint``) and clamped into [lo, hi]: a register
    value. NaN raises ValueError. (Plain floats: this runs for every servo every period.)"""
    return int(round(min(max(units, float(lo)), float(hi))))


def word_to_signed(raw: int) -> int:
    """Present Speed/Load word -> signed magnitude in register units (CCW positive)."""
    raw = int(raw)
    return -(raw & 0x3FF) if raw & DIRECTION_BIT else raw & 0x3FF


def load_fraction(raw: int) -> float:
    """Present Load word -> signed fraction of the maximum torque (−1..1, CCW positive)."""
    return word_to_signed(raw) / 1023.0


@dataclass(frozen=True)
class ServoSpec:
    """Datasheet of one Dynamixel model (protocol 1.0).

    Attributes:
        name: "RX-24F" or "AX-12A".
        model_number: control-table address 0 value (24 or 12).
        stall_torque: N·m at 12 V.
        no_load_speed: rad/s at the horn at 12 V.
        gear_ratio: motor turns per horn turn.
        default_baud_value: EEPROM address 4 factory value.
        temperature_limit: °C (address 11 default).
        max_voltage: V (address 13 default ×0.1).
        position_range: rad covered by raw 0..1023 (300°).
        speed_unit: rad/s per Moving/Present Speed unit (0.111 rpm).
    """

    name: str
    model_number: int
    stall_torque: float
    no_load_speed: float
    gear_ratio: float
    default_baud_value: int
    temperature_limit: int
    max_voltage: float
    position_range: float = math.radians(300.0)  # a Python float: numpy scalars are slow
    speed_unit: float = 0.111 * RPM

    @cached_property  # read for every servo every period
    def position_unit(self) -> float:
        """rad per position count (300° / 1023 ≈ 0.29°)."""
        return self.position_range / 1023.0

    def position_to_raw(self, angle: float) -> int:
        """Joint-side angle (rad from centre) -> goal position 0..1023, rounded and clamped."""
        return clamped_count(512.0 + float(angle) / self.position_unit, 0, 1023)

    def raw_to_position(self, raw: int) -> float:
        """Position count 0..1023 -> rad from centre."""
        return (int(raw) - 512) * self.position_unit

    def speed_to_raw(self, speed: float) -> int:
        """Moving-speed magnitude rad/s -> 1..1023 (never 0, which means "no limit").

        ``inf`` asks for the fastest setting: 0 (no speed control).
        """
        speed = float(speed)
        if math.isinf(speed):
            return 0
        return clamped_count(abs(speed) / self.speed_unit, 1, 1023)

    def raw_to_speed_limit(self, raw: int) -> float:
        """Moving Speed register -> rad/s limit (0 -> the no-load speed: no control)."""
        raw = int(raw) & 0x3FF
        return self.no_load_speed if raw == 0 else min(raw * self.speed_unit, self.no_load_speed)

    def present_speed_to_raw(self, velocity: float) -> int:
        """Signed rad/s -> Present Speed word (magnitude 0..1023, bit 10 set when CW)."""
        return signed_word(velocity / self.speed_unit)

    def raw_to_present_speed(self, raw: int) -> float:
        """Present Speed word -> signed rad/s (CCW positive)."""
        return word_to_signed(raw) * self.speed_unit

    def raw_to_load(self, raw: int) -> float:
        """Present Load word -> signed N·m (CCW positive)."""
        return load_fraction(raw) * self.stall_torque

    def torque_limit_to_raw(self, torque: float) -> int:
        """N·m -> Torque Limit / Max Torque register 0..1023."""
        return clamped_count(float(torque) / self.stall_torque * 1023.0, 0, 1023)

    def raw_to_torque_limit(self, raw: int) -> float:
        """Torque Limit register -> N·m."""
        return (int(raw) & 0x3FF) / 1023.0 * self.stall_torque


#: Stall torque 2.6 N·m: the ROBOTIS e-manual's SI figure (12 V, 2.4 A). The thesis prints
#: 26 kgf·cm = 2.55 N·m, the same datasheet value given to two figures in kgf·cm (25.5 to
#: 26.5 kgf·cm, i.e. 2.50 to 2.60 N·m, holds 2.6). The lab keeps 2.6 so that Present Load
#: decodes as ROBOTIS defines it (1023 = stall); in kgf·cm the thesis's torques differ by
#: 2 %, below the ~1.5 kgf·cm torque error chapter 4 reports.
RX24F = ServoSpec(
    name="RX-24F", model_number=24, stall_torque=2.6, no_load_speed=126 * RPM,
    gear_ratio=193.0, default_baud_value=34, temperature_limit=80, max_voltage=19.0,
)
AX12A = ServoSpec(
    name="AX-12A", model_number=12, stall_torque=1.5, no_load_speed=59 * RPM,
    gear_ratio=254.0, default_baud_value=1, temperature_limit=70, max_voltage=14.0,
)


def baud_from_value(value: int) -> float:
    """EEPROM baud value -> bit/s: 2 000 000 / (value + 1) (thesis §2.3)."""
    return 2_000_000 / (int(value) + 1)


def value_from_baud(baud: float) -> int:
    """bit/s -> EEPROM baud value; ValueError when no value gives that rate within 3 %."""
    value = int(round(2_000_000 / baud - 1))
    if not 0 <= value <= 254 or abs(baud_from_value(value) - baud) / baud > 0.03:
        raise ValueError(f"baud {baud:g} is not a Dynamixel rate (2 000 000 / (n + 1))")
    return value
