"""Dynamixel X-series (protocol 2.0): XL430-W250, XM430-W350, XL330-M288.

Their datasheets and their shared control table (ROBOTIS e-manual, each model's
page; the addresses the three share are listed in docs/serial.md), with the same
named access, range checks and raw <-> SI conversions as the protocol-1.0 tables
(:class:`armlab.hardware.servos.control_table.ControlTable`, whose :class:`Item` these reuse).
Angles here are horn angles from the centre (raw 2048), counter-clockwise positive,
as for the protocol-1.0 servos.

Differences a student meets on the wire: positions are 4-byte counts, 4096 a turn
(0.088°); velocities and currents are signed; XM430 and XL330 measure their motor
current (Present Current, address 126), while the XL430 has no current sensor and
reports Present Load in 0.1 % of its maximum torque at that address.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from armlab.hardware.families.xseries.packets import describe_hardware_error
from armlab.hardware.servos.control_table import EEPROM, RAM, ControlTable, Item
from armlab.hardware.servos.servo_spec import (  # the 4096-count encoder's, one home
    CENTRE,
    COUNTS,
    RETURN_DELAY_UNIT,
    RPM,
    TurnEncoder,
)

VELOCITY_UNIT = 0.229 * RPM  #: rad/s per Goal/Present Velocity count
LOAD_UNIT = 0.001  #: fraction of maximum torque per Present Load count (0.1 %)
PWM_UNIT = 0.00113  #: fraction of the supply per Goal/Present PWM count (0.113 %)
#: Baud Rate (address 8) value -> bit/s.
BAUDS = {0: 9_600, 1: 57_600, 2: 115_200, 3: 1_000_000, 4: 2_000_000, 5: 3_000_000,
         6: 4_000_000, 7: 4_500_000}


class OperatingMode:
    """Operating Mode (address 11) values."""

    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


@dataclass(frozen=True)
class XSpec(TurnEncoder):
    """Datasheet of one X-series model.

    Attributes:
        name: "XM430-W350" etc.
        model_number: control-table address 0 value.
        stall_torque: N·m at ``voltage``.
        stall_current: A at ``voltage``.
        no_load_speed: rad/s at the horn at ``voltage``.
        voltage: the datasheet's rated supply, V.
        current_unit: A per Present/Goal Current count; None without a current sensor.
        modes: Operating Mode values the model accepts.
        temperature_limit, min_voltage_limit, max_voltage_limit: factory EEPROM values
            (°C; 0.1 V units).
    """

    name: str
    model_number: int
    stall_torque: float
    stall_current: float
    no_load_speed: float
    voltage: float
    current_unit: float | None
    modes: tuple[int, ...]
    temperature_limit: int
    min_voltage_limit: int
    max_voltage_limit: int

    @property
    def has_current(self) -> bool:
        """The servo measures its motor current (Present Current at address 126)."""
        return self.current_unit is not None

    @property
    def torque_constant(self) -> float:
        """N·m per A at the horn, from the datasheet's stall point (stall torque / stall
        current): the slope the observers need, as
        ``armlab.kinematics.hand_statics.GRIPPER_KT`` is."""
        return self.stall_torque / self.stall_current

    def velocity_to_raw(self, velocity: float) -> int:
        return int(round(velocity / VELOCITY_UNIT))

    def raw_to_velocity(self, raw: int) -> float:
        """Present/Goal Velocity (signed) -> rad/s, CCW positive."""
        return int(raw) * VELOCITY_UNIT

    def raw_to_current(self, raw: int) -> float:
        """Present/Goal Current (signed) -> A; ValueError on a servo without current sensing."""
        if self.current_unit is None:
            raise ValueError(f"the {self.name} has no current sensor (address 126 is "
                             "Present Load)")
        return int(raw) * self.current_unit

    def current_to_raw(self, current: float) -> int:
        if self.current_unit is None:
            raise ValueError(f"the {self.name} has no current modes")
        return int(round(current / self.current_unit))

    def raw_to_torque(self, raw: int) -> float:
        """Address 126 -> torque at the horn, N·m: measured current × torque constant
        where the servo senses current, else Present Load (0.1 %) × stall torque (the
        estimate the RX-24F's load reading gives)."""
        if self.current_unit is None:
            return int(raw) * LOAD_UNIT * self.stall_torque
        return self.raw_to_current(raw) * self.torque_constant


_ALL_MODES = (0, 1, 3, 4, 5, 16)
#: ROBOTIS e-manual, XL430-W250-T: 1.5 N·m, 1.4 A, 61 rpm at 12 V; no current sensor.
XL430_W250 = XSpec("XL430-W250", 1060, stall_torque=1.5, stall_current=1.4,
                   no_load_speed=61 * RPM, voltage=12.0, current_unit=None,
                   modes=(1, 3, 4, 16), temperature_limit=72, min_voltage_limit=60,
                   max_voltage_limit=140)
#: ROBOTIS e-manual, XM430-W350-T: 4.1 N·m, 2.3 A, 46 rpm at 12 V; 2.69 mA per count.
XM430_W350 = XSpec("XM430-W350", 1020, stall_torque=4.1, stall_current=2.3,
                   no_load_speed=46 * RPM, voltage=12.0, current_unit=2.69e-3,
                   modes=_ALL_MODES, temperature_limit=80, min_voltage_limit=95,
                   max_voltage_limit=160)
#: ROBOTIS e-manual, XL330-M288-T: 0.52 N·m, 1.47 A, 103 rpm at 5 V; 1 mA per count.
XL330_M288 = XSpec("XL330-M288", 1200, stall_torque=0.52, stall_current=1.47,
                   no_load_speed=103 * RPM, voltage=5.0, current_unit=1.0e-3,
                   modes=_ALL_MODES, temperature_limit=70, min_voltage_limit=35,
                   max_voltage_limit=70)


#: Factory values of the items whose defaults differ between the models (ROBOTIS
#: e-manual, each model's control table): limits, Shutdown and the controllers' gains.
FACTORY = {
    "XL430-W250": {"pwm_limit": 885, "velocity_limit": 265, "shutdown": 52,
                   "velocity_i_gain": 1000, "velocity_p_gain": 100, "position_d_gain": 4000,
                   "position_i_gain": 0, "position_p_gain": 640},
    "XM430-W350": {"pwm_limit": 885, "current_limit": 1193, "velocity_limit": 200,
                   "shutdown": 52, "velocity_i_gain": 1920, "velocity_p_gain": 100,
                   "position_d_gain": 0, "position_i_gain": 0, "position_p_gain": 800},
    "XL330-M288": {"pwm_limit": 885, "current_limit": 1750, "velocity_limit": 445,
                   "shutdown": 53, "velocity_i_gain": 1600, "velocity_p_gain": 180,
                   "position_d_gain": 0, "position_i_gain": 0, "position_p_gain": 400},
}
#: Position D Gain (address 80) the backends write in Current-based Position Control.
#: There the servo's current loop cancels its motor's back-EMF, the damping the arm has
#: in (PWM) Position Control, and with the factory D gain 0 an arm under the compliance
#: loop rings: the thesis gains on the simulated OpenManipulator-X swing its shoulder by
#: 20° peak to peak while holding, and by about 1.2° with this gain (the X firmware model
#: in ``armlab.hardware.families.xseries.firmware``; 200 is too little, 2000 no better).
CURRENT_POSITION_D_GAIN = 800
#: Largest Velocity Limit (address 44) each model takes.
VELOCITY_LIMIT_MAX = {"XL430-W250": 1023, "XM430-W350": 1023, "XL330-M288": 2047}


def _items(spec: XSpec) -> tuple[Item, ...]:
    E, R = EEPROM, RAM
    f = FACTORY[spec.name]
    current = "current" if spec.has_current else "load"
    sensed = (  # only on servos that measure their current
        Item("current_limit", 38, 2, True, E, 0, f.get("current_limit", 2047),
             f.get("current_limit"), "current"),
        Item("goal_current", 102, 2, True, R, -2047, 2047, None, "current", signed=True),
    ) if spec.has_current else ()
    return sensed + (
        Item("model_number", 0, 2, False, E, 0, 0xFFFF, None),
        Item("firmware_version", 6, 1, False, E, 0, 255, None),
        Item("id", 7, 1, True, E, 0, 252, 1),
        Item("baud_rate", 8, 1, True, E, 0, 7, 1, "baud"),
        Item("return_delay_time", 9, 1, True, E, 0, 254, 250, "delay"),
        Item("drive_mode", 10, 1, True, E, 0, 13, 0),
        Item("operating_mode", 11, 1, True, E, 0, 16, OperatingMode.POSITION),
        Item("temperature_limit", 31, 1, True, E, 0, 100, spec.temperature_limit, "celsius"),
        Item("max_voltage_limit", 32, 2, True, E, 0, 160, spec.max_voltage_limit, "voltage"),
        Item("min_voltage_limit", 34, 2, True, E, 0, 160, spec.min_voltage_limit, "voltage"),
        Item("pwm_limit", 36, 2, True, E, 0, 885, f["pwm_limit"], "pwm"),
        Item("velocity_limit", 44, 4, True, E, 0, VELOCITY_LIMIT_MAX[spec.name],
             f["velocity_limit"], "velocity"),
        Item("max_position_limit", 48, 4, True, E, 0, COUNTS - 1, COUNTS - 1, "position"),
        Item("min_position_limit", 52, 4, True, E, 0, COUNTS - 1, 0, "position"),
        Item("shutdown", 63, 1, True, E, 0, 255, f["shutdown"]),
        Item("torque_enable", 64, 1, True, R, 0, 1, 0),
        Item("led", 65, 1, True, R, 0, 1, 0),
        Item("status_return_level", 68, 1, True, R, 0, 2, 2),
        Item("registered_instruction", 69, 1, False, R, 0, 1, 0),
        Item("hardware_error_status", 70, 1, False, R, 0, 255, 0),
        *(Item(name, address, 2, True, R, 0, 16383, f[name]) for name, address in (
            ("velocity_i_gain", 76), ("velocity_p_gain", 78), ("position_d_gain", 80),
            ("position_i_gain", 82), ("position_p_gain", 84))),
        Item("feedforward_2nd_gain", 88, 2, True, R, 0, 16383, 0),
        Item("feedforward_1st_gain", 90, 2, True, R, 0, 16383, 0),
        Item("goal_pwm", 100, 2, True, R, -885, 885, None, "pwm", signed=True),
        Item("goal_velocity", 104, 4, True, R, -VELOCITY_LIMIT_MAX[spec.name],
             VELOCITY_LIMIT_MAX[spec.name], 0, "velocity", signed=True),
        Item("profile_acceleration", 108, 4, True, R, 0, 32767, 0),
        Item("profile_velocity", 112, 4, True, R, 0, 32767, 0),
        Item("goal_position", 116, 4, True, R, 0, COUNTS - 1, None, "position"),
        Item("moving", 122, 1, False, R, 0, 1, 0),
        Item("present_pwm", 124, 2, False, R, -885, 885, None, "pwm", signed=True),
        Item("present_current" if spec.has_current else "present_load", 126, 2, False, R,
             -2047, 2047, None, current, signed=True),
        Item("present_velocity", 128, 4, False, R, -(2**31), 2**31 - 1, None, "velocity",
             signed=True),
        Item("present_position", 132, 4, False, R, -(2**31), 2**31 - 1, None, "position",
             signed=True),
        Item("present_input_voltage", 144, 2, False, R, 0, 0xFFFF, None, "voltage"),
        Item("present_temperature", 146, 1, False, R, 0, 255, None, "celsius"),
    )


TABLE_SIZE = 147  #: addresses 0..146 (the image the emulator keeps)


@dataclass(frozen=True)
class XControlTable(ControlTable):
    """The control table of one X-series model (named access and range checks from
    :class:`ControlTable`; its own units and power-on image)."""

    if TYPE_CHECKING:  # for mypy only: the dataclass's fields stay the base's
        spec: XSpec  # type: ignore[assignment]  # a family's table holds its own spec class

    def check_operating_mode(self, mode: int) -> int:
        """``mode`` if this model accepts it; ValueError naming the model otherwise."""
        if int(mode) not in self.spec.modes:
            raise ValueError(f"operating mode {mode} is not available on the {self.name} "
                             f"(it takes {', '.join(map(str, self.spec.modes))})")
        return int(mode)

    def defaults(self, *, firmware: int = 0, servo_id: int = 1,
                 present_position: int = CENTRE, baud_value: int | None = None) -> bytearray:
        """Power-on image (147 bytes) with the factory EEPROM values; Goal Position starts
        at the present position."""
        mem = bytearray(TABLE_SIZE)
        given = {"model_number": self.spec.model_number, "firmware_version": firmware,
                 "id": servo_id, "goal_position": present_position,
                 "present_position": present_position,
                 # the goals that limit the output start at their limits
                 "goal_pwm": FACTORY[self.name]["pwm_limit"],
                 "goal_current": FACTORY[self.name].get("current_limit")}
        if baud_value is not None:
            given["baud_rate"] = baud_value
        for item in self.items:
            value = given.get(item.name, item.default)
            if value is not None:
                mem[item.address : item.address + item.size] = int(value).to_bytes(
                    item.size, "little", signed=item.signed)
        return mem

    def to_si(self, name: str, raw: int) -> float:
        """Raw value -> SI: rad, rad/s, A, N·m (XL430 load), V, °C, s, bit/s, fraction."""
        unit = self.item(name).unit
        s: XSpec = self.spec
        raw = int(raw)
        if unit == "position":
            return s.raw_to_position(raw)
        if unit == "velocity":
            return s.raw_to_velocity(raw)
        if unit == "current":
            return s.raw_to_current(raw)
        if unit == "load":
            return s.raw_to_torque(raw)
        if unit == "pwm":
            return raw * PWM_UNIT
        if unit == "voltage":
            return raw * 0.1
        if unit == "delay":
            return raw * RETURN_DELAY_UNIT
        if unit == "baud":
            return float(BAUDS[raw])
        return float(raw)

    def from_si(self, name: str, value: float) -> int:
        """SI value -> raw value for writing item ``name`` (range-checked by ``encode``)."""
        unit = self.item(name).unit
        s: XSpec = self.spec
        if unit == "position":
            return s.position_to_raw(value)
        if unit == "velocity":
            return s.velocity_to_raw(value)
        if unit == "current":
            return s.current_to_raw(value)
        if unit == "voltage":
            return int(round(value * 10.0))
        if unit == "delay":
            return int(round(value / RETURN_DELAY_UNIT))
        if unit == "baud":
            for k, b in BAUDS.items():
                if abs(b - value) <= 0.03 * b:
                    return k
            raise ValueError(f"{value:g} bit/s is not an X-series baud rate "
                             f"({', '.join(map(str, BAUDS.values()))})")
        if unit in ("load", "pwm"):
            raise ValueError(f"{name}: no SI conversion for writing on the {self.name}")
        return int(round(value))


XL430_W250_TABLE = XControlTable(XL430_W250, _items(XL430_W250))
XM430_W350_TABLE = XControlTable(XM430_W350, _items(XM430_W350))
XL330_M288_TABLE = XControlTable(XL330_M288, _items(XL330_M288))
X_TABLES = {t.spec.model_number: t for t in (XL430_W250_TABLE, XM430_W350_TABLE,
                                             XL330_M288_TABLE)}


def x_table_for(model: int | str) -> XControlTable:
    """The table of an X-series model given as number (1020) or name ("XM430-W350",
    "xm430")."""
    if isinstance(model, str):
        key = model.upper().replace("-", "").replace("_", "")
        for t in X_TABLES.values():
            name = t.name.replace("-", "")
            if name == key or name[:5] == key:
                return t
        raise ValueError(f"unknown X-series model {model!r}; known: "
                         f"{', '.join(t.name for t in X_TABLES.values())}")
    if int(model) not in X_TABLES:
        raise ValueError(f"unknown X-series model number {model}; known: "
                         f"{', '.join(f'{k} ({t.name})' for k, t in X_TABLES.items())}")
    return X_TABLES[int(model)]


def lab_mode(spec: XSpec) -> int:
    """The operating mode the lab runs a servo in: current-based position control where it
    measures its current (Goal Current then bounds its torque), else position control."""
    return OperatingMode.CURRENT_BASED_POSITION if spec.has_current else OperatingMode.POSITION


def lab_settings(spec: XSpec, *, torque_limit: float) -> tuple[tuple[str, int, str], ...]:
    """The RAM items the lab sets with :func:`lab_mode`, as (item, raw value, a line for
    the log): the torque bound, Goal Current (or Goal PWM) at ``torque_limit`` of its
    factory limit, and in current-based position control the Position D Gain
    (:data:`CURRENT_POSITION_D_GAIN`). The X-series backend writes them to real servos;
    the simulator sets them in its firmware model's registers."""
    table = x_table_for(spec.model_number)
    share = f"{torque_limit:.0%} of its limit"
    if not spec.has_current:
        return (("goal_pwm", round(torque_limit * table.item("pwm_limit").default),  # type: ignore[operator]  # the tables give these items a default
                 f"goal PWM {share}"),)
    return (("goal_current", round(torque_limit * table.item("current_limit").default),  # type: ignore[operator]  # the tables give these items a default
             f"goal current {share}"),
            ("position_d_gain", CURRENT_POSITION_D_GAIN,
             f"position D gain {CURRENT_POSITION_D_GAIN} (the damping the current loop "
             "takes away)"))


def hardware_alarm(bits: int, *, servo_id: int | None = None) -> str:
    """What a person is told about a servo's Hardware Error Status ``bits``: the servo,
    the flags by their e-manual names with the value, and the way back, e.g. "servo 12:
    Overload (Hardware Error Status 0x20), cleared by a REBOOT (Reset sends it)"."""
    who = "" if servo_id is None else f"servo {servo_id}: "
    return f"{who}{describe_hardware_error(bits)}, cleared by a REBOOT (Reset sends it)"
