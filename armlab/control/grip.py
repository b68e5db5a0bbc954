"""Open, close and a compliant grasp for the thesis's three-finger hand (thesis §2.4, §3.1.1).

The hand's only sensors are the motor current sensors (thesis §2.4: "with a
current sensor ... the motor torque can be obtained"). From a measured current
the controller knows the motor torque (tau = K_t·I, eq. 2.29), hence the tendon
tension, and with the finger's geometry and spring the fingertip force
(:func:`armlab.kinematics.hand_statics.grip_force_from_tension`). A grasp then closes the
fingers until each one holds the object with the chosen grip force F and no
more: a compliant grasp, whatever the object's size or stiffness.

How it closes, per finger (all in :meth:`GripController.update`):

1. Approach ("closing"): a speed loop drives the fingertip at
   ``approach_speed`` with the current capped at what a light touch force
   (``touch_force``) needs, so the first contact is soft.
2. Contact: the finger has stopped (estimated speed under a third of the
   approach speed) while pushing with at least half the touch force, for
   ``contact_time``. At the closed stop that means "empty" (nothing held).
3. Squeeze ("squeezing", then "holding"): current control at the current
   that holds the force cap, the cap rising at ``ramp_rate`` and easing into
   F (time constant ``RAMP_EASE``), so the finger arrives at rest. If the
   finger speeds off (the object gave way or was taken), it approaches again.

Never crushing (the documented margin): the impact at first touch adds
about v·sqrt(k·m_eff) to the touch force (m_eff ≈ 5 g at the fingertip: the
rotor seen through gearbox and tendon, softened by the tendon's stretch).
With the defaults the first touch peaks at about 0.1 N for objects up to
5000 N/m (about 0.35 N at the 50 kN/m maximum) whatever F, and the eased ramp
overshoots F by well under 1 %. So the peak is at most max(1.02·F, first-touch
peak): within 2 % of F for F >= 0.2 N and objects up to 5000 N/m
(tests/test_hand_grip.py). A slower approach softens the first touch.

Without a position sensor, the motor speed comes from its electrical
equation, omega = (V − R·I)/K_e (:func:`back_emf_speed`), integrated to the
motor angle and, through the tendon, the finger angle (needed for the spring
torque and the lever). A current sensor with an RC filter is undone first
(:func:`unfilter_current`). Open drives the motor back past the angle where
the tendon goes slack at the open stop; the spring opens the finger.

The controller never sees the plant: it takes measured currents (3,) A and
returns motor voltages (3,) V. :func:`simulate_grasp` wires it to anything that
satisfies :class:`HandPlant` (the simulator in ``armlab.hardware.sim.hand_plant``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from armlab.kinematics.hand_statics import (
    FingerGeometry,
    contact_lever,
    grip_force_from_tension,
    motor_torque,
    tension_for_grip_force,
)
from armlab.kinematics.validate import scalar, vector

N_FINGERS = 3
#: Per-finger modes, in the order a grasp goes through them ("empty": closed on nothing).
MODES = ("idle", "opening", "closing", "squeezing", "holding", "empty")
OPEN_SLACK = -0.5  #: rad (motor output) of tendon slack left when open
OPEN_GAIN = 2.0  #: V per rad of motor angle error while opening
RAMP_EASE = 0.05  #: s, time constant of the force cap's approach to the limit


class MotorConstants(Protocol):
    """The motor numbers the controller needs (output shaft, SI)."""

    @property
    def kt(self) -> float: ...
    @property
    def ke(self) -> float: ...
    @property
    def resistance(self) -> float: ...
    @property
    def inductance(self) -> float: ...
    @property
    def supply(self) -> float: ...


class HandPlant(Protocol):
    """A hand the controller can drive (``armlab.hardware.sim.hand_plant.HandSim`` is one)."""

    @property
    def motor(self) -> MotorConstants: ...
    @property
    def finger(self) -> FingerGeometry: ...
    @property
    def current_lpf_hz(self) -> float | None:
        """Cut-off of the current sensor's RC filter, Hz (None: unfiltered)."""
        ...
    @property
    def t(self) -> float: ...
    @property
    def obj(self) -> object:
        """The object between the fingers (None: nothing)."""
        ...
    # Any: each simulator takes its own object type (HandSim a GraspObject or None)
    def set_object(self, obj: Any) -> None:
        """Put ``obj`` (the simulator's object, or None) between the fingers."""
        ...
    @property
    def contact_force(self) -> np.ndarray:
        """(3,) N, the true fingertip forces (for the figures; the controller never reads it)."""
        ...
    @property
    def finger_angle(self) -> np.ndarray:
        """(3,) rad, the true finger angles (for drawing; the controller never reads it)."""
        ...

    def step(self, voltage: np.ndarray, duration: float) -> np.ndarray:
        """Apply ``voltage`` (3,) V for ``duration`` s; return the measured currents (3,) A."""
        ...


