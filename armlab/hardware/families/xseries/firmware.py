"""A Dynamixel X-series servo (XL430-W250, XM430-W350, XL330-M288) as its firmware behaves,
driven by raw register values: the X-series counterpart of
:mod:`armlab.hardware.families.dynamixel1.firmware`.

What the servo's microcontroller does once per firmware tick (ROBOTIS e-manual, the
models' pages: "Operating Mode", "Profile Velocity", "Position PID Gain"; docs/serial.md):

1. sense the horn angle through the 12-bit magnetic encoder (Present Position, 4096
   counts a turn, 2048 = centre);
2. in the position modes, move a desired position towards Goal Position along the
   profile Profile Velocity and Profile Acceleration describe (0 = no limit: with both
   0 the desired position jumps to the goal);
3. the position controller: PID on (desired − present) counts plus velocity and
   acceleration feed-forward, with the gains the e-manual converts from the table
   (KPP = P/128, KPI = I/65536, KPD = D/16, KFF = FF/4);
   - Position Control and Extended Position Control: its output is a PWM value (885 =
     full duty), limited by Goal PWM;
   - Current-based Position Control: its output is a current (the table's current
     unit), limited by Goal Current, which an ideal current loop turns into torque;
4. Velocity Control: PI on (Goal Velocity − present velocity) (KVP = P/128,
   KVI = I/65536) to PWM; Current Control: Goal Current; PWM Control: Goal PWM;
5. report Present Position, Velocity, PWM and Current (or Present Load on the XL430,
   which has no current sensor), Moving, and the Hardware Error Status (an overload:
   full PWM without moving for ``overload_time``; any other bit when injected,
   :meth:`XServoModel.inject_error`; a bit set in Shutdown switches the torque
   off until a REBOOT).

Between ticks the horn torque follows the DC-motor line, as for the protocol-1.0
servos: tau = stall_torque · (duty − omega / no_load_speed), minus gear friction.

*Interpretations* (the e-manual gives the gains' conversion "including the sampling
time" but not the time itself, nor how the derivative is taken): the firmware's control
period is :data:`FIRMWARE_PERIOD`; the integral and derivative are scaled to it when the
plant's step differs. The derivative is the desired position's change less the horn's
velocity as the firmware senses it (what it reports as Present Velocity), not the
difference of two encoder counts: that difference is 0 or a whole count per tick, and
with the lab's D gain every count the horn crosses would put a one-tick spike of
0.24 N·m into the current the servo reports, so a reading taken 1 ms earlier or later
would see a different load (the emulated and simulated OpenManipulator-X under the
compliance loop drifted 2° apart from that alone). The current loop is ideal: the
torque is current × torque constant as far as the supply voltage allows (duty within
±PWM Limit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from armlab.hardware.families.xseries.packets import HARDWARE_ERROR_BITS, HardwareError
from armlab.hardware.families.xseries.table import (
    CENTRE,
    COUNTS,
    FACTORY,
    LOAD_UNIT,
    PWM_UNIT,
    VELOCITY_UNIT,
    OperatingMode,
    XControlTable,
    XSpec,
    x_table_for,
)
from armlab.hardware.sim.servo_motor import GearedMotor, ServoParams

#: s: the firmware's control period the e-manual's gain conversions assume (interpretation)
FIRMWARE_PERIOD = 1e-3
#: Goal/Present PWM count of full duty.
PWM_FULL = round(1.0 / PWM_UNIT)  # 885
#: counts/s per Profile Velocity unit (0.229 rpm) and counts/s² per Profile Acceleration
#: unit (214.577 rev/min²)
PROFILE_VELOCITY_UNIT = 0.229 / 60.0 * COUNTS
PROFILE_ACCELERATION_UNIT = 214.577 / 3600.0 * COUNTS
#: The Hardware Error Status bit the simulated firmware sets (a plain int: this runs
#: every tick).
HW_OVERLOAD = int(HardwareError.OVERLOAD)
#: Present Velocity counts under which the horn counts as still (Moving Threshold's
#: factory value, address 24).
MOVING_THRESHOLD = 10


_XM430 = FACTORY["XM430-W350"]


@dataclass
class XRegisters:
    """The control-table registers the X-series firmware acts on (raw values).

    Anyone may assign these at any time, as a WRITE packet would; the firmware reads
    them at its next tick. The defaults are the XM430-W350's power-on values;
    :meth:`factory` gives any model's.
    """

    torque_enable: int = 0
    operating_mode: int = OperatingMode.POSITION
    goal_position: int = CENTRE
    goal_velocity: int = 0
    goal_current: int = 0
    goal_pwm: int = PWM_FULL
    profile_acceleration: int = 0
    profile_velocity: int = 0
    position_p_gain: int = _XM430["position_p_gain"]
    position_i_gain: int = _XM430["position_i_gain"]
    position_d_gain: int = _XM430["position_d_gain"]
    feedforward_1st_gain: int = 0
    feedforward_2nd_gain: int = 0
    velocity_p_gain: int = _XM430["velocity_p_gain"]
    velocity_i_gain: int = _XM430["velocity_i_gain"]
    pwm_limit: int = PWM_FULL
    current_limit: int = _XM430["current_limit"]
    velocity_limit: int = _XM430["velocity_limit"]
    max_position_limit: int = COUNTS - 1
    min_position_limit: int = 0
    shutdown: int = _XM430["shutdown"]

    @classmethod
    def factory(cls, table: XControlTable, *, goal_position: int = CENTRE) -> XRegisters:
        """The power-on registers of ``table``'s model (its items' factory values)."""
        items = {item.name: item for item in table.items}
        values = {name: int(items[name].default) for name in cls.__dataclass_fields__  # type: ignore[arg-type]  # only items with a default are read (filtered or known)
                  if name in items and items[name].default is not None}
        if "goal_current" in items:
            values["goal_current"] = values.get("current_limit", 0)
        values["goal_pwm"] = values.get("pwm_limit", PWM_FULL)
        values["goal_position"] = int(goal_position)
        return cls(**values)


@dataclass(frozen=True)
class XReport:
    """What the servo answers to a READ, raw values as in its control table.

    Attributes:
        position: Present Position (signed counts, 2048 = centre).
        velocity: Present Velocity (signed, 0.229 rpm units).
        pwm: Present PWM (signed, 885 = full duty).
        current: Present Current (signed, the model's current unit) or, on a servo
            without a current sensor, Present Load (signed, 0.1 % of the stall torque).
        moving: 1 while going to the goal or the horn moves.
        hardware_error: Hardware Error Status.
        torque_enable: the Torque Enable register (0 after a shutdown).
        voltage: Present Input Voltage, 0.1 V.
        temperature: Present Temperature, °C.
    """

    position: int
    velocity: int
    pwm: int
    current: int
    moving: int
    hardware_error: int
    torque_enable: int
    voltage: int
    temperature: int


class XServoModel(GearedMotor):
    """One X-series servo's firmware and motor (the plant's interface of
    :class:`armlab.hardware.families.dynamixel1.firmware.ServoModel`: :meth:`update`,
    ``drive``/``damping`` and the torques of
    :class:`~armlab.hardware.sim.servo_motor.GearedMotor`, :meth:`report`).

    Args:
        spec: the datasheet (``armlab.hardware.families.xseries.table.XM430_W350`` etc.).
        regs: its registers (the model's power-on values when omitted). Shared, not
            copied: writes take effect at the next :meth:`update`.
        params: physical constants (rotor inertia, gear friction, overload time).
        angle: initial horn angle, rad from the centre.
        table: the model's control table (for power-on registers; default: looked up).
    """

    def __init__(self, spec: XSpec, regs: XRegisters | None = None, *,
                 params: ServoParams | None = None, angle: float = 0.0,
                 table: XControlTable | None = None) -> None:
        self.spec = spec
        self.params = params or ServoParams()
        self._counts_per_rad = 1.0 / spec.position_unit
        self._backemf = spec.stall_torque / spec.no_load_speed
        self._angle = float(angle)
        self._velocity = 0.0
        self._present = spec.position_to_raw(self._angle)
        if regs is None:
            regs = XRegisters.factory(table or x_table_for(spec.model_number),
                                      goal_position=self._present)
        self.regs = regs
        self._desired = float(self._present)  # profile state, counts and counts/s
        self._desired_v = 0.0
        self._integral = 0.0
        self._last_desired = self._desired  # counts, at the last tick (the derivative's)
        self._velocity_integral = 0.0
        self._enabled = False
        self._duty = 0.0
        self._stall_time = 0.0
        self._hardware_error = 0
        self._torque_time = 0.0  #: s the torque has been on (an injected error's clock)
        self._injected: tuple[int, float] | None = None  #: (bits, after s of torque on)
        self._moving = False

    # -- firmware tick ------------------------------------------------------

    def update(self, dt: float, angle: float, velocity: float) -> None:
        """One firmware tick of ``dt`` s at horn ``angle`` (rad) and ``velocity`` (rad/s)."""
        regs = self.regs
        self._angle = angle
        self._velocity = velocity
        present = round(CENTRE + angle * self._counts_per_rad)
        self._present = present
        enabled = bool(regs.torque_enable) and not self._hardware_error & regs.shutdown
        if enabled and not self._enabled:  # torque on: start from where the horn is
            self._desired, self._desired_v = float(present), 0.0
            self._integral = self._velocity_integral = 0.0
            self._last_desired = self._desired
        self._enabled = enabled
        mode = regs.operating_mode
        duty = 0.0
        torque_target = None  # N·m, for the current-driven modes
        if not enabled:
            self._desired, self._desired_v = float(present), 0.0
            self._moving = abs(velocity) > MOVING_THRESHOLD * VELOCITY_UNIT
        elif mode in (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION,
                      OperatingMode.CURRENT_BASED_POSITION):
            goal = regs.goal_position
            if mode == OperatingMode.POSITION:  # the limits hold in Position Control only
                goal = min(max(goal, regs.min_position_limit), regs.max_position_limit)
            accel = self._profile(goal, dt)
            u = self._position_pid(present, velocity, accel, dt)
            if mode == OperatingMode.CURRENT_BASED_POSITION:
                limit = abs(regs.goal_current)
                torque_target = self._current_torque(min(max(u, -limit), limit))
            else:
                limit = min(abs(regs.goal_pwm), regs.pwm_limit)
                duty = min(max(u, -limit), limit) / PWM_FULL
            self._moving = self._desired != goal or \
                abs(velocity) > MOVING_THRESHOLD * VELOCITY_UNIT
        elif mode == OperatingMode.VELOCITY:
            goal_v = regs.goal_velocity
            if regs.velocity_limit:
                goal_v = min(max(goal_v, -regs.velocity_limit), regs.velocity_limit)
            error = goal_v - velocity / VELOCITY_UNIT
            self._velocity_integral += error * dt / FIRMWARE_PERIOD
            u = regs.velocity_p_gain / 128.0 * error + \
                regs.velocity_i_gain / 65536.0 * self._velocity_integral
            limit = min(abs(regs.goal_pwm), regs.pwm_limit)
            duty = min(max(u, -limit), limit) / PWM_FULL
            self._moving = goal_v != 0
        elif mode == OperatingMode.CURRENT:
            torque_target = self._current_torque(regs.goal_current)
            self._moving = abs(velocity) > MOVING_THRESHOLD * VELOCITY_UNIT
        elif mode == OperatingMode.PWM:
            limit = regs.pwm_limit
            duty = min(max(regs.goal_pwm, -limit), limit) / PWM_FULL
            self._moving = abs(velocity) > MOVING_THRESHOLD * VELOCITY_UNIT
        if torque_target is not None:  # an ideal current loop, within the supply's reach
            full = regs.pwm_limit / PWM_FULL
            duty = min(max(torque_target / self.spec.stall_torque +
                           velocity / self.spec.no_load_speed, -full), full)
        self._duty = duty
        self._check_hardware(dt, duty, velocity)
        if self._duty != 0.0:
            self.drive = self._duty * self.spec.stall_torque
            self.damping = self._backemf
        else:
            self.drive = 0.0
            self.damping = 0.0

    def _profile(self, goal: int, dt: float) -> float:
        """Move the desired position towards ``goal`` along the velocity/acceleration
        profile; returns the desired acceleration, counts/s²."""
        regs = self.regs
        if regs.profile_velocity == 0 and regs.profile_acceleration == 0:
            self._desired, self._desired_v = float(goal), 0.0
            return 0.0
        v_max = regs.profile_velocity * PROFILE_VELOCITY_UNIT or math.inf
        a_max = regs.profile_acceleration * PROFILE_ACCELERATION_UNIT or math.inf
        left = goal - self._desired
        v_stop = math.sqrt(2.0 * a_max * abs(left)) if a_max != math.inf else math.inf
        v_want = math.copysign(min(v_max, v_stop), left) if left else 0.0
        v_old = self._desired_v
        dv = v_want - v_old
        if a_max != math.inf:
            dv = min(max(dv, -a_max * dt), a_max * dt)
        v = v_old + dv
        step = v * dt
        if v_max == math.inf and a_max == math.inf or abs(step) >= abs(left):
            self._desired, v = float(goal), 0.0
        else:
            self._desired += step
        self._desired_v = v
        return (v - v_old) / dt

    def _position_pid(self, present: int, velocity: float, accel: float, dt: float) -> float:
        """The position controller's output (PWM counts, or current counts in
        Current-based Position Control) for this tick, at Present Position ``present``
        (counts) and horn ``velocity`` (rad/s)."""
        regs = self.regs
        error = self._desired - present
        ticks = dt / FIRMWARE_PERIOD
        self._integral += error * ticks
        derivative = self._error_rate(velocity, ticks)
        per_tick_v = self._desired_v * FIRMWARE_PERIOD
        per_tick_a = accel * FIRMWARE_PERIOD * FIRMWARE_PERIOD
        return (regs.position_p_gain / 128.0 * error
                + regs.position_i_gain / 65536.0 * self._integral
                + regs.position_d_gain / 16.0 * derivative
                + regs.feedforward_1st_gain / 4.0 * per_tick_v
                + regs.feedforward_2nd_gain / 4.0 * per_tick_a)

    def _error_rate(self, velocity: float, ticks: float) -> float:
        """The position error's change per firmware tick, counts: the desired position's
        change since the last tick less the sensed horn ``velocity`` (rad/s) over one
        :data:`FIRMWARE_PERIOD` (see the module's interpretations)."""
        desired_rate = (self._desired - self._last_desired) / ticks
        self._last_desired = self._desired
        return desired_rate - velocity * self._counts_per_rad * FIRMWARE_PERIOD

    def _current_torque(self, current_counts: float) -> float:
        """Torque at the horn (N·m) a current command gives (counts of the current unit)."""
        unit = self.spec.current_unit
        if unit is None:  # no current sensor: no current modes (the table refuses them)
            return 0.0
        return current_counts * unit * self.spec.torque_constant

    def inject_error(self, bits: int, *, after: float = 0.0) -> None:
        """Raise Hardware Error Status ``bits`` once the torque has been on for ``after`` s
        in all (a test-and-teaching fault: what the firmware sets by itself on an input
        voltage out of range, a hot motor, a broken encoder...). Once: a REBOOT clears it
        as any other. Bits in Shutdown switch the torque off, as the firmware's own do.

        Raises:
            ValueError: ``bits`` not a Hardware Error Status bit, or ``after`` negative.
        """
        bits = int(bits)
        if not bits or bits & ~HARDWARE_ERROR_BITS:
            raise ValueError(f"bits: Hardware Error Status bits ({HARDWARE_ERROR_BITS:#04x}), "
                             f"got {bits:#04x}")
        if not after >= 0.0:
            raise ValueError(f"after: s of torque on, >= 0, got {after}")
        self._injected = (bits, float(after))

    def _check_hardware(self, dt: float, duty: float, velocity: float) -> None:
        """Hardware Error Status: an overload (full PWM without moving for
        ``overload_time``) or an injected error that is due; with its Shutdown bit set,
        torque off until a REBOOT (:meth:`reboot`)."""
        if self._enabled:
            self._torque_time += dt
        if self._injected is not None and self._enabled and \
                self._torque_time >= self._injected[1]:
            self._hardware_error |= self._injected[0]
            self._injected = None
        p = self.params
        full = self.regs.pwm_limit / PWM_FULL
        if full > 0 and abs(duty) >= full - 1e-9 and abs(velocity) < p.stall_speed:
            self._stall_time += dt
        else:
            self._stall_time = 0.0
        if self._stall_time > p.overload_time:
            self._hardware_error |= HW_OVERLOAD
        if self._hardware_error & self.regs.shutdown:
            self.regs.torque_enable = 0
            self._enabled = False
            self._duty = 0.0

    def reboot(self) -> None:
        """REBOOT: the hardware error is cleared, torque off (the registers' RAM the
        emulator resets)."""
        self._hardware_error = 0
        self._stall_time = 0.0
        self.regs.torque_enable = 0

    # -- what the servo reports --------------------------------------------

    @property
    def duty(self) -> float:
        """PWM duty of this tick, −1..1 (CCW positive)."""
        return self._duty

    @property
    def desired(self) -> float:
        """The profile's desired position, counts (float)."""
        return self._desired

    @property
    def hardware_error(self) -> int:
        """Hardware Error Status (0 = healthy)."""
        return self._hardware_error

    def report(self) -> XReport:
        """Every present value as raw register values."""
        torque = self.motor_torque(self._velocity)
        if self.spec.current_unit is None:
            current = round(torque / self.spec.stall_torque / LOAD_UNIT)
        else:
            current = round(torque / self.spec.torque_constant / self.spec.current_unit)
        return XReport(
            position=self._present, velocity=round(self._velocity / VELOCITY_UNIT),
            pwm=round(self._duty * PWM_FULL), current=max(-2047, min(2047, current)),
            moving=int(self._moving), hardware_error=self._hardware_error,
            torque_enable=int(self.regs.torque_enable),
            voltage=int(round(self.params.voltage * 10)),
            temperature=int(round(self.params.temperature)),
        )
