"""A Dynamixel RX-24F / AX-12A as its firmware behaves, driven by raw register values.

The model is what the servo's own microcontroller does once per firmware tick
(thesis §2.3; docs/servo-model.md explains every choice):

1. sense the horn angle through the 10-bit potentiometer (Present Position, 0..1023);
2. move an internal set-point towards Goal Position at Moving Speed (0 = no speed
   control: the set-point jumps to the goal);
3. turn the position error (set-point − present position, counts) into a PWM duty by
   the compliance curve: zero inside the margin, Punch at its edge, then rising
   linearly across the slope region up to Torque Limit (CW or CCW margin/slope by the
   direction the servo has to turn);
4. report Present Speed and Present Load (the duty, 0..1023 of full torque, bit 10 =
   CW) and the error bits (angle limit, overload with Alarm Shutdown).

Between ticks the horn torque follows the DC-motor line through the gear:
tau = stall_torque · (duty − omega / no_load_speed), minus gear friction. The duty is
held over a tick (zero-order hold), as the firmware's PWM is.

All angles here are *servo-side*: rad from the centre (raw 512), CCW positive. The
plant maps joints to servos (direction sign).
"""

from __future__ import annotations

from dataclasses import dataclass

from armlab.hardware.families.dynamixel1.packets import ErrorBits
from armlab.hardware.servos.servo_spec import DIRECTION_BIT, ServoSpec, signed_word
from armlab.hardware.sim.servo_motor import GearedMotor, ServoParams

#: Error-byte bits the firmware sets (plain ints: this runs every tick).
ERROR_ANGLE_LIMIT = int(ErrorBits.ANGLE_LIMIT)


ERROR_OVERLOAD = int(ErrorBits.OVERLOAD)


@dataclass
class ServoRegisters:
    """The writable control-table registers the firmware acts on (raw values, factory defaults).

    Anyone may assign these at any time, as a WRITE packet would; the firmware reads
    them at its next tick. Attributes are named after the control table (ROBOTIS
    e-manual, AX-12A / RX-24F; docs/servo-model.md): angle limits, compliance margins
    (0..255 counts), compliance slopes (0..255, 7 effective steps), goal position (0..1023), moving
    speed (0..1023, 0 = no speed control; in wheel mode bit 10 = CW), torque limit and
    max torque (0..1023 of full torque), punch (0..1023), alarm bit masks.
    """

    torque_enable: int = 0
    led: int = 0
    cw_compliance_margin: int = 1
    ccw_compliance_margin: int = 1
    cw_compliance_slope: int = 32
    ccw_compliance_slope: int = 32
    goal_position: int = 512
    moving_speed: int = 0
    torque_limit: int = 1023
    punch: int = 32
    cw_angle_limit: int = 0
    ccw_angle_limit: int = 1023
    max_torque: int = 1023
    alarm_led: int = 36  # overload | overheating
    alarm_shutdown: int = 36
    lock: int = 0


@dataclass(frozen=True)
class ServoReport:
    """What the servo answers to a READ, raw words as in its control table.

    Attributes:
        position: Present Position 0..1023.
        speed: Present Speed (bits 0-9 magnitude, bit 10 = CW).
        load: Present Load (bits 0-9 magnitude in 0.1 % of full torque, bit 10 = CW).
        voltage: Present Voltage, 0.1 V.
        temperature: Present Temperature, °C.
        moving: 1 while the set-point has not reached the goal or the horn moves.
        error: status error byte.
        torque_enable: the Torque Enable register.
        torque_limit: the Torque Limit register (0 after an overload shutdown).
    """

    position: int
    speed: int
    load: int
    voltage: int
    temperature: int
    moving: int
    error: int
    torque_enable: int
    torque_limit: int


def effective_slope(raw: int) -> int:
    """Compliance slope register -> its effective step 2, 4, ..., 128 (thesis Table 2.4).

    0-3 -> 2, 4-7 -> 4, 8-15 -> 8, ..., 128-255 -> 128.
    """
    v = max(int(raw) & 0xFF, 2)
    return min(1 << (v.bit_length() - 1), 128)


