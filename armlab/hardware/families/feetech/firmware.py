"""A Feetech STS3215 as its firmware behaves, driven by raw register values: the STS
counterpart of :mod:`armlab.hardware.families.dynamixel1.firmware` and
:mod:`armlab.hardware.families.xseries.firmware`, with the same plant interface (:meth:`update`,
``drive``/``damping``, :meth:`report`).

What the model's firmware does each tick (the registers of
:mod:`armlab.hardware.families.feetech.table`):

1. sense the horn angle through the 12-bit magnetic encoder (4096 counts a turn);
2. Position mode (Operating Mode 0): clamp Goal Position into the Min/Max Position Limit
   (both 0: no limit), then move a desired position towards it at Goal Speed (counts/s;
   0 = no limit) with Acceleration (100 counts/s² a unit; 0 = no limit);
3. the position loop, a PID on (desired − present) counts with the P, I and D
   coefficients (addresses 21–23), its output a PWM duty, limited by Torque Limit
   (address 48, 0.1 % of full duty a count: the torque bound, as the lab uses it);
4. Velocity mode (1): a proportional loop on (Goal Speed − present speed) with the P
   coefficient, limited as above;
5. report Present Position, Speed (counts/s), Load (the duty in 0.1 %, sign in bit 10),
   Current (the motor current's magnitude in 6.5 mA counts), Voltage, Temperature and
   Moving, and the status error bits: overload when the duty sits at its limit without
   moving for ``overload_time`` s, after which the output is held to Overload Torque
   (address 36, % of full) until the torque is switched off and on again (LeRobot's
   SO-101 sets it to 25 "% torque when overloaded"); overheating above the temperature
   limit; voltage outside the voltage limits; and an injected fault
   (:meth:`StsServoModel.inject_error`, ``armlab emulate --fault``) once due.

Between ticks the horn torque follows the DC-motor line at the supply voltage ``V``
(``ServoParams.voltage``): tau = stall(V) · (duty − omega / no_load(V)) minus gear
friction, with stall(V) and no_load(V) the datasheet's figures at
:attr:`~armlab.hardware.families.feetech.table.StsSpec.voltage` scaled by V / that voltage (a DC
motor's stall torque and no-load speed are both proportional to its supply).

*Interpretations* (Feetech publishes neither the loop's form nor its scaling, nor the
firmware's period): the loop runs every :data:`FIRMWARE_PERIOD`; the duty is
``P · e · KP_UNIT + D · ė · KD_UNIT + I · Σe · KI_UNIT`` with ``e`` in counts and ``ė`` in
counts/s (the desired position's rate less the sensed velocity). :data:`KP_UNIT` makes
the factory P of 32 reach full duty at 31 counts (2.7°) of error; :data:`KD_UNIT` makes
the factory D of 32 add 0.32 duty at 1000 counts/s (1.5 rad/s). Operating modes 2 (PWM)
and 3 (step) are not modelled: the model's output is off in them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from armlab.hardware.families.feetech.packets import ErrorBits
from armlab.hardware.families.feetech.table import (
    CENTRE,
    COUNTS,
    CURRENT_UNIT,
    SPEED_UNIT,
    STS_TABLES,
    OperatingMode,
    StsControlTable,
    StsSpec,
)
from armlab.hardware.sim.servo_motor import GearedMotor, ServoParams

FIRMWARE_PERIOD = 1e-3  #: s per firmware tick (interpretation)
KP_UNIT = 1.0 / 1000.0  #: duty per count of error per P unit (interpretation)
KD_UNIT = 1.0e-5  #: duty per count/s of error rate per D unit (interpretation)
KI_UNIT = 1.0e-6  #: duty per count·tick of summed error per I unit (interpretation)
ACCELERATION_UNIT = 100.0  #: counts/s² per Acceleration unit
MOVING_THRESHOLD = 20  #: counts/s under which the horn counts as still (interpretation)
OVERLOAD = int(ErrorBits.OVERLOAD)
ERROR_BITS = int(sum(ErrorBits))  #: every status error bit an STS reports
#: Not a status bit: an injected fault after which the servo answers nothing (a cut
#: cable, a dead servo; :attr:`StsServoModel.silent`).
SILENT = 0x100


@dataclass
class StsRegisters:
    """The control-table registers the STS firmware acts on (raw values, signed where the
    table's are sign-magnitude). Anyone may assign them, as a WRITE would; the firmware
    reads them at its next tick."""

    torque_enable: int = 0
    operating_mode: int = OperatingMode.POSITION
    goal_position: int = CENTRE
    goal_speed: int = 0
    acceleration: int = 0
    p_coefficient: int = 32
    d_coefficient: int = 32
    i_coefficient: int = 0
    torque_limit: int = 1000
    min_position_limit: int = 0
    max_position_limit: int = COUNTS - 1
    overload_torque: int = 80
    temperature_limit: int = 70
    min_voltage_limit: int = 40
    max_voltage_limit: int = 80

    @classmethod
    def factory(cls, table: StsControlTable, *, goal_position: int = CENTRE) -> StsRegisters:
        """The power-on registers of ``table``'s model (its items' factory values)."""
        items = {item.name: item for item in table.items}
        values = {name: int(items[name].default) for name in cls.__dataclass_fields__  # type: ignore[arg-type]  # only items with a default are read (filtered or known)
                  if name in items and items[name].default is not None}
        values["torque_limit"] = int(items["max_torque"].default)  # type: ignore[arg-type]  # only items with a default are read (filtered or known)
        values["goal_position"] = int(goal_position)
        return cls(**values)


@dataclass(frozen=True)
class StsReport:
    """What the servo answers to a READ, as signed values (the table encodes them).

    Attributes:
        position: Present Position, counts (2048 = centre).
        speed: Present Speed, counts/s, CCW positive.
        load: Present Load, the duty in 0.1 %, signed.
        current: Present Current, 6.5 mA counts (magnitude).
        voltage: Present Voltage, 0.1 V.
        temperature: Present Temperature, °C.
        moving: 1 while going to the goal or the horn moves.
        error: the status error bits.
        torque_enable: the Torque Enable register.
    """

    position: int
    speed: int
    load: int
    current: int
    voltage: int
    temperature: int
    moving: int
    error: int
    torque_enable: int


class StsServoModel(GearedMotor):
    """One STS servo's firmware and motor.

    Args:
        spec: the datasheet (``armlab.hardware.families.feetech.table.STS3215``).
        regs: its registers (the model's power-on values when omitted). Shared, not
            copied: writes take effect at the next :meth:`update`.
        params: physical constants; ``params.voltage`` is the supply (the SO-101 runs
            from 5 V) the stall torque and no-load speed are scaled to.
        angle: initial horn angle, rad from the centre.
    """

    def __init__(self, spec: StsSpec, regs: StsRegisters | None = None, *,
                 params: ServoParams | None = None, angle: float = 0.0) -> None:
        self.spec = spec
        self.params = params or ServoParams(voltage=spec.voltage)
        scale = self.params.voltage / spec.voltage
        self.stall_torque = spec.stall_torque * scale  #: N·m at the supply
        self.no_load_speed = spec.no_load_speed * scale  #: rad/s at the supply
        self._backemf = spec.stall_torque / spec.no_load_speed  # N·m·s/rad, any supply
        self._counts_per_rad = 1.0 / spec.position_unit
        self._angle = float(angle)
        self._velocity = 0.0
        self._present = spec.position_to_raw(self._angle)
        if regs is None:
            regs = StsRegisters.factory(STS_TABLES[spec.model_number],
                                        goal_position=self._present)
        self.regs = regs
        self._desired = float(self._present)
        self._desired_v = 0.0
        self._integral = 0.0
        self._enabled = False
        self._duty = 0.0
        self._stall_time = 0.0
        self._overloaded = False
        self._moving = False
        self._injected: tuple[int, float] | None = None  # (bits, s of torque on)
        self._torque_time = 0.0  # s the torque has been on, in all
        self._fault = 0  # injected bits raised (besides an overload)
        #: the servo answers nothing any more (an injected :data:`SILENT`; for good)
        self.silent = False

    # -- firmware tick ------------------------------------------------------

    def update(self, dt: float, angle: float, velocity: float) -> None:
        """One firmware tick of ``dt`` s at horn ``angle`` (rad) and ``velocity`` (rad/s)."""
        regs = self.regs
        self._angle, self._velocity = angle, velocity
        present = round(CENTRE + angle * self._counts_per_rad)
        self._present = present
        v_counts = velocity / SPEED_UNIT
        enabled = bool(regs.torque_enable)
        if enabled and not self._enabled:  # torque on: start from where the horn is
            self._desired, self._desired_v, self._integral = float(present), 0.0, 0.0
            self._overloaded = False
            self._fault = 0
        self._enabled = enabled
        if enabled:
            self._torque_time += dt
            if self._injected is not None and self._torque_time >= self._injected[1]:
                bits = self._injected[0]
                self._injected = None
                self._overloaded = self._overloaded or bool(bits & OVERLOAD)
                self._fault |= bits & ERROR_BITS & ~OVERLOAD
                self.silent = self.silent or bool(bits & SILENT)
        limit = max(0, regs.torque_limit) / 1000.0
        if self._overloaded:
            limit = min(limit, regs.overload_torque / 100.0)
        duty = 0.0
        moving = abs(v_counts) > MOVING_THRESHOLD
        if not enabled:
            self._desired, self._desired_v = float(present), 0.0
        elif regs.operating_mode == OperatingMode.POSITION:
            goal = regs.goal_position
            if regs.min_position_limit or regs.max_position_limit:
                goal = min(max(goal, regs.min_position_limit), regs.max_position_limit)
            self._profile(goal, dt)
            error = self._desired - present
            self._integral += error * dt / FIRMWARE_PERIOD
            u = (regs.p_coefficient * KP_UNIT * error
                 + regs.d_coefficient * KD_UNIT * (self._desired_v - v_counts)
                 + regs.i_coefficient * KI_UNIT * self._integral)
            duty = min(max(u, -limit), limit)
            moving = moving or self._desired != goal
        elif regs.operating_mode == OperatingMode.VELOCITY:
            u = regs.p_coefficient * KP_UNIT * (regs.goal_speed - v_counts)
            duty = min(max(u, -limit), limit)
            moving = regs.goal_speed != 0
        self._moving = moving
        self._check_overload(dt, duty, limit, velocity)
        self._duty = duty
        if duty != 0.0:
            self.drive = duty * self.stall_torque
            self.damping = self._backemf
        else:
            self.drive = self.damping = 0.0

    def _profile(self, goal: int, dt: float) -> None:
        """Move the desired position towards ``goal`` at Goal Speed with Acceleration
        (0: no limit)."""
        regs = self.regs
        vmax = abs(regs.goal_speed) or math.inf
        amax = regs.acceleration * ACCELERATION_UNIT or math.inf
        if math.isinf(vmax) and math.isinf(amax):
            self._desired, self._desired_v = float(goal), 0.0
            return
        gap = goal - self._desired
        # the fastest speed from which the goal can still be reached braking at amax
        reach = math.sqrt(2.0 * amax * abs(gap)) if math.isfinite(amax) else math.inf
        want = math.copysign(min(vmax, reach), gap)
        if math.isfinite(amax):
            step = amax * dt
            want = min(max(want, self._desired_v - step), self._desired_v + step)
        move = want * dt
        if abs(move) >= abs(gap):
            self._desired, self._desired_v = float(goal), 0.0
        else:
            self._desired += move
            self._desired_v = want

    def inject_error(self, bits: int, *, after: float = 0.0) -> None:
        """Raise status error ``bits`` once the torque has been on for ``after`` s in all (a
        test-and-teaching fault: what the firmware flags by itself on a hot motor, a bad
        supply...). An overload acts as the firmware's own (the output held back to
        Overload Torque); every bit clears when the torque is switched off and on again
        (*interpretation* for the bits other than overload: the model has no temperature).
        :data:`SILENT` makes the servo stop answering for good.

        Raises:
            ValueError: ``bits`` not status error bits, or ``after`` negative.
        """
        bits = int(bits)
        if not bits or bits & ~(ERROR_BITS | SILENT):
            raise ValueError(f"bits: STS status error bits ({ERROR_BITS:#04x}) or SILENT "
                             f"({SILENT:#x}), got {bits:#04x}")
        if not after >= 0.0:
            raise ValueError(f"after: s of torque on, >= 0, got {after}")
        self._injected = (bits, float(after))

    def _check_overload(self, dt: float, duty: float, limit: float, velocity: float) -> None:
        """Overload: the duty at its limit without moving for ``overload_time`` s."""
        p = self.params
        if limit > 0 and abs(duty) >= limit - 1e-9 and abs(velocity) < p.stall_speed:
            self._stall_time += dt
        else:
            self._stall_time = 0.0
        if self._stall_time > p.overload_time:
            self._overloaded = True

    # -- what the servo reports --------------------------------------------

    @property
    def duty(self) -> float:
        """PWM duty of this tick, −1..1 (CCW positive)."""
        return self._duty

    @property
    def desired(self) -> float:
        """The profile's desired position, counts."""
        return self._desired

    def present_position(self) -> int:
        """Present Position, counts."""
        return self._present

    def error(self) -> int:
        """The status error bits: overload, overheating, input voltage."""
        regs, p = self.regs, self.params
        bits = (OVERLOAD if self._overloaded else 0) | self._fault
        if p.temperature > regs.temperature_limit:
            bits |= int(ErrorBits.OVERHEAT)
        if not regs.min_voltage_limit <= round(p.voltage * 10) <= regs.max_voltage_limit:
            bits |= int(ErrorBits.VOLTAGE)
        return bits

    def report(self) -> StsReport:
        """Every present value (signed where the table is sign-magnitude)."""
        torque = self.motor_torque(self._velocity)
        current = abs(torque) / self.spec.torque_constant / CURRENT_UNIT
        return StsReport(
            position=self._present, speed=round(self._velocity / SPEED_UNIT),
            load=round(self._duty * 1000), current=min(round(current), 0x7FFF),
            voltage=int(round(self.params.voltage * 10)),
            temperature=int(round(self.params.temperature)), moving=int(self._moving),
            error=self.error(), torque_enable=int(self.regs.torque_enable))
