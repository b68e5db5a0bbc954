"""The thesis's three-finger hand as a plant: DC gearmotors, tendons, springs, an object.

Thesis §2.4 and §3.1.1: each of the three fingers is pulled by its own 6 V DC
gearmotor (5:1, 24 x 10 x 12 mm) through a tendon against a return spring, and a
current sensor on each motor gives its torque (tau = K_t·I, eq. 2.29). This
module simulates that hardware: per finger the motor's electrical circuit and
rotor, an elastic tendon that only pulls, the finger on its hinge with its
spring and stops, and the contact with a cylindrical object of chosen size,
stiffness and damping. The current sensor returns the true current, optionally
through an RC low-pass filter.

Fixed step: :meth:`HandSim.step` advances by whole plant steps (0.1 ms by
default, ten per 1 ms control period; the contact with a hard object and the
tendon are too stiff for a 1 ms explicit step) with the voltage held constant.

The geometry of the fingers lives in :mod:`armlab.kinematics.hand_statics`; the controller that
closes the hand with a force limit lives in :mod:`armlab.control.grip`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from armlab.kinematics.hand_statics import (
    GEARMOTOR_GEAR_RATIO,
    GEARMOTOR_STALL_CURRENT,
    GEARMOTOR_STALL_TORQUE,
    FingerGeometry,
    motor_torque,
    torque_constant,
)
from armlab.kinematics.validate import scalar, vector

RPM = 2.0 * math.pi / 60.0  #: 1 rpm in rad/s
N_FINGERS = 3


@dataclass(frozen=True)
class DCMotor:
    """A brushed DC gearmotor seen at its gearbox output shaft.

    Attributes:
        supply: V, the rated (and maximum) drive voltage.
        resistance: ohm, armature resistance R.
        inductance: H, armature inductance L.
        kt: N·m/A, torque constant at the output (gear ratio included), eq. 2.29.
        ke: V·s/rad, back-EMF constant at the output.
        friction: N·m·s/rad, viscous friction at the output (motor + gearbox).
        inertia: kg·m², rotor + gears reflected to the output.
    """

    supply: float
    resistance: float
    inductance: float
    kt: float
    ke: float
    friction: float
    inertia: float

    @classmethod
    def from_datasheet(
        cls,
        *,
        voltage: float = 6.0,
        free_speed_rpm: float = 6000.0,
        free_current: float = 0.120,
        stall_current: float = GEARMOTOR_STALL_CURRENT,
        stall_torque: float = GEARMOTOR_STALL_TORQUE,
        gear_ratio: float = GEARMOTOR_GEAR_RATIO,
        inductance: float = 0.5e-3,
        rotor_inertia: float = 5.0e-9,
    ) -> DCMotor:
        """Motor constants from the thesis's gearmotor datasheet (§2.4).

        Defaults are the thesis's numbers: 6 V, 5:1, 6000 rpm and 120 mA free
        run, 1.6 A and 2 oz·in stall, all at the gearbox output. The datasheet
        gives no inductance or rotor inertia; the defaults (0.5 mH; 5e-9 kg·m²
        at the motor shaft, typical of a 10 mm can) are assumptions.

        Derivation (steady state, output shaft, omega_0 = 6000 rpm = 628.3 rad/s):

        - Stall (omega = 0, so no back-EMF and no viscous friction):
          V = R·I_s gives R = 6 / 1.6 = 3.75 ohm, and tau_s = K_t·I_s
          (eq. 2.29) gives K_t = 0.014123 / 1.6 = 8.827e-3 N·m/A.
        - Free run (no load): V = R·I_0 + K_e·omega_0 gives
          K_e = (6 − 3.75·0.12) / 628.3 = 8.833e-3 V·s/rad. It equals K_t to
          0.07 %, as it must for an ideal motor in SI units: the datasheet is
          consistent, so the gearbox loss is all in the no-load current.
        - No-load friction: at free run the motor torque K_t·I_0 all goes into
          friction. Modelled as viscous, b = K_t·I_0 / omega_0 = 1.69e-6
          N·m·s/rad (zero at stall, which is why the stall point gave K_t
          directly). Free run then takes exactly I_0 at omega_0.
        - Reflected inertia: rotor_inertia · gear_ratio².
        """
        omega0 = free_speed_rpm * RPM
        r = voltage / stall_current
        kt = torque_constant(stall_torque, stall_current)
        ke = (voltage - r * free_current) / omega0
        b = kt * free_current / omega0
        return cls(
            supply=voltage,
            resistance=r,
            inductance=inductance,
            kt=kt,
            ke=ke,
            friction=b,
            inertia=rotor_inertia * gear_ratio**2,
        )

    @property
    def stall_torque(self) -> float:
        """N·m at the output with the full supply across a stalled rotor."""
        return float(motor_torque(self.kt, self.supply / self.resistance))


def rc_alpha(h: float, cutoff_hz: float) -> float:
    """alpha of the current sensor's low-pass filter y[i] = y[i−1] + alpha·(x[i] − y[i−1]).

    That is the thesis's LPF (§2.2, there on the servo load, with
    alpha = dt/(RC + dt)); for the sensor's analog RC filter of cut-off
    ``cutoff_hz`` sampled every ``h`` s the exact value is 1 − exp(−h/RC).
    """
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * h)


@dataclass(frozen=True)
class GraspObject:
    """A cylinder on the palm axis between the fingers.

    Attributes:
        size: m, diameter.
        stiffness: N/m, contact stiffness at each fingertip (object + finger pad).
        damping: N·s/m, contact damping (the contact only pushes).
    """

    size: float = 0.06
    stiffness: float = 1000.0
    damping: float = 1.0

    def __post_init__(self) -> None:
        scalar("size", self.size, positive=True)
        scalar("stiffness", self.stiffness, positive=True)
        scalar("damping", self.damping, nonnegative=True)


MAX_STIFFNESS = 5.0e4  #: N/m; stiffer contacts would need a shorter plant step
MAX_DAMPING = 20.0  #: N·s/m; likewise


@dataclass(frozen=True)
class HandParams:
    """Everything fixed about the simulated hand.

    Attributes:
        motor: the gearmotor (the same on each finger).
        finger: finger and tendon geometry.
        finger_inertia: kg·m² of a finger about its hinge (8 g, 6 cm rod: m L²/3).
        hinge_damping: N·m·s/rad at the finger hinge.
        tendon_damping: N·s/m along the tendon.
        dt: s, plant step.
        current_lpf_hz: cut-off of the current sensor's RC filter; None = unfiltered.
    """

    motor: DCMotor = field(default_factory=DCMotor.from_datasheet)
    finger: FingerGeometry = field(default_factory=FingerGeometry)
    finger_inertia: float = 0.008 * 0.06**2 / 3.0
    hinge_damping: float = 1.0e-5
    tendon_damping: float = 20.0
    dt: float = 1.0e-4
    current_lpf_hz: float | None = None

    def __post_init__(self) -> None:
        scalar("dt", self.dt, positive=True)
        if self.current_lpf_hz is not None:
            scalar("current_lpf_hz", self.current_lpf_hz, positive=True)


def check_object(obj: GraspObject, finger: FingerGeometry) -> GraspObject:
    """Refuse an object the simulated hand cannot hold (ValueError naming the field)."""
    if obj.size >= finger.max_size:
        raise ValueError(
            f"size {obj.size * 100:.1f} cm does not fit between the open fingers "
            f"(at most {finger.max_size * 100:.1f} cm)"
        )
    if obj.stiffness > MAX_STIFFNESS:
        raise ValueError(f"stiffness must be <= {MAX_STIFFNESS:g} N/m, got {obj.stiffness:g}")
    if obj.damping > MAX_DAMPING:
        raise ValueError(f"damping must be <= {MAX_DAMPING:g} N·s/m, got {obj.damping:g}")
    return obj


@dataclass
class HandState:
    """The hand's state; every array is (3,), one entry per finger.

    Attributes:
        t: s since the start.
        current: A, true armature current.
        measured: A, what the current sensor reads (after its filter).
        motor_angle: rad at the gearbox output, 0 where the tendon goes taut
            with the finger on its open stop.
        motor_speed: rad/s at the output.
        finger_angle: rad, see :mod:`armlab.kinematics.hand_statics`.
        finger_speed: rad/s.
        tension: N in each tendon (>= 0).
        contact_force: N, the object's normal force on each fingertip (>= 0).
    """

    t: float
    current: np.ndarray
    measured: np.ndarray
    motor_angle: np.ndarray
    motor_speed: np.ndarray
    finger_angle: np.ndarray
    finger_speed: np.ndarray
    tension: np.ndarray
    contact_force: np.ndarray


def _zeros() -> np.ndarray:
    return np.zeros(N_FINGERS)


class HandSim:
    """The simulated hand: three motor + tendon + finger units around one object.

    ``step(voltage, duration)`` is the only way time moves; it returns what the
    current sensors read. The object can be swapped or removed at any time.
    """

    def __init__(self, params: HandParams | None = None, obj: GraspObject | None = None) -> None:
        self._p = params if params is not None else HandParams()
        self._obj = check_object(obj, self._p.finger) if obj is not None else None
        self._s = self._initial()

    def _initial(self) -> HandState:
        return HandState(
            t=0.0,
            current=_zeros(),
            measured=_zeros(),
            motor_angle=_zeros(),
            motor_speed=_zeros(),
            finger_angle=np.full(N_FINGERS, self._p.finger.open_angle),
            finger_speed=_zeros(),
            tension=_zeros(),
            contact_force=_zeros(),
        )

    # --- what a controller (armlab.control.grip.HandPlant) sees -------------------------
    @property
    def motor(self) -> DCMotor:
        return self._p.motor

    @property
    def finger(self) -> FingerGeometry:
        return self._p.finger

    @property
    def current_lpf_hz(self) -> float | None:
        """Cut-off of the current sensor's filter (None: unfiltered)."""
        return self._p.current_lpf_hz

    @property
    def t(self) -> float:
        return self._s.t

    @property
    def measured_current(self) -> np.ndarray:
        """(3,) A, the current sensors' reading."""
        return self._s.measured.copy()

    @property
    def contact_force(self) -> np.ndarray:
        """(3,) N, true normal force between each fingertip and the object."""
        return self._s.contact_force.copy()

    @property
    def finger_angle(self) -> np.ndarray:
        """(3,) rad, true finger angles (for drawing; the controller has no angle sensor)."""
        return self._s.finger_angle.copy()

    # --- the rest ---------------------------------------------------------------
    @property
    def params(self) -> HandParams:
        return self._p

    @property
    def obj(self) -> GraspObject | None:
        return self._obj

    @property
    def state(self) -> HandState:
        """A copy of the state."""
        s = self._s
        return HandState(
            s.t, s.current.copy(), s.measured.copy(), s.motor_angle.copy(),
            s.motor_speed.copy(), s.finger_angle.copy(), s.finger_speed.copy(),
            s.tension.copy(), s.contact_force.copy(),
        )

    def set_object(self, obj: GraspObject | None) -> None:
        """Put ``obj`` between the fingers (None: take it away)."""
        self._obj = check_object(obj, self._p.finger) if obj is not None else None

    def reset(self, *, keep_time: bool = False) -> None:
        """Back to t = 0 (``keep_time``: at the time it is), hand open and at rest."""
        t = self._s.t
        self._s = self._initial()
        if keep_time:
            self._s.t = t

    def step(self, voltage: np.ndarray, duration: float) -> np.ndarray:
        """Drive the motors with ``voltage`` (3,) V for ``duration`` s; return the sensor reading.

        The voltage is clipped to ± the supply (the H-bridge cannot give more);
        a non-finite voltage raises ValueError and nothing moves.
        """
        v = np.clip(vector("voltage", voltage, N_FINGERS), -self.motor.supply, self.motor.supply)
        n = max(1, round(scalar("duration", duration, positive=True) / self._p.dt))
        s = self._s
        for i in range(N_FINGERS):
            out = self._advance_finger(
                float(v[i]), n, s.current[i], s.measured[i], s.motor_angle[i],
                s.motor_speed[i], s.finger_angle[i], s.finger_speed[i],
            )
            (s.current[i], s.measured[i], s.motor_angle[i], s.motor_speed[i],
             s.finger_angle[i], s.finger_speed[i], s.tension[i], s.contact_force[i]) = out
        s.t += n * self._p.dt
        return self.measured_current

    def _advance_finger(
        self, v: float, n: int, i: float, i_meas: float, th: float, om: float, phi: float,
        phid: float,
    ) -> tuple[float, ...]:
        """``n`` plant steps of one motor + tendon + finger at voltage ``v`` (scalars, SI).

        Per step: tendon tension (elastic, pulls only), contact force
        (spring-damper, pushes only), rotor and finger accelerations,
        semi-implicit Euler, inelastic hinge stops, then the armature current
        and the sensor filter (:func:`rc_alpha`). The current solves
        L dI/dt = V − R·I − K_e·omega exactly over the step (omega held), so it
        is stable although L/R = 0.13 ms.
        The geometry is :mod:`armlab.kinematics.hand_statics`'s (tip radius R_b − L sin phi,
        lever L cos phi, spring preload + rate·(phi − open)), written out on
        floats because this loop runs 10 000 times per simulated second.
        """
        p, m, g, obj = self._p, self._p.motor, self._p.finger, self._obj
        h = p.dt
        rp, rt, kt_, ct = g.spool_radius, g.tendon_arm, g.tendon_stiffness, p.tendon_damping
        lo, hi = g.open_angle, g.closed_angle
        radius = 0.5 * obj.size if obj is not None else -math.inf
        k_obj = obj.stiffness if obj is not None else 0.0
        d_obj = obj.damping if obj is not None else 0.0
        decay = math.exp(-h * m.resistance / m.inductance)
        alpha = 1.0 if p.current_lpf_hz is None else rc_alpha(h, p.current_lpf_hz)
        inv_jm, inv_jf = 1.0 / m.inertia, 1.0 / p.finger_inertia
        # the constants as locals: the loop reads each of them every step
        length, hinge_radius, preload, rate = (g.length, g.hinge_radius, g.spring_preload,
                                               g.spring_rate)
        kt, friction, ke, resistance = m.kt, m.friction, m.ke, m.resistance
        hinge_damping = p.hinge_damping
        cos, sin = math.cos, math.sin
        tension = force = 0.0
        for _ in range(n):
            stretch = rp * th - rt * (phi - lo)
            tension = max(0.0, kt_ * stretch + ct * (rp * om - rt * phid)) if stretch > 0 else 0.0
            lever = length * cos(phi)
            depth = radius - (hinge_radius - length * sin(phi))
            force = max(0.0, k_obj * depth + d_obj * lever * phid) if depth > 0 else 0.0
            torque = kt * i  # thesis eq. 2.29
            om += h * (torque - friction * om - rp * tension) * inv_jm
            th += h * om
            spring = preload + rate * (phi - lo)
            phid += h * (rt * tension - spring - hinge_damping * phid - force * lever) * inv_jf
            phi += h * phid
            if phi < lo:
                phi, phid = lo, max(phid, 0.0)
            elif phi > hi:
                phi, phid = hi, min(phid, 0.0)
            i_ss = (v - ke * om) / resistance
            i = i_ss + (i - i_ss) * decay
            i_meas += alpha * (i - i_meas)
        return i, i_meas, th, om, phi, phid, tension, force


def make_hand(
    *,
    size: float,
    stiffness: float,
    damping: float = 1.0,
    current_lpf_hz: float | None = None,
) -> HandSim:
    """A simulated hand, open and at rest, around a cylinder of diameter ``size`` m.

    ``stiffness`` N/m and ``damping`` N·s/m are the object's contact;
    ``current_lpf_hz`` the current sensor's filter (None: unfiltered). The
    factory ``armlab experiment hand-grip`` receives. Bad values raise
    ValueError naming the argument.
    """
    obj = GraspObject(size=size, stiffness=stiffness, damping=damping)
    return HandSim(HandParams(current_lpf_hz=current_lpf_hz), obj)
