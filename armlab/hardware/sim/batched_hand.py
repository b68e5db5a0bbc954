"""N simulated hands stepped together: :class:`armlab.hardware.sim.hand_plant.HandSim`, numpy
over hands.

A classroom gives every student a private copy of the thesis's three-finger hand (§2.4).
Instead of N ``HandSim`` objects, each looping over its three fingers in Python ten
times per millisecond, one :class:`BatchedHand` keeps every hand's state in (N, 3)
arrays (hand, finger) and runs each plant step's arithmetic once for all hands. The
physics is :meth:`HandSim._advance_finger`'s, written over arrays: tendon tension
(elastic, pulls only), contact force (spring-damper, pushes only), rotor and finger
accelerations, semi-implicit Euler, inelastic hinge stops, the armature current solved
exactly over the step and the current sensor's filter (tests/test_batched_hand.py checks
N hands against N ``HandSim`` to 1e-9 at every period).

Hands are named by a stable integer id (:meth:`BatchedHand.add`); rows are the hands in
the order they joined (:attr:`BatchedHand.ids`); a removed hand's row is deleted and the
rows after it move up. All hands share the
:class:`armlab.hardware.sim.hand_plant.HandParams` (motor, finger geometry, plant step,
sensor filter) and one clock; each holds its own object.
"""

from __future__ import annotations

import math

import numpy as np

from armlab.control.batch_rows import BatchRows
from armlab.hardware.sim.hand_plant import (
    N_FINGERS,
    GraspObject,
    HandParams,
    check_object,
    rc_alpha,
)
from armlab.kinematics.smallarrays import clamp
from armlab.kinematics.validate import scalar

#: m, the "radius" of no object: far inside any fingertip's reach, so never touched
NO_OBJECT_RADIUS = -1.0e3
#: the state arrays, each (N, 3), in :class:`armlab.hardware.sim.hand_plant.HandState`'s order
STATE = ("current", "measured", "motor_angle", "motor_speed", "finger_angle",
         "finger_speed", "tension", "contact_force")


