"""The quadruped's 12 AX-12A servos, simulated: one :class:`SimBackend` per leg, one Backend.

Each leg is a 3-joint serial chain whose base is its hip mount, held still (as the
emulator does for ``armlab emulate --robot quadruped``); its servos are AX-12A
firmware models (``armlab.hardware.families.dynamixel1.firmware``) on a simulated plant.
:class:`QuadrupedSimBackend`
stacks the four legs into one :class:`armlab.control.backend.Backend` of 12 joints in the
order of ``armlab.hardware.backends.joint_map.default_joint_map`` (RF, LF, RH, LH; hip yaw, hip
pitch, knee), the order the serial backend uses too.

The legs carry the body (:class:`BodyOnLegs`, quasi-static): before each step the
floor plane the body rests on is found from where the feet really are (the servos'
deflected angles), the robot's weight is shared among the feet that touch it by
force and moment balance, and each contact foot is pushed by its share along the
floor's normal. Through J^T f that load turns each stance leg's servos, which give
way by their compliance (margin, slope, punch: ``armlab.hardware.families.dynamixel1.firmware``),
and the plane through the deflected contact feet is the body's pose: :attr:`BodyOnLegs.tilt_deg`.
The emulator loads its legs with the same class (``armlab emulate --robot quadruped``).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from armlab.control.backend import GoalLimits, JointState
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.servos.servo_spec import AX12A
from armlab.hardware.sim.plant import Plant
from armlab.kinematics.body_statics import contact_forces, rest_pose, tilt_deg
from armlab.kinematics.model import Quadruped
from armlab.kinematics.quadruped import LEGS, QuadrupedGeometry, foot_in_tibia
from armlab.kinematics.validate import scalar, vector

#: Joints per leg.
LEG_JOINTS = 3
G = 9.81  #: m/s²
LOAD_STEP = 0.01  #: s between renewals of the body's load on the legs
#: s, the plant step and servo tick the lab's simulated legs use (eq. 4.1 figures agree with
#: 1 ms to 0.01 %, at half the cost)
SIM_DT = 2e-3
BELLY_RAMP = 0.01  #: m over which the body's underside takes its weight off the feet


def total_mass(model: Quadruped) -> float:
    """Body plus every leg link, kg."""
    return model.body_mass + sum(link.mass for chain in model.legs.values()
                                 for link in chain.links)


class BodyOnLegs:
    """The quadruped's weight on its four leg plants (hips held in the body frame).

    Args:
        model: the quadruped.
        plants: its four leg plants, in ``model.legs`` order.
        mass: kg the feet carry (default: the whole robot, :func:`total_mass`); 0 turns
            the load off.
        belly: m from the body frame's origin down to the body's underside; when the feet
            no longer reach below it the body lies on the floor and the feet carry nothing.
            So it does when any servo lets go (torque off): a quasi-static model has no
            body inertia to follow a fall, so the body is put on its underside at once.

    Attributes:
        tilt_deg: the body's tilt at the last :meth:`load`, degrees.
        contact: (4,) which feet touched the floor then.
        forces: (4,) the floor's normal force on each foot then, N.
    """

    def __init__(self, model: Quadruped, plants: Sequence[Plant], *,
                 mass: float | None = None,
                 belly: float = QuadrupedGeometry().body_size[2] / 2) -> None:
        self.model = model
        self.belly = scalar("belly", belly, nonnegative=True)
        self.plants = list(plants)
        self.weight = G * (total_mass(model) if mass is None
                           else scalar("mass", mass, nonnegative=True))
        self._feet_points = [foot_in_tibia(leg) for leg in LEGS]
        self.tilt_deg = 0.0
        self.contact = np.ones(len(self.plants), dtype=bool)
        self.forces = np.zeros(len(self.plants))

    def q(self) -> np.ndarray:
        """(12,) the legs' true joint angles now, rad."""
        return np.concatenate([plant.q for plant in self.plants])

    def load(self, until: float) -> None:
        """Put the weight on the feet touching the floor, from now until ``until`` s."""
        duration = until - self.plants[0].t
        if duration <= 0.0 or self.weight <= 0.0:
            return
        q = self.q()
        f = np.zeros(len(self.plants))
        holding = all(servo.regs.torque_enable for plant in self.plants for servo in plant.servos)
        try:
            n, d, contact, feet, com = rest_pose(self.model, q)
        except ValueError:  # no three feet under the body
            contact = np.zeros(len(f), dtype=bool)
        if not holding:  # a servo let go (torque off, e-stop, overload): the body sits down
            contact = np.zeros(len(f), dtype=bool)
        # The underside takes the weight over as the floor comes up to it (within
        # BELLY_RAMP of the underside): a robot squatting that low sits on its body.
        share = 0.0 if not contact.any() else float(np.clip((-d - self.belly) / BELLY_RAMP,
                                                            0.0, 1.0))
        if share <= 0.0:
            self.contact, self.forces, self.tilt_deg = np.zeros(len(f), dtype=bool), f, 0.0
            return
        f[contact] = contact_forces(feet[contact], com, share * self.weight, n)
        for i in np.flatnonzero(f > 0.0):
            self.plants[i].push(f[i] * n, link=LEG_JOINTS - 1, point=self._feet_points[i],
                                duration=duration)
        self.contact, self.forces = contact, f
        self.tilt_deg = tilt_deg(n)


