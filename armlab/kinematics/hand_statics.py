"""Geometry and statics of the thesis's three-finger hand (thesis §2.4, §3.1.1).

The gripper has three fingers spaced 120° around the palm axis, each a rigid
link on a hinge, pulled closed by a tendon wound on a 6 V DC gearmotor's shaft
and pushed open by a return spring (thesis §2.4: the motor is "strong enough to
pull the spring in the finger"). The thesis gives no finger dimensions; the
defaults below are plausible for its 3 mm acrylic palm and are parameters.

Conventions (palm frame): z along the palm normal (the fingers point +z), the
palm axis is the z axis. Finger i lies in the vertical plane at azimuth
``azimuths[i]``; its angle ``phi`` is measured from +z, positive towards the
axis (closing). The object is a cylinder on the palm axis, so each fingertip
touches it with a horizontal (radial) normal.

Pure functions of (geometry, arrays); no I/O, no state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

OZ_IN = 0.0070615518  #: 1 oz·in in N·m

#: The gripper gearmotor's datasheet (thesis §2.4), all figures at the 5:1 gearbox output.
GEARMOTOR_STALL_TORQUE = 2.0 * OZ_IN  #: N·m (2 oz·in)
GEARMOTOR_STALL_CURRENT = 1.6  #: A
GEARMOTOR_GEAR_RATIO = 5.0  #: already inside the stall torque above: do not apply it again


def torque_constant(stall_torque: float, stall_current: float) -> float:
    """Thesis eq. 2.29 at stall: K_t = tau_stall / I_stall, N·m/A.

    At stall the rotor does not turn, so there is neither back-EMF nor
    viscous friction and all the current makes torque. The datasheet's stall
    torque is measured at the gearbox output, so this K_t is the output-side
    constant with the gear ratio already in it. Example: 2 oz·in / 1.6 A =
    0.014123 / 1.6 = 8.827e-3 N·m/A (:data:`GRIPPER_KT`).
    """
    return stall_torque / stall_current


GRIPPER_KT = torque_constant(GEARMOTOR_STALL_TORQUE, GEARMOTOR_STALL_CURRENT)  #: N·m/A, output side


@dataclass(frozen=True)
class FingerGeometry:
    """One finger and its tendon drive (the three are identical).

    Attributes:
        hinge_radius: m, distance of each finger hinge from the palm axis.
        length: m, hinge to the fingertip pad (where it touches the object).
        open_angle: rad, finger angle at the open stop (negative: leaning out).
        closed_angle: rad, finger angle at the closed stop.
        spool_radius: m, tendon spool on the gearmotor's 3 mm output shaft.
        tendon_arm: m, moment arm of the tendon about the finger hinge.
        spring_rate: N·m/rad, return spring stiffness about the hinge.
        spring_preload: N·m, return-spring torque at the open stop (keeps the
            finger on its stop and the tendon taut).
        tendon_stiffness: N/m, axial stiffness of the tendon (pulls only).
        azimuths: rad, (3,) angular position of the fingers around the palm.
    """

    hinge_radius: float = 0.035
    length: float = 0.06
    open_angle: float = -0.35
    closed_angle: float = 0.45
    spool_radius: float = 0.0015
    tendon_arm: float = 0.012
    spring_rate: float = 0.008
    spring_preload: float = 0.008
    tendon_stiffness: float = 2.0e4
    azimuths: tuple[float, float, float] = (0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0)

    @property
    def ratio(self) -> float:
        """Motor-shaft radians per finger radian, tendon_arm / spool_radius."""
        return self.tendon_arm / self.spool_radius

    @property
    def max_size(self) -> float:
        """m, the largest object diameter that fits between the open fingers."""
        return 2.0 * float(tip_radius(self, self.open_angle))

    @property
    def min_size(self) -> float:
        """m, the smallest object diameter the closed fingers still touch."""
        return 2.0 * float(tip_radius(self, self.closed_angle))


def motor_torque(kt: float, current: float | np.ndarray) -> float | np.ndarray:
    """Thesis eq. 2.29: motor torque tau_m = K_t · I_a (N·m from A).

    ``kt`` in N·m/A at the shaft the torque is wanted on (here the gearbox
    output); ``current`` scalar or (n,) A. Example: the hand's gearmotor stalls
    at 1.6 A with 2 oz·in, so K_t = 0.01412/1.6 = 8.83e-3 N·m/A and 1 A gives
    8.83 mN·m.
    """
    return np.multiply(kt, current)


def tip_radius(g: FingerGeometry, phi: float | np.ndarray) -> np.ndarray:
    """Distance of the fingertip from the palm axis, m: R_b − L sin(phi). phi scalar or (n,)."""
    return g.hinge_radius - g.length * np.sin(phi)


def tip_positions(g: FingerGeometry, phi: np.ndarray) -> np.ndarray:
    """Fingertip positions (3, 3) in the palm frame for finger angles ``phi`` (3,) rad."""
    phi = np.asarray(phi, dtype=np.float64)
    r = tip_radius(g, phi)
    az = np.asarray(g.azimuths)
    return np.stack([r * np.cos(az), r * np.sin(az), g.length * np.cos(phi)], axis=1)


def contact_lever(g: FingerGeometry, phi: float | np.ndarray) -> np.ndarray:
    """Moment arm of a radial fingertip force about the hinge, m: L cos(phi).

    A normal force F at the fingertip (the object pushing it outward) loads the
    hinge with F · L cos(phi) (= −d tip_radius / d phi · F).
    """
    return g.length * np.cos(phi)


def spring_torque(g: FingerGeometry, phi: float | np.ndarray) -> np.ndarray:
    """Return-spring torque opening the finger, N·m: preload + rate·(phi − open_angle)."""
    return g.spring_preload + g.spring_rate * (np.asarray(phi) - g.open_angle)


def grip_force_from_tension(
    g: FingerGeometry, tension: float | np.ndarray, phi: float | np.ndarray
) -> np.ndarray:
    """Static fingertip force (N) a tendon tension (N) holds against the object.

    Hinge balance: tension · tendon_arm = spring_torque(phi) + F · contact_lever(phi).
    """
    return (np.asarray(tension) * g.tendon_arm - spring_torque(g, phi)) / contact_lever(g, phi)


def tension_for_grip_force(
    g: FingerGeometry, force: float | np.ndarray, phi: float | np.ndarray
) -> np.ndarray:
    """Tendon tension (N) that holds fingertip force ``force`` (N) at finger angle ``phi``.

    The inverse of :func:`grip_force_from_tension`.
    """
    return (spring_torque(g, phi) + np.asarray(force) * contact_lever(g, phi)) / g.tendon_arm
