"""The quadruped's 12 AX-12A servos, simulated: one :class:`SimBackend` per leg, one Backend.

Each leg is a 3-joint serial chain whose base is its hip mount, held still (as the
emulator does for ``armlab emulate --robot quadruped``); its servos are AX-12A
firmware models (``hardware.servo``) on a simulated plant. :class:`QuadrupedSimBackend`
stacks the four legs into one :class:`control.backend.Backend` of 12 joints in the
order of ``hardware.joint_map.default_joint_map`` (RF, LF, RH, LH; hip yaw, hip
pitch, knee), the order the serial backend uses too.

The legs do not carry the body's weight by themselves (their hips are fixed). A
walking controller puts that load on through :meth:`QuadrupedSimBackend.push`: the
floor's reaction on each stance foot, in the hip-mount (= body) frame.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from control.backend import GoalLimits, JointState
from hardware.servo_spec import AX12A
from hardware.sim_backend import SimBackend
from kinematics.model import Quadruped
from kinematics.validate import vector

#: Joints per leg.
LEG_JOINTS = 3


class QuadrupedSimBackend(GoalLimits):
    """Four simulated legs of AX-12A servos behind one 12-joint Backend (and Pushable).

    Args:
        model: the quadruped (``kinematics.load_robot("quadruped")``).
        q0: (12,) initial joint angles, rad (default zeros), in leg order.
        dt: plant step and servo tick, s.

    Attributes:
        legs: the four :class:`SimBackend`, in the order of ``model.legs``.
    """

    def __init__(self, model: Quadruped, *, q0: Sequence[float] | np.ndarray | None = None,
                 dt: float = 1e-3) -> None:
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
        self._lock = threading.RLock()

    # -- Backend protocol ---------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of joints (12)."""
        return LEG_JOINTS * len(self.legs)

    def sync(self, t: float) -> None:
        """Integrate every leg up to ``t`` s."""
        with self._lock:
            for leg in self.legs:
                leg.sync(t)

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

    def estop(self) -> None:
        """Torque off on all 12 servos now; never raises."""
        for leg in self.legs:
            leg.estop()

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


__all__ = ["QuadrupedSimBackend", "LEG_JOINTS"]