@dataclass(frozen=True)
class GripModel:
    """What the controller knows of the hand (nominal values, output shaft, SI)."""

    kt: float
    ke: float
    resistance: float
    inductance: float
    supply: float
    finger: FingerGeometry
    current_lpf_hz: float | None = None

    @classmethod
    def of(cls, plant: HandPlant) -> GripModel:
        """The nominal model of ``plant`` (its datasheet motor, geometry and sensor filter)."""
        m = plant.motor
        return cls(
            m.kt, m.ke, m.resistance, m.inductance, m.supply, plant.finger, plant.current_lpf_hz
        )

    def current_for_force(self, force: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Motor current (A) that holds fingertip force ``force`` (N) at finger angle ``phi``.

        Tendon tension from the hinge balance, motor torque = tension · spool
        radius, current = torque / K_t (eq. 2.29).
        """
        g = self.finger
        return tension_for_grip_force(g, force, phi) * g.spool_radius / self.kt

    def force_from_current(self, current: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Fingertip force (N) that a measured ``current`` (A) holds at ``phi`` (static).

        tau = K_t·I (eq. 2.29) at the spool, tension = tau / spool radius, then
        the hinge balance. Can be negative (the spring not yet overcome).
        """
        g = self.finger
        tension = motor_torque(self.kt, current) / g.spool_radius
        return grip_force_from_tension(g, tension, phi)

    def max_force(self) -> float:
        """N, the largest grip force the controller accepts: at 80 % of the stall
        current (headroom for the current loop) with the finger upright (phi = 0)."""
        i = 0.8 * self.supply / self.resistance
        return float(self.force_from_current(np.array(i), np.array(0.0)))


@dataclass(frozen=True)
class GripParams:
    """The grasp's settings (swap the whole object to change them).

    Attributes:
        force_limit: N, the grip force F each finger holds the object with.
        approach_speed: m/s, fingertip speed while closing towards the object.
        touch_force: N, force cap before contact (capped at force_limit).
        ramp_rate: N/s, how fast the force cap rises from touch to F.
        contact_time: s, how long a finger must stall at its cap to count as touching.
        open_voltage: V, the largest voltage used to open.
        speed_gain: A per rad/s (motor output) of the approach speed loop.
        speed_integral: A per rad of the speed loop's integral.
        current_gain: V/A of the current loop (below R = 3.75 ohm for stability
            at a 1 ms period).
        current_integral: V/(A·s) of the current loop's integral.
    """

    force_limit: float = 1.0
    approach_speed: float = 0.03
    touch_force: float = 0.1
    ramp_rate: float = 5.0
    contact_time: float = 0.02
    open_voltage: float = 4.0
    speed_gain: float = 0.005
    speed_integral: float = 0.3
    current_gain: float = 1.5
    current_integral: float = 500.0

    def __post_init__(self) -> None:
        for name in (
            "force_limit", "approach_speed", "touch_force", "ramp_rate", "contact_time",
            "open_voltage",
        ):
            scalar(name, getattr(self, name), positive=True)
        for name in ("speed_gain", "speed_integral", "current_gain", "current_integral"):
            scalar(name, getattr(self, name), nonnegative=True)


def back_emf_speed(model: GripModel, voltage: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Motor speed (rad/s, output shaft) from its electrical equation, arrays (3,).

    V = R·I + L·dI/dt + K_e·omega averaged over one period during which
    ``voltage`` was applied and at whose end ``current`` was measured. After a
    voltage step the current settles with L/R (0.13 ms, far shorter than the
    1 ms period), so the period's integral of R·I + L·dI/dt is R·I_end·dt
    exactly (the L terms cancel) and omega = (V − R·I_end)/K_e.
    """
    return (voltage - model.resistance * current) / model.ke


def unfilter_current(
    filtered: np.ndarray, previous: np.ndarray, cutoff_hz: float | None, dt: float
) -> np.ndarray:
    """Undo the current sensor's RC low-pass: the mean current over the last period, A (3,).

    For a current held constant over the period, an RC filter's output goes
    from ``previous`` to ``filtered`` = I + (previous − I)·a with
    a = exp(−dt/RC), so I = (filtered − a·previous)/(1 − a). Exact for a
    noise-free sensor and a current that settles fast (L/R ≪ dt).
    """
    if cutoff_hz is None:
        return filtered
    a = math.exp(-2.0 * math.pi * cutoff_hz * dt)
    return (filtered - a * previous) / (1.0 - a)


@dataclass
class GripState:
    """The controller's memory; arrays are (3,), one entry per finger."""

    mode: list[str]
    motor_angle: np.ndarray
    finger_angle: np.ndarray
    speed: np.ndarray
    current: np.ndarray
    measured: np.ndarray
    voltage: np.ndarray
    force_cap: np.ndarray
    stall_time: np.ndarray
    speed_sum: np.ndarray
    current_sum: np.ndarray


class GripController:
    """Open/close and force-limited grasp of three fingers from their motor currents.

    Call :meth:`update` once per period ``dt`` with the measured currents; it
    returns the voltages to apply until the next call. :meth:`close`,
    :meth:`open` and :meth:`set_params` may be called between updates.
    """

    def __init__(
        self, model: GripModel, params: GripParams | None = None, *, dt: float = 1.0e-3
    ) -> None:
        self.model = model
        self._params = params if params is not None else GripParams()
        self._check_force(self._params)
        self.dt = scalar("dt", dt, positive=True)
        z = np.zeros(N_FINGERS)
        self._s = GripState(
            mode=["idle"] * N_FINGERS,
            motor_angle=z.copy(),
            finger_angle=np.full(N_FINGERS, model.finger.open_angle),
            speed=z.copy(),
            current=z.copy(),
            measured=z.copy(),
            voltage=z.copy(),
            force_cap=z.copy(),
            stall_time=z.copy(),
            speed_sum=z.copy(),
            current_sum=z.copy(),
        )

    # --- commands ----------------------------------------------------------------
    @property
    def params(self) -> GripParams:
        return self._params

    def _check_force(self, params: GripParams) -> None:
        fmax = self.model.max_force()
        if params.force_limit > fmax:
            raise ValueError(
                f"force_limit must be <= {fmax:.2f} N (what the 6 V motors can hold), "
                f"got {params.force_limit:g}"
            )

    def set_params(self, params: GripParams) -> None:
        """Use ``params`` from the next update. A lower force limit applies at once;
        a higher one is ramped up at ``ramp_rate``."""
        self._check_force(params)
        self._params = params
        s = self._s
        s.force_cap = np.minimum(s.force_cap, params.force_limit)
        for i, mode in enumerate(s.mode):
            if mode == "holding" and s.force_cap[i] < params.force_limit:
                s.mode[i] = "squeezing"

    def set_force_limit(self, force: float) -> None:
        """Shorthand: change only the grip force limit F (N)."""
        self.set_params(replace(self._params, force_limit=scalar("force", force, positive=True)))

    def close(self) -> None:
        """Start a grasp: approach, touch, squeeze to the force limit, hold."""
        s = self._s
        for i in range(N_FINGERS):
            s.mode[i] = "closing"
        s.force_cap[:] = min(self._params.touch_force, self._params.force_limit)
        s.stall_time[:] = 0.0
        s.speed_sum[:] = 0.0
        s.current_sum[:] = 0.0

    def open(self) -> None:
        """Release: unwind the tendons to the open stop, then stop the motors."""
        s = self._s
        for i in range(N_FINGERS):
            s.mode[i] = "opening"
        s.current_sum[:] = 0.0

    def stop(self) -> None:
        """Motors off now (0 V from the next update); the springs open the fingers."""
        s = self._s
        for i in range(N_FINGERS):
            s.mode[i] = "idle"

    # --- what the UI and the figures read ---------------------------------------
    @property
    def modes(self) -> tuple[str, ...]:
        return tuple(self._s.mode)

    @property
    def finger_angle(self) -> np.ndarray:
        """(3,) rad, the back-EMF estimate of each finger's angle."""
        return self._s.finger_angle.copy()

    @property
    def force_cap(self) -> np.ndarray:
        """(3,) N, the force each finger is currently allowed."""
        return self._s.force_cap.copy()

    def estimated_force(self) -> np.ndarray:
        """(3,) N, fingertip force from the last measured current (0 while not touching)."""
        s = self._s
        f = self.model.force_from_current(s.current, s.finger_angle)
        touching = np.array([m in ("squeezing", "holding") for m in s.mode])
        return np.where(touching, np.maximum(f, 0.0), 0.0)

    # --- the law -------------------------------------------------------------------
    def update(self, current: np.ndarray) -> np.ndarray:
        """One period: measured currents (3,) A in, motor voltages (3,) V out.

        Raises ValueError on a non-finite current (and leaves its state as it was).
        """
        measured = vector("current", current, N_FINGERS)
        m, g, s, dt = self.model, self.model.finger, self._s, self.dt
        i_meas = unfilter_current(measured, s.measured, m.current_lpf_hz, dt)
        s.measured = measured
        # sensorless state: speed and angles from the back-EMF
        s.speed = back_emf_speed(m, s.voltage, i_meas)
        s.current = i_meas
        s.motor_angle = s.motor_angle + s.speed * dt
        tension = np.maximum(motor_torque(m.kt, i_meas), 0.0) / g.spool_radius
        stretch = tension / g.tendon_stiffness / g.spool_radius  # motor rad
        s.finger_angle = np.clip(
            g.open_angle + (s.motor_angle - stretch) / g.ratio, g.open_angle, g.closed_angle
        )
        volts = np.zeros(N_FINGERS)
        for i, mode in enumerate(s.mode):
            if mode == "opening":
                volts[i] = self._open_law(i)
            elif mode in ("closing", "squeezing", "holding", "empty"):
                volts[i] = self._close_law(i)
        s.voltage = np.clip(volts, -m.supply, m.supply)
        return s.voltage.copy()

    def _open_law(self, i: int) -> float:
        s, p = self._s, self._params
        err = OPEN_SLACK - s.motor_angle[i]
        if abs(err) < 0.2 and abs(s.speed[i]) < 2.0:
            s.mode[i] = "idle"
            return 0.0
        return float(np.clip(OPEN_GAIN * err, -p.open_voltage, p.open_voltage))

    def _close_law(self, i: int) -> float:
        s, p, m, g, dt = self._s, self._params, self.model, self.model.finger, self.dt
        phi = s.finger_angle[i]
        mode = s.mode[i]
        # the force cap: touch before contact, ramp to F after
        if mode == "squeezing":
            # rise at ramp_rate, easing into F over RAMP_EASE s so the finger arrives at rest
            gap = p.force_limit - s.force_cap[i]
            s.force_cap[i] += min(p.ramp_rate, gap / RAMP_EASE) * dt
            if gap <= 0.002 * p.force_limit:
                s.force_cap[i] = p.force_limit
                s.mode[i] = "holding"
        # the currents that hold no force (the spring alone) and the capped force
        i_spring, i_cap = m.current_for_force(np.array([0.0, s.force_cap[i]]), phi).tolist()
        omega_ref = p.approach_speed / float(contact_lever(g, phi)) * g.ratio
        if mode in ("squeezing", "holding", "empty"):
            # force control: the current that holds the capped force
            i_ref = i_cap
            if s.speed[i] > 2.0 * omega_ref:  # the object gave way: approach again
                s.mode[i] = "closing"
                s.force_cap[i] = min(p.touch_force, p.force_limit)
                s.speed_sum[i] = 0.0
        else:
            # approach: speed loop, current capped at the touch force
            err = omega_ref - s.speed[i]
            i_ref = i_spring + p.speed_gain * err + s.speed_sum[i]
            if i_ref >= i_cap:
                i_ref = i_cap
            elif i_ref <= -i_cap:
                i_ref = -i_cap
            else:
                s.speed_sum[i] += p.speed_integral * err * dt
            # contact: stopped while pushing with at least half the touch force
            pushing = i_ref >= 0.5 * (i_spring + i_cap)
            stalled = pushing and s.speed[i] < omega_ref / 3.0
            s.stall_time[i] = s.stall_time[i] + dt if stalled else 0.0
            if s.stall_time[i] >= p.contact_time:
                at_stop = phi >= g.closed_angle - 0.01
                s.mode[i] = "empty" if at_stop else "squeezing"
        # current loop with back-EMF feed-forward
        i_err = i_ref - s.current[i]
        s.current_sum[i] += p.current_integral * i_err * dt
        s.current_sum[i] = min(max(s.current_sum[i], -m.supply), m.supply)
        return (
            m.resistance * i_ref + m.ke * s.speed[i] + p.current_gain * i_err + s.current_sum[i]
        )


@dataclass(frozen=True)
class GraspTrace:
    """A simulated grasp, sampled every control period.

    Attributes:
        t: (k,) s.
        voltage: (k, 3) V applied.
        current: (k, 3) A measured.
        force: (k, 3) N, true fingertip forces.
        estimate: (k, 3) N, the controller's force estimate from the current.
        angle: (k, 3) rad, the true finger angles (None where not recorded).
    """

    t: np.ndarray
    voltage: np.ndarray
    current: np.ndarray
    force: np.ndarray
    estimate: np.ndarray
    angle: np.ndarray | None = None


def simulate_grasp(
    plant: HandPlant,
    controller: GripController,
    *,
    duration: float,
    open_at: float | None = None,
) -> GraspTrace:
    """Close at t = 0, optionally open at ``open_at`` s, run ``duration`` s (times from the close).

    One period with the motors off comes first, for a first sensor reading.
    """
    duration = scalar("duration", duration, positive=True)
    dt = controller.dt
    n = max(1, math.ceil(duration / dt - 1e-9))
    t = np.empty(n)
    volt, cur, force, est, angle = (np.empty((n, N_FINGERS)) for _ in range(5))
    current = plant.step(np.zeros(N_FINGERS), dt)  # a first sensor reading, motors off
    t0 = plant.t
    controller.close()
    for k in range(n):
        if open_at is not None and k == round(open_at / dt):
            controller.open()
        v = controller.update(current)
        current = plant.step(v, dt)
        t[k] = plant.t - t0
        volt[k], cur[k], force[k] = v, current, plant.contact_force
        est[k], angle[k] = controller.estimated_force(), plant.finger_angle
    return GraspTrace(t, volt, cur, force, est, angle)


def grasp_figures(
    trace: GraspTrace, force_limit: float, *, settle: float = 0.2
) -> dict[str, float | None]:
    """The grasp's figures from a trace.

    - steady_force_N: mean true fingertip force over the last ``settle`` s
      (mean of the three fingers).
    - peak_force_N: the largest fingertip force at any time on any finger.
    - time_to_grasp_s: first time every finger holds at least 90 % of
      ``force_limit`` (None if never).
    - final_current_A: mean measured current at the end.
    """
    last = trace.t >= trace.t[-1] - settle
    held = np.all(trace.force >= 0.9 * force_limit, axis=1)
    when = float(trace.t[np.argmax(held)]) if held.any() else None
    return {
        "steady_force_N": float(trace.force[last].mean()),
        "peak_force_N": float(trace.force.max()),
        "time_to_grasp_s": when,
        "final_current_A": float(trace.current[-1].mean()),
    }
