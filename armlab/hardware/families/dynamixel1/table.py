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

from armlab.hardware.servos.control_table import EEPROM, RAM, ControlTable, Item
from armlab.hardware.servos.servo_spec import (
    AX12A,
    RX24F,
    ServoSpec,
)

TABLE_SIZE = 50  #: addresses 0..49


LOCKED_WRITABLE = range(24, 36)  #: with Lock = 1 only addresses 24..35 accept writes


#: Thesis §2.3 "Set Compliance Margin and Slope": margins 0, slopes 64 (0x40).
THESIS_COMPLIANCE_MARGIN = 0


THESIS_COMPLIANCE_SLOPE = 64


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