class BatchedHand:
    """Every hand's plant (see the module docstring).

    Args:
        params: what all the hands share (default :class:`HandParams`).

    Attributes:
        params: the shared hand.
        t: s since the start, on the shared clock.
    """

    def __init__(self, params: HandParams | None = None) -> None:
        self.params = params if params is not None else HandParams()
        self.t = 0.0
        self._rows = BatchRows()
        self._objects: list[GraspObject | None] = []
        self._obj = np.empty((3, 0, 1))  # radius, stiffness, damping per row (each (N, 1))
        self._s = {name: np.empty((0, N_FINGERS)) for name in STATE}

    # -- hands ---------------------------------------------------------------------

    @property
    def n_hands(self) -> int:
        return len(self._rows)

    @property
    def ids(self) -> tuple[int, ...]:
        """The hands' ids in row order."""
        return self._rows.ids

    def row(self, hand: int) -> int:
        """The row of hand ``hand`` (ValueError: no such hand)."""
        return self._rows.row(hand)

    def add(self, obj: GraspObject | None = None) -> int:
        """A new hand, open and at rest, around ``obj`` (None: nothing); returns its id."""
        obj = self._checked(obj)
        rest = {name: np.zeros((1, N_FINGERS)) for name in STATE}
        rest["finger_angle"][:] = self.params.finger.open_angle
        for name in STATE:
            self._s[name] = np.concatenate([self._s[name], rest[name]])
        self._obj = np.concatenate([self._obj, self._columns(obj)], axis=1)
        self._objects.append(obj)
        return self._rows.join()

    def remove(self, hand: int) -> None:
        """Take hand ``hand`` out (ValueError: no such hand)."""
        r = self._rows.leave(hand)
        for name in STATE:
            self._s[name] = np.delete(self._s[name], r, axis=0)
        self._obj = np.delete(self._obj, r, axis=1)
        del self._objects[r]

    def reset(self, hand: int) -> None:
        """Hand ``hand`` open and at rest again (its object stays)."""
        r = self.row(hand)
        for name in STATE:
            self._s[name][r] = 0.0
        self._s["finger_angle"][r] = self.params.finger.open_angle

    def _checked(self, obj: GraspObject | None) -> GraspObject | None:
        return None if obj is None else check_object(obj, self.params.finger)

    @staticmethod
    def _columns(obj: GraspObject | None) -> np.ndarray:
        if obj is None:
            return np.array([NO_OBJECT_RADIUS, 0.0, 0.0]).reshape(3, 1, 1)
        return np.array([0.5 * obj.size, obj.stiffness, obj.damping]).reshape(3, 1, 1)

    def obj(self, hand: int) -> GraspObject | None:
        """The object between hand ``hand``'s fingers (None: nothing)."""
        return self._objects[self.row(hand)]

    def set_object(self, hand: int, obj: GraspObject | None) -> None:
        """Put ``obj`` between hand ``hand``'s fingers (None: take it away); a size the
        fingers cannot hold raises ValueError
        (:func:`armlab.hardware.sim.hand_plant.check_object`)."""
        r = self.row(hand)
        obj = self._checked(obj)
        self._obj[:, r:r + 1] = self._columns(obj)
        self._objects[r] = obj

    # -- what the controllers see --------------------------------------------------

    def state(self, name: str) -> np.ndarray:
        """A copy of state array ``name`` (one of :data:`STATE`), (N, 3)."""
        return self._s[name].copy()

    @property
    def measured_current(self) -> np.ndarray:
        """(N, 3) A, the current sensors' readings."""
        return self._s["measured"].copy()

    @property
    def contact_force(self) -> np.ndarray:
        """(N, 3) N, the object's normal force on each fingertip."""
        return self._s["contact_force"].copy()

    @property
    def finger_angle(self) -> np.ndarray:
        """(N, 3) rad, the true finger angles."""
        return self._s["finger_angle"].copy()

    # -- time ------------------------------------------------------------------------

    def step(self, voltage: np.ndarray, duration: float) -> np.ndarray:
        """Drive every hand's motors with ``voltage`` (N, 3) V for ``duration`` s; return
        the sensors' readings (N, 3) A.

        As :meth:`HandSim.step`: the voltage is clipped to ± the supply, and a
        non-finite one raises ValueError (nothing moves).
        """
        p, m = self.params, self.params.motor
        v = np.asarray(voltage, dtype=float)
        if v.shape != (self.n_hands, N_FINGERS):
            raise ValueError(f"voltage must be ({self.n_hands}, {N_FINGERS}), got {v.shape}")
        if not np.isfinite(v).all():
            raise ValueError("voltage must be finite")
        v = np.clip(v, -m.supply, m.supply)
        n = max(1, round(scalar("duration", duration, positive=True) / p.dt))
        self._advance(v, n)
        self.t += n * p.dt
        return self.measured_current

    def _advance(self, v: np.ndarray, n: int) -> None:
        """``n`` plant steps of every finger at ``v`` (N, 3) V: HandSim._advance_finger,
        term for term, over arrays."""
        p, m, g, s = self.params, self.params.motor, self.params.finger, self._s
        h = p.dt
        rp, rt, kt_, ct = g.spool_radius, g.tendon_arm, g.tendon_stiffness, p.tendon_damping
        lo, hi, length = g.open_angle, g.closed_angle, g.length
        radius, k_obj, d_obj = self._obj
        decay = math.exp(-h * m.resistance / m.inductance)
        alpha = 1.0 if p.current_lpf_hz is None else rc_alpha(h, p.current_lpf_hz)
        inv_jm, inv_jf = 1.0 / m.inertia, 1.0 / p.finger_inertia
        i, i_meas = s["current"], s["measured"]
        th, om = s["motor_angle"], s["motor_speed"]
        phi, phid = s["finger_angle"], s["finger_speed"]
        tension = force = np.zeros_like(v)
        for _ in range(n):
            stretch = rp * th - rt * (phi - lo)
            tension = np.maximum(0.0, kt_ * stretch + ct * (rp * om - rt * phid)) * (stretch > 0)
            lever = length * np.cos(phi)
            depth = radius - (g.hinge_radius - length * np.sin(phi))
            force = np.maximum(0.0, k_obj * depth + d_obj * lever * phid) * (depth > 0)
            torque = m.kt * i  # thesis eq. 2.29
            om = om + h * (torque - m.friction * om - rp * tension) * inv_jm
            th = th + h * om
            spring = g.spring_preload + g.spring_rate * (phi - lo)
            phid = phid + h * (rt * tension - spring - p.hinge_damping * phid
                               - force * lever) * inv_jf
            phi = phi + h * phid
            phid = np.where(phi < lo, np.maximum(phid, 0.0),
                            np.where(phi > hi, np.minimum(phid, 0.0), phid))
            phi = clamp(phi, lo, hi)
            i_ss = (v - m.ke * om) / m.resistance
            i = i_ss + (i - i_ss) * decay
            i_meas = i_meas + alpha * (i - i_meas)
        s.update(current=i, measured=i_meas, motor_angle=th, motor_speed=om, finger_angle=phi,
                 finger_speed=phid, tension=tension, contact_force=force)


__all__ = ["BatchedHand", "NO_OBJECT_RADIUS", "STATE"]
