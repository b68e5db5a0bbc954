"""Joint trajectories: the thesis's 20 cm line through RMRC, holds and smooth approaches.

A :class:`JointTrajectory` is samples of (q, q̇, q̈) at given times; the control
loop samples it at its own period (linear interpolation between samples, the
last point held after the end).

The thesis's experiments (ch. 4) move the hand 20 cm along y, from
(−11.322, 7.653, 0) cm to (−11.322, 27.653, 0) cm in the arm's base frame,
2.5 mm per 16 ms sample, each sample's joint angles found by RMRC from the
previous ones (thesis §3.3, ch. 4.1.1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armlab.kinematics.ik import rmrc
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import scalar, vector

#: Thesis ch. 4: start and end of the line, m, base frame.
THESIS_LINE_START = np.array([-0.11322, 0.07653, 0.0])
THESIS_LINE_END = np.array([-0.11322, 0.27653, 0.0])
THESIS_STEP = 0.0025  #: m per sample
THESIS_PERIOD = 0.016  #: s per sample
#: A start guess on the branch the thesis's arm used (elbow bent, θ1 = 45° at the start).
THESIS_Q_GUESS = np.array([0.8, 0.0, 2.5])


@dataclass(frozen=True)
class JointTrajectory:
    """Samples of a joint trajectory.

    Attributes:
        times: (N,) s, increasing, from 0.
        q: (N, n) rad.
        qd: (N, n) rad/s.
        qdd: (N, n) rad/s².
        name: what it is (shown in the UI).
    """

    times: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    name: str = ""

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float)
        if t.ndim != 1 or len(t) == 0 or not np.all(np.isfinite(t)):
            raise ValueError("times must be a non-empty finite 1-D array")
        if len(t) > 1 and np.any(np.diff(t) <= 0):
            raise ValueError("times must increase")
        for name in ("q", "qd", "qdd"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.ndim != 2 or a.shape[0] != len(t):
                raise ValueError(f"{name} must have shape (N, n) with N = {len(t)}, "
                                 f"got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be finite")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "times", t - t[0])

    @property
    def n(self) -> int:
        return self.q.shape[1]

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q̇, q̈) at time ``t`` s, each (n,); before 0 the first point, after the end
        the last point at rest."""
        if t >= self.times[-1]:
            return self.q[-1].copy(), np.zeros(self.n), np.zeros(self.n)
        if t <= 0.0:
            return self.q[0].copy(), self.qd[0].copy(), self.qdd[0].copy()
        k = int(np.searchsorted(self.times, t, side="right")) - 1
        f = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
        return tuple(a[k] + f * (a[k + 1] - a[k]) for a in (self.q, self.qd, self.qdd))

    @classmethod
    def from_positions(cls, times: np.ndarray, q: np.ndarray, name: str = "") -> JointTrajectory:
        """Velocities and accelerations by finite differences of ``q`` (N, n), the
        ends at rest (the arm starts and stops)."""
        t = np.asarray(times, dtype=float)
        q = np.asarray(q, dtype=float)
        if len(t) < 2:
            z = np.zeros_like(q)
            return cls(t, q, z, z.copy(), name)
        qd = np.gradient(q, t, axis=0)
        qd[0] = qd[-1] = 0.0
        qdd = np.gradient(qd, t, axis=0)
        return cls(t, q, qd, qdd, name)

    def then(self, other: JointTrajectory, name: str | None = None) -> JointTrajectory:
        """This trajectory followed by ``other`` (which should start where this ends)."""
        t = np.concatenate([self.times, self.times[-1] + other.times[1:]])
        return JointTrajectory(t, np.vstack([self.q, other.q[1:]]),
                               np.vstack([self.qd, other.qd[1:]]),
                               np.vstack([self.qdd, other.qdd[1:]]),
                               self.name if name is None else name)


def hold(q: np.ndarray, duration: float, *, dt: float = THESIS_PERIOD,
         name: str = "hold") -> JointTrajectory:
    """Stand still at ``q`` (n,) for ``duration`` s."""
    q = vector("q", q)
    duration = scalar("duration", duration, positive=True)
    n = max(1, int(round(duration / dt)))
    t = np.linspace(0.0, duration, n + 1)
    z = np.zeros((n + 1, len(q)))
    return JointTrajectory(t, np.tile(q, (n + 1, 1)), z, z.copy(), name)