_SLOPE_STEPS = tuple(effective_slope(v) for v in range(256))


def compliance_duty(error: float, *, margin: int, slope: int, punch: int,
                    torque_limit: int) -> float:
    """Output duty 0..1023 (magnitude) of the compliance curve for a position error in counts.

    Zero while |error| <= margin; Punch at the margin's edge; then rising linearly with
    (torque_limit − punch) / effective_slope per count, capped at torque_limit (the
    manual's Figure "compliance margin and slope", thesis Gambar 2.20).
    """
    e = abs(error)
    if e <= margin or torque_limit <= 0:
        return 0.0
    p = min(punch, torque_limit)
    return min(float(torque_limit), p + (e - margin) * (torque_limit - p) / effective_slope(slope))


class ServoModel(GearedMotor):
    """One servo's firmware and motor.

    Args:
        spec: the datasheet (``armlab.hardware.servos.servo_spec.RX24F`` or ``AX12A``).
        regs: its registers (a fresh factory-default set when omitted). Shared, not copied:
            writes to it take effect at the next :meth:`update`.
        params: physical constants (:class:`ServoParams`).
        angle: initial horn angle, rad from centre (the goal register starts there, as a
            real servo's Goal Position starts at its Present Position).
    """

    def __init__(self, spec: ServoSpec, regs: ServoRegisters | None = None, *,
                 params: ServoParams | None = None, angle: float = 0.0) -> None:
        self.spec = spec
        self.params = params or ServoParams()
        self._counts_per_rad = 1.0 / spec.position_unit
        self._counts_per_speed_unit = spec.speed_unit / spec.position_unit
        self._backemf = spec.stall_torque / spec.no_load_speed
        self._angle = float(angle)
        self._velocity = 0.0
        self._present = spec.position_to_raw(self._angle)
        if regs is None:
            regs = ServoRegisters(goal_position=self._present)
        self.regs = regs
        self._setpoint = float(self._present)
        self._enabled = False
        self._duty = 0.0  # -1..1
        self._stall_time = 0.0
        self._overload = False
        self._shutdown = False
        self._angle_error = False
        self._moving = False

    # -- firmware tick ------------------------------------------------------

    def update(self, dt: float, angle: float, velocity: float) -> None:
        """One firmware tick of ``dt`` s at horn ``angle`` (rad) and ``velocity`` (rad/s)."""
        regs = self.regs
        self._angle = angle
        self._velocity = velocity
        present = round(512.0 + angle * self._counts_per_rad)
        present = 0 if present < 0 else (1023 if present > 1023 else present)
        self._present = present
        torque_limit = regs.torque_limit & 0x3FF
        if self._shutdown and torque_limit > 0 and regs.torque_enable:
            self._shutdown = False  # recovered: Torque Limit and Torque Enable written again
            self._overload = False
            self._stall_time = 0.0
        enabled = bool(regs.torque_enable) and not self._shutdown
        if enabled and not self._enabled:
            self._setpoint = float(present)  # no jump when torque comes on
        self._enabled = enabled
        cw, ccw = regs.cw_angle_limit & 0x3FF, regs.ccw_angle_limit & 0x3FF
        goal = regs.goal_position & 0x3FF
        duty = 0.0
        if cw == 0 and ccw == 0:  # wheel mode: Moving Speed is the PWM duty
            self._angle_error = False
            self._setpoint = float(present)
            speed = regs.moving_speed & 0x7FF
            if enabled:
                duty = min(speed & 0x3FF, torque_limit) / 1023.0
                if speed & DIRECTION_BIT:
                    duty = -duty
            self._moving = speed & 0x3FF != 0
        else:
            self._angle_error = not (cw <= goal <= ccw)
            target = float(cw if goal < cw else (ccw if goal > ccw else goal))
            raw_speed = regs.moving_speed & 0x3FF
            sp = self._setpoint
            if not enabled:
                sp = float(present)
            elif raw_speed == 0:
                sp = target
            elif sp != target:
                step = raw_speed * self._counts_per_speed_unit * dt
                if sp < target:
                    sp = sp + step if sp + step < target else target
                else:
                    sp = sp - step if sp - step > target else target
            self._setpoint = sp
            if enabled and torque_limit > 0:
                rsp = round(sp)
                error = rsp - present
                if error > 0:
                    margin, slope = regs.ccw_compliance_margin, regs.ccw_compliance_slope
                else:
                    margin, slope = regs.cw_compliance_margin, regs.cw_compliance_slope
                    error = -error
                if error > margin:  # the compliance curve (see compliance_duty)
                    punch = regs.punch if regs.punch < torque_limit else torque_limit
                    level = punch + (error - margin) * (torque_limit - punch) / \
                        _SLOPE_STEPS[slope & 0xFF]
                    duty = (torque_limit if level > torque_limit else level) / 1023.0
                    if rsp < present:
                        duty = -duty
            self._moving = sp != target or abs(velocity) > self.spec.speed_unit
        self._duty = duty
        if torque_limit > 0 and abs(duty) * 1023.0 >= torque_limit - 0.5 or self._stall_time:
            self._check_overload(dt, duty, velocity, torque_limit)
        if self._duty != 0.0:
            self.drive = self._duty * self.spec.stall_torque
            self.damping = self._backemf
        else:
            self.drive = 0.0
            self.damping = 0.0

    def _check_overload(self, dt: float, duty: float, velocity: float, torque_limit: int) -> None:
        """Overload: full duty (at Torque Limit) without moving for ``overload_time``."""
        p = self.params
        if torque_limit > 0 and abs(duty) * 1023.0 >= torque_limit - 0.5 and \
                abs(velocity) < p.stall_speed:
            self._stall_time += dt
        else:
            self._stall_time = 0.0
        self._overload = self._shutdown or self._stall_time > p.overload_time
        if self._overload and not self._shutdown and self.regs.alarm_shutdown & ERROR_OVERLOAD:
            # Alarm Shutdown: torque off, Torque Limit to 0 until the user writes it again.
            self._shutdown = True
            self.regs.torque_enable = 0
            self.regs.torque_limit = 0
            self._enabled = False
            self._duty = 0.0

    # -- what the servo reports --------------------------------------------

    @property
    def duty(self) -> float:
        """PWM duty of this tick, −1..1 (CCW positive)."""
        return self._duty

    def present_position(self) -> int:
        """Present Position 0..1023 (10-bit potentiometer reading at the last tick)."""
        return self._present

    def present_speed(self) -> int:
        """Present Speed word (0.111 rpm units, bit 10 = CW)."""
        return self.spec.present_speed_to_raw(self._velocity)

    def present_load(self) -> int:
        """Present Load word: the duty the firmware applies, 0..1023, bit 10 = CW."""
        return signed_word(self._duty * 1023.0)

    def present_voltage(self) -> int:
        """Present Voltage, 0.1 V."""
        return int(round(self.params.voltage * 10))

    def present_temperature(self) -> int:
        """Present Temperature, °C."""
        return int(round(self.params.temperature))

    def moving(self) -> int:
        """Moving register: 1 while going to the goal."""
        return int(self._moving)

    def error(self) -> int:
        """The status packet's error byte (angle limit and overload bits; 0 = healthy)."""
        return (ERROR_ANGLE_LIMIT if self._angle_error else 0) | \
            (ERROR_OVERLOAD if self._overload else 0)

    def report(self) -> ServoReport:
        """Every present value as raw words."""
        return ServoReport(
            position=self.present_position(), speed=self.present_speed(),
            load=self.present_load(), voltage=self.present_voltage(),
            temperature=self.present_temperature(), moving=self.moving(), error=self.error(),
            torque_enable=int(self.regs.torque_enable), torque_limit=self.regs.torque_limit,
        )
