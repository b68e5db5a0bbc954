"""N grasp controllers updated together: :class:`armlab.control.grip.GripController`, numpy over
hands.

The classroom's private hands (:class:`armlab.hardware.sim.batched_hand.BatchedHand`) each need the
thesis hand's compliant grasp (§2.4, §3.1.1). :class:`BatchedGrip` runs
:meth:`GripController.update`'s law for every hand at once: the sensorless state from
the back-EMF, then per finger the open law or the close law (approach with the current
capped at the touch force, contact, squeeze to F, hold; approach again when the object
gives way), each branch a mask over the (N, 3) arrays (hand, finger) instead of an
``if``. Every hand has its own :class:`GripParams` and commands (close, open, motors
off). tests/test_batched_grip.py checks N controllers against N ``GripController`` to
1e-9 over whole grasps.

Rows and ids as :class:`armlab.hardware.sim.batched_hand.BatchedHand`'s: :meth:`BatchedGrip.add`
returns a stable id; rows are the hands in the order they joined.
"""

from __future__ import annotations

import numpy as np

from armlab.control.batch_rows import BatchRows
from armlab.control.grip import (
    MODES,
    N_FINGERS,
    OPEN_GAIN,
    OPEN_SLACK,
    RAMP_EASE,
    GripModel,
    GripParams,
    back_emf_speed,
    unfilter_current,
)
from armlab.kinematics.hand_statics import contact_lever, motor_torque

IDLE, OPENING, CLOSING, SQUEEZING, HOLDING, EMPTY = range(len(MODES))
#: GripParams fields held per hand as an (N, 1) column
COLUMNS = ("force_limit", "approach_speed", "touch_force", "ramp_rate", "contact_time",
           "open_voltage", "speed_gain", "speed_integral", "current_gain", "current_integral")
#: the controller's memory, each (N, 3): GripState's arrays
MEMORY = ("motor_angle", "finger_angle", "speed", "current", "measured", "voltage",
          "force_cap", "stall_time", "speed_sum", "current_sum")