class QuadrupedSimBackend(GoalLimits):
    """Four simulated legs of AX-12A servos behind one 12-joint Backend (and Pushable).

    Args:
        model: the quadruped (``kinematics.load_robot("quadruped")``).
        q0: (12,) initial joint angles, rad (default zeros), in leg order.
        dt: plant step and servo tick, s.
        body_mass: kg the legs carry (default the whole robot; 0: legs unloaded).

    Attributes:
        legs: the four :class:`SimBackend`, in the order of ``model.legs``.
        body: the body's weight on them (:class:`BodyOnLegs`).
    """

    def __init__(self, model: Quadruped, *, q0: Sequence[float] | np.ndarray | None = None,
                 dt: float = 1e-3, body_mass: float | None = None) -> None:
        if not isinstance(model, Quadruped):
            raise ValueError("model: QuadrupedSimBackend needs a Quadruped")
        chains = list(model.legs.values())
        n = LEG_JOINTS * len(chains)
        start = np.zeros(n) if q0 is None else vector("q0", q0, n)
        self.model = model
        self.legs = [SimBackend(chain, specs=AX12A, dt=dt,
                                q0=start[LEG_JOINTS * k:LEG_JOINTS * (k + 1)])
                     for k, chain in enumerate(chains)]
        self._lower = np.concatenate([leg.lower for leg in self.legs])
        self._upper = np.concatenate([leg.upper for leg in self.legs])
        self.body = BodyOnLegs(model, [leg.plant for leg in self.legs], mass=body_mass)
        self._lock = threading.RLock()

    # -- Backend protocol ---------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of joints (12)."""
        return LEG_JOINTS * len(self.legs)

    def sync(self, t: float) -> None:
        """Integrate every leg up to ``t`` s, carrying the body (:class:`BodyOnLegs`, its load
        renewed every :data:`LOAD_STEP` s)."""
        with self._lock:
            now = self.legs[0].plant.t
            while now < t - 1e-12:
                now = min(t, now + LOAD_STEP)
                self.body.load(now)
                for leg in self.legs:
                    leg.sync(now)

    def read(self) -> JointState:
        """Every servo's report, legs in order (positions quantised to AX-12A steps)."""
        with self._lock:
            states = [leg.read() for leg in self.legs]
        return JointState(
            t=states[0].t,
            position=np.concatenate([s.position for s in states]),
            velocity=np.concatenate([s.velocity for s in states]),
            load=np.concatenate([s.load for s in states]),
            errors=tuple(e for s in states for e in s.errors),
            torque_on=tuple(x for s in states for x in s.torque_on),
            alarms=tuple(a for s in states for a in s.alarms),
        )

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Goal positions (12,) rad and moving speeds (12,) rad/s, clamped per servo.

        Raises:
            ValueError: a wrong shape or a non-finite value (nothing is written).
        """
        p, s = self.checked_goal(position, speed)
        with self._lock:
            for k, leg in enumerate(self.legs):
                sl = slice(LEG_JOINTS * k, LEG_JOINTS * (k + 1))
                leg.write_checked(p[sl], s[sl])

    def set_torque(self, on: bool) -> None:
        with self._lock:
            for leg in self.legs:
                leg.set_torque(on)

    def estop(self) -> bool:
        """Torque off on all 12 servos now; never raises. Returns True."""
        return all([leg.estop() for leg in self.legs])

    def close(self) -> None:
        with self._lock:
            for leg in self.legs:
                leg.close()

    # -- Pushable -------------------------------------------------------------------

    def _leg(self, link: int) -> tuple[SimBackend, int]:
        if isinstance(link, bool) or not isinstance(link, int | np.integer) or not (
                0 <= int(link) < self.n):
            raise ValueError(f"link must be a joint index 0..{self.n - 1}, got {link!r}")
        return self.legs[int(link) // LEG_JOINTS], int(link) % LEG_JOINTS

    def push(self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float) -> None:
        """Apply ``force`` (3,) N, in the leg's hip-mount frame (the body frame's axes), at
        ``point`` (3,) m in the frame of link ``link`` (0..11: leg ``link // 3``, its link
        ``link % 3``), for ``duration`` s of simulated time."""
        leg, i = self._leg(link)
        with self._lock:
            leg.push(force, link=i, point=point, duration=duration)

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """Pull ``point`` on ``link`` (0..11) towards ``anchor`` (hip-mount frame); None
        releases that leg's spring."""
        leg, i = self._leg(link)
        with self._lock:
            leg.set_spring(anchor, stiffness=stiffness, link=i, point=point)


__all__ = ["QuadrupedSimBackend", "BodyOnLegs", "LEG_JOINTS", "SIM_DT", "total_mass"]