def minimum_jerk(q0: np.ndarray, q1: np.ndarray, duration: float, *, dt: float = 0.004,
                 name: str = "approach") -> JointTrajectory:
    """Minimum-jerk move q0 -> q1 (each (n,)) in ``duration`` s, at rest at both ends.

    q(s) = q0 + (q1 − q0)(10 s³ − 15 s⁴ + 6 s⁵), s = t / duration.
    """
    q0, q1 = vector("q0", q0), vector("q1", q1, len(q0))
    duration = scalar("duration", duration, positive=True)
    n = max(2, int(np.ceil(duration / dt)))
    t = np.linspace(0.0, duration, n + 1)
    s = (t / duration)[:, None]
    d = (q1 - q0)[None, :]
    q = q0 + d * (10 * s**3 - 15 * s**4 + 6 * s**5)
    qd = d * (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    qdd = d * (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    return JointTrajectory(t, q, qd, qdd, name)


#: rad/s, the peak joint speed of every approach the lab makes to a goal away from the
#: command (a slider, a trajectory's first point, the quadruped standing up): about 29°/s,
#: a ninth of the slowest servo's no-load speed here (the STS3215's 45 rpm, 4.7 rad/s),
#: slow enough for a person beside the arm to see it coming and step away
APPROACH_SPEED = 0.5


def approach_duration(q0: np.ndarray, q1: np.ndarray, *, speed: float = APPROACH_SPEED,
                      minimum: float = 0.5) -> float:
    """A calm duration for :func:`minimum_jerk`: peak speed ``speed`` rad/s (a minimum-jerk
    move of distance d over T peaks at 1.875 d / T)."""
    dist = float(np.max(np.abs(np.asarray(q1) - np.asarray(q0))))
    return max(minimum, 1.875 * dist / speed)


def line_points(start: np.ndarray, end: np.ndarray, step: float) -> np.ndarray:
    """(N, 3) points from ``start`` to ``end`` (m) spaced ``step`` m apart (end included)."""
    start, end = vector("start", start, 3), vector("end", end, 3)
    step = scalar("step", step, positive=True)
    n = max(1, int(round(np.linalg.norm(end - start) / step)))
    s = np.linspace(0.0, 1.0, n + 1)[:, None]
    return start + s * (end - start)


def cartesian_to_joint(model: SerialChain, points: np.ndarray, q0: np.ndarray, *,
                       dt: float, name: str = "") -> JointTrajectory:
    """RMRC sample by sample (thesis §3.3): each point solved from the previous angles.

    Args:
        points: (N, 3) hand positions, m, base frame, one per ``dt`` s.
        q0: (n,) a start guess for the first point.

    Raises:
        ValueError: when a point cannot be reached (the message names it).
    """
    q = vector("q0", q0, model.n)
    out = np.empty((len(points), model.n))
    for k, p in enumerate(points):
        res = rmrc(model, p, q, restarts=0 if k else 24)
        if not res.reached:
            raise ValueError(f"point {k} {np.round(p * 100, 2).tolist()} cm is not reachable: "
                             f"{res.message}")
        q = out[k] = res.q
    return JointTrajectory.from_positions(np.arange(len(points)) * dt, out, name)


#: Robot -> (start, end (3,) m in its base frame, a start guess (n,) rad) of its chapter-4
#: line, 20 cm: the thesis's for its arm; across the OpenManipulator-X's front, 20 cm ahead
#: of its base and 15 cm up, for the same experiment on an arm a school owns.
LINES = {
    "open_manipulator_x": (np.array([0.20, -0.10, 0.15]), np.array([0.20, 0.10, 0.15]),
                           np.array([-0.46, 0.0, 0.3, 0.3])),
}


def thesis_line(model: SerialChain, *, step: float = THESIS_STEP,
                period: float = THESIS_PERIOD) -> JointTrajectory:
    """The chapter-4 line: 20 cm along y at 2.5 mm per 16 ms sample (81 samples, 1.28 s);
    the thesis's, or the model's own from :data:`LINES`."""
    start, end, guess = LINES.get(model.name, (THESIS_LINE_START, THESIS_LINE_END,
                                               THESIS_Q_GUESS))
    pts = line_points(start, end, step)
    name = "thesis 20 cm line" if model.name not in LINES else f"{model.name} 20 cm line"
    return cartesian_to_joint(model, pts, guess, dt=period, name=name)