class BatchedGrip:
    """The grasp controllers of a class of hands (see the module docstring).

    Args:
        model: what every controller knows of its hand (they are all the same hand).
        dt: s, the control period.
    """

    def __init__(self, model: GripModel, *, dt: float = 1.0e-3) -> None:
        self.model = model
        self.dt = float(dt)
        self._rows = BatchRows()
        self._params: list[GripParams] = []
        self._p = {name: np.empty((0, 1)) for name in COLUMNS}
        self._mode = np.empty((0, N_FINGERS), dtype=np.int8)
        self._m = {name: np.empty((0, N_FINGERS)) for name in MEMORY}

    # -- hands -----------------------------------------------------------------------

    @property
    def ids(self) -> tuple[int, ...]:
        return self._rows.ids

    def row(self, hand: int) -> int:
        """The row of controller ``hand`` (ValueError: no such one)."""
        return self._rows.row(hand)

    def add(self, params: GripParams | None = None) -> int:
        """A new controller, idle, its hand open; returns its id (a force limit the motors
        cannot hold raises ValueError, as :class:`GripController`)."""
        params = params if params is not None else GripParams()
        self._check_force(params)
        fresh = {name: np.zeros((1, N_FINGERS)) for name in MEMORY}
        fresh["finger_angle"][:] = self.model.finger.open_angle
        for name in MEMORY:
            self._m[name] = np.concatenate([self._m[name], fresh[name]])
        for name in COLUMNS:
            self._p[name] = np.concatenate([self._p[name], [[getattr(params, name)]]])
        self._mode = np.concatenate([self._mode, np.full((1, N_FINGERS), IDLE, np.int8)])
        self._params.append(params)
        return self._rows.join()

    def reset(self, hand: int) -> None:
        """Controller ``hand`` as :meth:`add` makes one (idle, its hand open), its settings
        kept: a challenge's restart (:class:`armlab.control.grip_loop.RestartHand`)."""
        r = self.row(hand)
        for name in MEMORY:
            self._m[name][r] = 0.0
        self._m["finger_angle"][r] = self.model.finger.open_angle
        self._mode[r] = IDLE

    def remove(self, hand: int) -> None:
        """Take controller ``hand`` out."""
        r = self._rows.leave(hand)
        for name in MEMORY:
            self._m[name] = np.delete(self._m[name], r, axis=0)
        for name in COLUMNS:
            self._p[name] = np.delete(self._p[name], r, axis=0)
        self._mode = np.delete(self._mode, r, axis=0)
        del self._params[r]

    # -- commands (GripController's, for one hand) -------------------------------------

    def params(self, hand: int) -> GripParams:
        return self._params[self.row(hand)]

    def _check_force(self, params: GripParams) -> None:
        fmax = self.model.max_force()
        if params.force_limit > fmax:
            raise ValueError(
                f"force_limit must be <= {fmax:.2f} N (what the 6 V motors can hold), "
                f"got {params.force_limit:g}")

    def set_params(self, hand: int, params: GripParams) -> None:
        """:meth:`GripController.set_params` for ``hand``: a lower force limit at once, a
        higher one ramped."""
        r = self.row(hand)
        self._check_force(params)
        self._params[r] = params
        for name in COLUMNS:
            self._p[name][r] = getattr(params, name)
        cap = self._m["force_cap"][r]
        np.minimum(cap, params.force_limit, out=cap)
        mode = self._mode[r]
        mode[(mode == HOLDING) & (cap < params.force_limit)] = SQUEEZING

    def close(self, hand: int) -> None:
        """Start ``hand``'s grasp: approach, touch, squeeze to the force limit, hold."""
        r, p = self.row(hand), self._params[self.row(hand)]
        self._mode[r] = CLOSING
        self._m["force_cap"][r] = min(p.touch_force, p.force_limit)
        for name in ("stall_time", "speed_sum", "current_sum"):
            self._m[name][r] = 0.0

    def open(self, hand: int) -> None:
        """Release: unwind ``hand``'s tendons to the open stop, then stop its motors."""
        r = self.row(hand)
        self._mode[r] = OPENING
        self._m["current_sum"][r] = 0.0

    def stop(self, hand: int) -> None:
        """``hand``'s motors off from the next update (the springs open the fingers)."""
        self._mode[self.row(hand)] = IDLE

    # -- what the UI reads ---------------------------------------------------------------

    def modes(self, hand: int) -> tuple[str, ...]:
        """``hand``'s fingers' modes (:data:`armlab.control.grip.MODES`)."""
        return tuple(MODES[k] for k in self._mode[self.row(hand)])

    @property
    def mode_codes(self) -> np.ndarray:
        """(N, 3) every finger's mode as its index in :data:`armlab.control.grip.MODES`."""
        return self._mode.copy()

    @property
    def force_cap(self) -> np.ndarray:
        """(N, 3) N, the force each finger is allowed now."""
        return self._m["force_cap"].copy()

    def estimated_force(self) -> np.ndarray:
        """(N, 3) N, fingertip forces from the last measured currents (0 while not touching)."""
        m = self._m
        f = self.model.force_from_current(m["current"], m["finger_angle"])
        touching = (self._mode == SQUEEZING) | (self._mode == HOLDING)
        return np.where(touching, np.maximum(f, 0.0), 0.0)

    # -- the law -------------------------------------------------------------------------

    def update(self, current: np.ndarray) -> np.ndarray:
        """One period for every hand: measured currents (N, 3) A in, voltages (N, 3) V out.

        :meth:`GripController.update`, term for term. A non-finite current raises
        ValueError and changes nothing.
        """
        measured = np.asarray(current, dtype=float)
        if measured.shape != self._mode.shape:
            raise ValueError(f"current must be {self._mode.shape}, got {measured.shape}")
        if not np.isfinite(measured).all():
            raise ValueError("current must be finite")
        md, g, s, p, dt = self.model, self.model.finger, self._m, self._p, self.dt
        i_meas = unfilter_current(measured, s["measured"], md.current_lpf_hz, dt)
        s["measured"] = measured.copy()
        speed = s["speed"] = back_emf_speed(md, s["voltage"], i_meas)
        s["current"] = i_meas
        s["motor_angle"] = s["motor_angle"] + speed * dt
        tension = np.maximum(motor_torque(md.kt, i_meas), 0.0) / g.spool_radius
        stretch = tension / g.tendon_stiffness / g.spool_radius
        phi = s["finger_angle"] = np.clip(
            g.open_angle + (s["motor_angle"] - stretch) / g.ratio, g.open_angle, g.closed_angle)
        mode = self._mode
        volts = np.zeros_like(measured)
        # open law
        opening = mode == OPENING
        err = OPEN_SLACK - s["motor_angle"]
        opened = opening & (np.abs(err) < 0.2) & (np.abs(speed) < 2.0)
        volts = np.where(opening & ~opened,
                         np.clip(OPEN_GAIN * err, -p["open_voltage"], p["open_voltage"]), volts)
        # close law (the modes as they were at the start of the period)
        closing = mode == CLOSING
        forced = (mode == SQUEEZING) | (mode == HOLDING) | (mode == EMPTY)
        law = closing | forced
        mode[opened] = IDLE
        fl = p["force_limit"]
        cap = s["force_cap"]
        squeezing = mode == SQUEEZING
        gap = fl - cap
        cap = np.where(squeezing, cap + np.minimum(p["ramp_rate"], gap / RAMP_EASE) * dt, cap)
        held = squeezing & (gap <= 0.002 * fl)
        cap = np.where(held, fl, cap)
        mode[held] = HOLDING
        i_spring = md.current_for_force(np.zeros_like(phi), phi)
        i_cap = md.current_for_force(cap, phi)
        omega_ref = p["approach_speed"] / contact_lever(g, phi) * g.ratio
        # force control; where the object gave way, approach again from the next period
        gave = forced & (speed > 2.0 * omega_ref)
        mode[gave] = CLOSING
        cap = np.where(gave, np.minimum(p["touch_force"], fl), cap)
        speed_sum = np.where(gave, 0.0, s["speed_sum"])
        # approach: speed loop, current capped at the touch force
        e = omega_ref - speed
        raw = i_spring + p["speed_gain"] * e + speed_sum
        over, under = raw >= i_cap, raw <= -i_cap
        approach = np.where(over, i_cap, np.where(under, -i_cap, raw))
        speed_sum = np.where(closing & ~over & ~under,
                             speed_sum + p["speed_integral"] * e * dt, speed_sum)
        stalled = (approach >= 0.5 * (i_spring + i_cap)) & (speed < omega_ref / 3.0)
        stall_time = np.where(closing, np.where(stalled, s["stall_time"] + dt, 0.0),
                              s["stall_time"])
        touched = closing & (stall_time >= p["contact_time"])
        at_stop = phi >= g.closed_angle - 0.01
        mode[touched & at_stop] = EMPTY
        mode[touched & ~at_stop] = SQUEEZING
        # current loop with back-EMF feed-forward
        i_ref = np.where(forced, i_cap, approach)  # force control: the capped force
        i_err = i_ref - s["current"]
        current_sum = np.where(law, np.clip(s["current_sum"] + p["current_integral"] * i_err
                                            * dt, -md.supply, md.supply), s["current_sum"])
        volts = np.where(law, md.resistance * i_ref + md.ke * speed + p["current_gain"] * i_err
                         + current_sum, volts)
        s.update(force_cap=cap, speed_sum=speed_sum, stall_time=stall_time,
                 current_sum=current_sum)
        s["voltage"] = np.clip(volts, -md.supply, md.supply)
        return s["voltage"].copy()
