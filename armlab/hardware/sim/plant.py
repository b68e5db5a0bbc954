"""The simulated arm: rigid-body dynamics + one Dynamixel firmware/motor model per joint.

Each step of ``dt`` (1 ms default):

1. every servo's firmware ticks once
(each family's firmware model, ``update``): it
   senses its horn, moves its set-point, fixes its PWM duty for the step;
2. the state (q, qd) is integrated by classical Runge–Kutta 4 with
   ``qdd = forward_dynamics(q, qd, tau)`` (thesis eq. 2.41–2.50 inverted), where tau =
   servo torques (motor line at the held duty, gear friction) + joint stops + external
   forces (push, spring, wall) + applied joint torques (a known disturbance), all
   re-evaluated at each RK stage except the push, the applied torques and the duty. The
   rotor inertias enter as armature (diagonal extra inertia).

Frames: every external force and point here is in the model's **base frame** (for
``receptionist_arm`` the thesis frame: x along gravity), not the 3D viewer's world;
``model.base_pose`` maps base to world for whoever draws or picks in the world.

Ground truth (:meth:`Plant.truth`) and what the servos report (:meth:`Plant.reports`,
raw words) are kept apart: a controller must only ever see the latter.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from armlab.control.backend import FRICTION_RANGE
from armlab.hardware.servos.registry import FAMILIES, family_of_spec
from armlab.hardware.servos.servo_spec import ServoSpec, TurnEncoder
from armlab.hardware.sim.plant_step import rk4_step
from armlab.hardware.sim.servo_motor import GearedMotor, ServoParams
from armlab.kinematics.dynamics import dynamics_model, kinetic_energy, potential_energy
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import finite
from armlab.kinematics.validate import index, scalar, vector


@dataclass(frozen=True)
class GroundTruth:
    """The plant's true state and torques at time ``t`` (never seen by a controller).

    Attributes:
        t: s since start.
        q, qd: (n,) joint positions rad and velocities rad/s.
        motor_torque: (n,) N·m the servo motors apply to the joints (motor line).
        friction_torque: (n,) N·m gear friction acting on the joints.
        external_torque: (n,) N·m of the push, spring and wall (J^T F) and the applied
            joint torques (:meth:`Plant.apply_joint_torque`).
        stop_torque: (n,) N·m of the joint-limit stops.
    """

    t: float
    q: np.ndarray
    qd: np.ndarray
    motor_torque: np.ndarray
    friction_torque: np.ndarray
    external_torque: np.ndarray
    stop_torque: np.ndarray


@dataclass(frozen=True)
class _Push:
    force: tuple[float, float, float]
    link: int
    point: tuple[float, float, float]
    until: float


@dataclass(frozen=True)
class _JointTorque:
    joint: int
    torque: float
    start: float


@dataclass(frozen=True)
class _Spring:
    anchor: tuple[float, float, float]
    stiffness: float
    damping: float
    link: int
    point: tuple[float, float, float]


@dataclass(frozen=True)
class _Wall:
    origin: tuple[float, float, float]
    normal: tuple[float, float, float]
    stiffness: float
    damping: float
    link: int
    point: tuple[float, float, float]
    friction: float = 0.0


#: N·s/m: the slope of the wall's friction below its Coulomb limit (the regularised
#: "stick": a damper on the sliding speed, capped at μ·f_n). Explicit RK4 at the plant's
#: 1 ms step keeps a damper c stable on a mass m while c·dt/m stays below about 2.8; the
#: lightest hand the lab drives (the receptionist arm's, some 0.35 kg of link and
#: reflected rotor) takes 200 at 0.6
FRICTION_DAMPING = 200.0


@dataclass(frozen=True)
class JointStops:
    """Soft mechanical stops at the model's joint limits (the arm hitting its own body).

    Attributes:
        stiffness: N·m/rad beyond a limit. damping: N·m·s/rad while beyond it.
    """

    stiffness: float = 50.0
    damping: float = 0.5



def checked_wall(origin_base: object, normal_base: object, stiffness: object, damping: object,
                 link: int | None, point: object, *, n: int, tip: np.ndarray,
                 link_index: Callable[[int], int],
                 ) -> tuple[np.ndarray, np.ndarray, float, float, int, np.ndarray]:
    """A wall's arguments checked (``Plant.set_wall``, ``BatchedPlant.set_wall``): origin
    (3,), unit normal (3,), stiffness, damping, the contact link's index and the contact
    point (3,) in its frame (the tip on the last link, else the link's origin).

    Raises:
        ValueError: naming the argument that is missing, zero, non-finite or out of range.
    """
    if normal_base is None:
        raise ValueError("normal_base is needed with a wall origin")
    nrm = vector("normal_base", normal_base, 3)
    length = float(np.linalg.norm(nrm))
    if length < 1e-9:
        raise ValueError("normal_base must not be zero")
    k = scalar("stiffness", stiffness, positive=True)
    c = scalar("damping", damping, nonnegative=True)
    li = n - 1 if link is None else link_index(link)
    pt = np.array(tip) if point is None else vector("point", point, 3)
    if point is None and link is not None and li != n - 1:
        pt = np.zeros(3)
    return vector("origin_base", origin_base, 3), nrm / length, k, c, li, pt

def checked_friction(friction: object) -> float:
    """A wall's friction μ checked: finite, in :data:`FRICTION_RANGE`."""
    mu = scalar("friction", friction, nonnegative=True)
    if not FRICTION_RANGE[0] <= mu <= FRICTION_RANGE[1]:
        raise ValueError(f"friction must be in {FRICTION_RANGE[0]:g}..{FRICTION_RANGE[1]:g}, "
                         f"got {mu:g}")
    return mu


def _wall_friction(wall: _Wall, push: float, v: Sequence[float]) -> list[float]:
    """(3,) N of the wall's friction on a contact point moving at ``v`` (3,) while it
    pushes ``push`` N: opposing the sliding (the velocity along the plane), the damper
    :data:`FRICTION_DAMPING` on its speed capped at Coulomb's μ·push. It never does work
    on the arm (its power −|f|·|v_t| ≤ 0): it only takes energy out."""
    nrm = wall.normal
    vn = sum(v[r] * nrm[r] for r in range(3))
    slide = [v[r] - vn * nrm[r] for r in range(3)]
    speed = math.sqrt(slide[0] ** 2 + slide[1] ** 2 + slide[2] ** 2)
    if push <= 0.0 or wall.friction <= 0.0 or speed <= 0.0:
        return [0.0, 0.0, 0.0]
    size = min(wall.friction * push, FRICTION_DAMPING * speed)
    return [-size * slide[r] / speed for r in range(3)]


def _wall_push(wall: _Wall, p: Sequence[float], v: Sequence[float]) -> float:
    """N of the wall's normal push on contact point ``p`` (3,) moving at ``v`` (3,), base
    frame: a spring on the penetration and a damper on its rate, never pulling (0 off the
    wall)."""
    nrm = wall.normal
    depth = sum((p[r] - wall.origin[r]) * nrm[r] for r in range(3))
    if depth >= 0.0:
        return 0.0
    vn = sum(v[r] * nrm[r] for r in range(3))
    return max(0.0, -wall.stiffness * depth - wall.damping * vn)


class Plant:
    """Arm + servos, stepped at a fixed ``dt``.

    Args:
        model: the serial chain.
        specs: one datasheet per joint, or one for all: a :class:`ServoSpec` (protocol
            1.0) or another family's (X-series, Feetech STS: a ``TurnEncoder``); each
            joint runs its family's firmware model.
        dt: integration step and servo firmware tick, s (1e-3 default).
        q0, qd0: (n,) initial joint state (default: neutral, at rest).
        directions: (n,) +1/-1: servo angle = direction · joint angle (default +1).
        params: :class:`ServoParams` per joint or one for all (rotor, friction, overload;
            default: :class:`ServoParams`, supplied at an X-series model's rated voltage).
        registers: per joint its family's registers (``ServoRegisters`` for protocol
            1.0, ``XRegisters`` for an X-series joint) to use (default: factory values, goal at the
            initial
            position, torque off).
        stops: joint-limit stops, or None for none.
    """

    def __init__(self, model: SerialChain,
                 specs: ServoSpec | TurnEncoder | Sequence[ServoSpec | TurnEncoder], *,
                 dt: float = 1e-3, q0: np.ndarray | Sequence[float] | None = None,
                 qd0: np.ndarray | None = None, directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 registers: Sequence[Any] | None = None,
                 stops: JointStops | None = JointStops()) -> None:
        n = model.n
        self.model = model
        self.n = n
        self.dt = scalar("dt", dt, positive=True)
        if self.dt > 0.01:
            raise ValueError(f"dt must be <= 0.01 s for a stable servo loop, got {dt}")
        self._dyn = dynamics_model(model)
        one = isinstance(specs, tuple(f.spec_type for f in FAMILIES))
        spec_list = [specs] * n if one else list(specs)  # type: ignore[arg-type]  # not one: a sequence (mypy cannot narrow on FAMILIES' spec types)
        if len(spec_list) != n:
            raise ValueError(f"specs must name {n} servos, got {len(spec_list)}")
        # each servo's firmware model is its family's (:mod:`armlab.hardware.families`)
        firmware = [family_of_spec(s).servo_model for s in spec_list]
        if params is None:  # a servo with a rated supply reports it (5 V: XL330)
            param_list = [ServoParams(voltage=s.voltage) if hasattr(s, "voltage")
                          else ServoParams() for s in spec_list]
        elif isinstance(params, ServoParams):
            param_list = [params] * n
        else:
            param_list = list(params)
            if len(param_list) != n:
                raise ValueError(f"params must have {n} entries, got {len(param_list)}")
        if directions is None:
            dirs = [1.0] * n
        else:
            dirs = [float(d) for d in vector("directions", directions, n)]
            if any(d not in (1.0, -1.0) for d in dirs):
                raise ValueError(f"directions must be +1 or -1, got {dirs}")
        self.directions = tuple(dirs)
        q = model.neutral() if q0 is None else vector("q0", q0, n)
        qd = np.zeros(n) if qd0 is None else vector("qd0", qd0, n)
        self._q = [float(x) for x in q]
        self._qd = [float(x) for x in qd]
        if registers is not None and len(registers) != n:
            raise ValueError(f"registers must have {n} entries, got {len(registers)}")
        self.servos: tuple[GearedMotor, ...] = tuple(
            firmware[i](
                spec_list[i], None if registers is None else registers[i],
                params=param_list[i], angle=dirs[i] * self._q[i]) for i in range(n))
        self._armature = [p.rotor_inertia for p in param_list]
        self._viscous = [p.viscous_friction for p in param_list]
        self._coulomb = [(i, (p.coulomb_friction, 1.0 / p.friction_speed))
                         for i, p in enumerate(param_list) if p.coulomb_friction]
        self._coulomb_joints = tuple(i for i, _ in self._coulomb)
        self._coulomb_pairs = tuple(pair for _, pair in self._coulomb)
        self._gravity = [float(x) for x in model.gravity]
        self._lower = [float(x) for x in model.lower]
        self._upper = [float(x) for x in model.upper]
        self.stops = stops
        self._k = 0  # steps taken; t = k dt
        self._pushes: list[_Push] = []
        self._spring: _Spring | None = None
        self._wall: _Wall | None = None
        #: N, the largest wall force since :meth:`wall_peak` was read (None: never asked)
        self._wall_peak: float | None = None
        self._push_tau = [0.0] * n
        self._joint_torques: list[_JointTorque] = []

    # -- state ------------------------------------------------------------------

    @property
    def t(self) -> float:
        """Simulated time, s."""
        return self._k * self.dt

    @property
    def q(self) -> np.ndarray:
        """(n,) true joint positions, rad."""
        return np.array(self._q)

    @property
    def qd(self) -> np.ndarray:
        """(n,) true joint velocities, rad/s."""
        return np.array(self._qd)

    def set_state(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """Put the arm at ``q`` (n,) with velocity ``qd`` (default rest); time goes on."""
        self._q = [float(x) for x in vector("q", q, self.n)]
        self._qd = [0.0] * self.n if qd is None else [float(x) for x in vector("qd", qd, self.n)]

    # -- external forces (base frame) ------------------------------------------

    def push(self, force_base: np.ndarray, *, link: int, point: np.ndarray,
             duration: float) -> None:
        """Apply ``force_base`` (3,) N, **base frame**, at ``point`` (3,) m in link ``link``'s
        frame, for ``duration`` s from now. Pushes add up while they overlap."""
        f = vector("force_base", force_base, 3)
        p = vector("point", point, 3)
        k = self._link(link)
        d = scalar("duration", duration, nonnegative=True)
        self._pushes.append(_Push(tuple(f), k, tuple(p), self.t + d))

    def set_spring(self, anchor_base: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray, damping: float = 0.0) -> None:
        """Pull ``point`` (3,) m on ``link`` towards ``anchor_base`` (3,) m, base frame, with
        a spring of ``stiffness`` N/m and ``damping`` N·s/m (a hand dragging); None releases."""
        if anchor_base is None:
            self._spring = None
            return
        k = scalar("stiffness", stiffness, nonnegative=True)
        c = scalar("damping", damping, nonnegative=True)
        self._spring = _Spring(tuple(vector("anchor_base", anchor_base, 3)), k, c,
                               self._link(link), tuple(vector("point", point, 3)))

    def set_wall(self, origin_base: np.ndarray | None, normal_base: np.ndarray | None = None, *,
                 stiffness: float = 5000.0, damping: float = 30.0, link: int | None = None,
                 point: np.ndarray | None = None, friction: float = 0.0) -> None:
        """A rigid-ish plane the arm can press on; None removes it.

        Args:
            origin_base: (3,) m, a point of the plane, base frame.
            normal_base: (3,) the plane's normal pointing to the free side, base frame.
            stiffness: N/m of penetration; damping: N·s/m while in contact (never pulls).
            friction: μ of its Coulomb friction along the plane (:func:`_wall_friction`).
            link, point: the contact point on the arm (default: the end effector, i.e. the
                last link's tip).
        """
        if origin_base is None:
            self._wall = None
            return
        origin, normal, k, c, li, pt = checked_wall(
            origin_base, normal_base, stiffness, damping, link, point, n=self.n,
            tip=self.model.tip[:3, 3], link_index=self._link)
        self._wall = _Wall(tuple(origin), tuple(normal), k, c, li,
                           cast("tuple[float, float, float]", tuple(float(x) for x in pt)),
                           checked_friction(friction))

    @property
    def wall(self) -> tuple[np.ndarray, np.ndarray, float, float, float] | None:
        """The wall :meth:`set_wall` placed: (origin (3,) m, unit normal (3,), stiffness
        N/m, damping N·s/m, friction μ), base frame; None without one."""
        w = self._wall
        return None if w is None else (np.array(w.origin), np.array(w.normal),
                                       w.stiffness, w.damping, w.friction)

    def apply_joint_torque(self, joint: int, torque: float, *, start: float = 0.0) -> None:
        """A known disturbance: a constant ``torque`` N·m on ``joint`` (positive along the
        joint's axis, as J^T F of a push is) from plant time ``start`` s on, for as long as
        the plant runs (a weight hung on a pulley at the joint). Torques add up; the
        disturbance observers (thesis eq. 2.36) are checked against it.

        Raises:
            ValueError: naming the argument: no such joint, a non-finite torque, or a
                negative or non-finite start.
        """
        j = index("joint", joint, self.n)
        tau = scalar("torque", torque)
        t0 = scalar("start", start, nonnegative=True)
        self._joint_torques.append(_JointTorque(j, tau, t0))

    def joint_torques(self, t: float | None = None) -> np.ndarray:
        """(n,) N·m of the applied joint torques (:meth:`apply_joint_torque`) acting at plant
        time ``t`` s (default now)."""
        now = self.t if t is None else t
        tau = np.zeros(self.n)
        for d in self._joint_torques:
            if now >= d.start - 1e-12:
                tau[d.joint] += d.torque
        return tau

    def clear_forces(self) -> None:
        """Remove every push, spring, wall and applied joint torque."""
        self._pushes.clear()
        self._spring = None
        self._wall = None
        self._joint_torques.clear()

    def _link(self, link: int) -> int:
        return index("link", link, self.n)

    # -- stepping -----------------------------------------------------------------

    def step(self) -> None:
        """Advance one ``dt``: servo firmware tick, then RK4 on the rigid body.

        A step where no stop, spring or wall acts runs as the straight-line code of
        :mod:`armlab.hardware.sim.plant_step`, which does the same float operations as
        :meth:`_readable_step`, in the same order."""
        q, qd = self._q, self._qd
        if self._pushes:
            self._update_pushes(q)
        # Stops only when a joint is within reach of a limit this step (13 rad/s × dt << 0.05).
        stops = self.stops is not None and any(
            x < lo + 0.05 or x > hi - 0.05
            for x, lo, hi in zip(q, self._lower, self._upper, strict=True))
        held = self._held_torques()
        if stops or self._spring is not None or self._wall is not None:
            self._readable_step(q, qd, held, stops=stops)
        else:
            self._q, self._qd = rk4_step(self.n, self._coulomb_joints, len(held))(
                q, qd, self.servos, self.directions, self._viscous, self._coulomb_pairs, held,
                self._dyn.fd, self._gravity, self._armature, self.dt)
        self._k += 1
        if not finite(self._qd):
            raise FloatingPointError(f"plant diverged at t = {self.t:.3f} s (q = {self._q})")
        if self._wall is not None and self._wall_peak is not None:  # (asked for: an
            # impact lasts a few steps, its peak is kept)
            self._wall_peak = max(self._wall_peak, self.wall_force())

    def _held_torques(self) -> tuple[list[float], ...]:
        """The joint torques held over this step, in the order the derivative adds them:
        the pushes' J^T F, then the applied joint torques (each only when present)."""
        held = []
        if self._pushes:
            held.append(self._push_tau)
        if self._joint_torques:
            held.append([float(x) for x in self.joint_torques()])
        return tuple(held)

    def _readable_step(self, q: list[float], qd: list[float], held: tuple[list[float], ...],
                       *, stops: bool) -> None:
        """One step as the equations read: tick the servos, then classical RK4 with the
        duties and ``held`` torques fixed and the stops (when ``stops``), spring and wall
        re-evaluated at each stage."""
        dt = self.dt
        dirs = self.directions
        servos = self.servos
        for i in range(self.n):
            d = dirs[i]
            servos[i].update(dt, d * q[i], d * qd[i])
        deriv = self._derivative(held, stops=stops)
        k1 = deriv(q, qd)
        h = 0.5 * dt
        q2 = [a + h * b for a, b in zip(q, qd, strict=True)]
        v2 = [a + h * b for a, b in zip(qd, k1, strict=True)]
        k2 = deriv(q2, v2)
        q3 = [a + h * b for a, b in zip(q, v2, strict=True)]
        v3 = [a + h * b for a, b in zip(qd, k2, strict=True)]
        k3 = deriv(q3, v3)
        q4 = [a + dt * b for a, b in zip(q, v3, strict=True)]
        v4 = [a + dt * b for a, b in zip(qd, k3, strict=True)]
        k4 = deriv(q4, v4)
        s = dt / 6.0
        self._q = [a + s * (b + 2.0 * (c + d) + e)
                   for a, b, c, d, e in zip(q, qd, v2, v3, v4, strict=True)]
        self._qd = [a + s * (b + 2.0 * (c + d) + e)
                    for a, b, c, d, e in zip(qd, k1, k2, k3, k4, strict=True)]

    def advance_to(self, t: float) -> int:
        """Step until the plant time reaches ``t`` s (to within dt/2); returns the steps taken."""
        target = scalar("t", t)
        steps = 0
        while (self._k + 0.5) * self.dt <= target:
            self.step()
            steps += 1
        return steps

    def _derivative(self, held: tuple[list[float], ...], *, stops: bool
                    ) -> Callable[[list[float], list[float]], tuple[float, ...]]:
        """qdd(q, qd) for this step: servo duties and ``held`` torques fixed, the stops (when
        ``stops``), spring and wall re-evaluated."""
        drive = [d * s.drive for d, s in zip(self.directions, self.servos, strict=True)]
        damp = [s.damping + b for s, b in zip(self.servos, self._viscous, strict=True)]
        coulomb = self._coulomb
        fields = self._spring is not None or self._wall is not None
        fd, g, arm = self._dyn.fd, self._gravity, self._armature
        tanh = math.tanh

        def deriv(q: list[float], qd: list[float]) -> tuple[float, ...]:
            tau = [a - b * v for a, b, v in zip(drive, damp, qd, strict=True)]
            for i, (c, rvs) in coulomb:
                tau[i] -= c * tanh(qd[i] * rvs)
            if stops:
                tau = [a + b for a, b in zip(tau, self._stop_torques(q, qd), strict=True)]
            for extra in held:
                tau = [a + b for a, b in zip(tau, extra, strict=True)]
            if fields:
                tau = [a + b for a, b in zip(tau, self._field_torques(q, qd), strict=True)]
            return fd(q, qd, tau, g, arm)

        return deriv

    def _stop_torques(self, q: list[float], qd: list[float]) -> list[float]:
        """Torques of the joint-limit stops (spring beyond the limit, damping going further)."""
        out = [0.0] * self.n
        if self.stops is None:
            return out
        k, c = self.stops.stiffness, self.stops.damping
        lo, hi = self._lower, self._upper
        for i in range(self.n):
            if q[i] < lo[i]:
                out[i] = k * (lo[i] - q[i]) - (c * qd[i] if qd[i] < 0 else 0.0)
            elif q[i] > hi[i]:
                out[i] = k * (hi[i] - q[i]) - (c * qd[i] if qd[i] > 0 else 0.0)
        return out

    def _update_pushes(self, q: list[float]) -> None:
        """Drop expired pushes; J^T F of the rest at the step's start (held over the step)."""
        now = self.t
        self._pushes = [p for p in self._pushes if p.until > now + 1e-12]
        tau = [0.0] * self.n
        if self._pushes:
            fr = self._dyn.frames(q)
            for p in self._pushes:
                _, cols = self._point(fr, p.link, p.point)
                for j, col in enumerate(cols):
                    tau[j] += col[0] * p.force[0] + col[1] * p.force[1] + col[2] * p.force[2]
        self._push_tau = tau

    def _point(self, fr: tuple[float, ...], link: int, point: tuple[float, float, float]
               ) -> tuple[list[float], list[tuple[float, float, float]]]:
        """Base-frame position of a link point and its Jacobian columns (3,) for joints <= link."""
        o = 12 * link
        px, py, pz = point
        p = [fr[o] * px + fr[o + 1] * py + fr[o + 2] * pz + fr[o + 9],
             fr[o + 3] * px + fr[o + 4] * py + fr[o + 5] * pz + fr[o + 10],
             fr[o + 6] * px + fr[o + 7] * py + fr[o + 8] * pz + fr[o + 11]]
        cols = []
        for j in range(link + 1):
            a = self._dyn.axes[j]
            b = 12 * j
            z = (fr[b] * a[0] + fr[b + 1] * a[1] + fr[b + 2] * a[2],
                 fr[b + 3] * a[0] + fr[b + 4] * a[1] + fr[b + 5] * a[2],
                 fr[b + 6] * a[0] + fr[b + 7] * a[1] + fr[b + 8] * a[2])
            if self._dyn.revolute[j]:
                rx, ry, rz = p[0] - fr[b + 9], p[1] - fr[b + 10], p[2] - fr[b + 11]
                cols.append((z[1] * rz - z[2] * ry, z[2] * rx - z[0] * rz, z[0] * ry - z[1] * rx))
            else:
                cols.append(z)
        return p, cols

    def _field_torques(self, q: list[float], qd: list[float]) -> list[float]:
        """J^T F of the spring and the wall at (q, qd)."""
        fr = self._dyn.frames(q)
        tau = [0.0] * self.n
        for src in (self._spring, self._wall):
            if src is None:
                continue
            p, cols = self._point(fr, src.link, src.point)
            vx = vy = vz = 0.0  # the point's velocity, J q̇ (in joint order, as sum() adds)
            for col, w in zip(cols, qd, strict=False):
                vx += col[0] * w
                vy += col[1] * w
                vz += col[2] * w
            v = [vx, vy, vz]
            if isinstance(src, _Spring):
                f = [src.stiffness * (src.anchor[r] - p[r]) - src.damping * v[r]
                     for r in range(3)]
            else:
                mag = _wall_push(src, p, v)
                if mag == 0.0:
                    continue
                nrm = src.normal
                if src.friction > 0.0:
                    rub = _wall_friction(src, mag, v)
                    f = [mag * nrm[0] + rub[0], mag * nrm[1] + rub[1], mag * nrm[2] + rub[2]]
                else:
                    f = [mag * nrm[0], mag * nrm[1], mag * nrm[2]]
            for j, col in enumerate(cols):
                tau[j] += col[0] * f[0] + col[1] * f[1] + col[2] * f[2]
        return tau

    def wall_peak(self) -> float:
        """N, the largest wall force at the end of any step since the last call (then
        forgotten): an impact's peak, which a controller's period may fall between. The
        plant keeps it from the first call on (until then its steps skip the work)."""
        peak, self._wall_peak = self._wall_peak, 0.0
        return self.wall_force() if peak is None else max(peak, self.wall_force())

    def wall_force(self) -> float:
        """N, the wall's normal force on the arm now (ground truth: 0 off the wall, or
        without one): what a force sensor at the contact would read."""
        w = self._wall
        if w is None:
            return 0.0
        p, cols = self._point(self._dyn.frames(self._q), w.link, w.point)
        v = [sum(cols[j][r] * self._qd[j] for j in range(len(cols))) for r in range(3)]
        return _wall_push(w, p, v)

    # -- ground truth and reports -------------------------------------------------

    def truth(self) -> GroundTruth:
        """The true state and torques now (duty of the last firmware tick)."""
        q, qd = self._q, self._qd
        motor, fric = [], []
        for i, servo in enumerate(self.servos):
            d = self.directions[i]
            motor.append(d * servo.motor_torque(d * qd[i]))
            fric.append(-d * servo.friction(d * qd[i]))
        ext = list(self._push_tau) if self._pushes else [0.0] * self.n
        if self._joint_torques:
            ext = [a + b for a, b in zip(ext, self.joint_torques(), strict=True)]
        if self._spring is not None or self._wall is not None:
            ext = [a + b for a, b in zip(ext, self._field_torques(q, qd), strict=True)]
        stop = self._stop_torques(q, qd)
        return GroundTruth(self.t, np.array(q), np.array(qd), np.array(motor), np.array(fric),
                           np.array(ext), np.array(stop))

    def servo_report(self, i: int) -> Any:
        """What servo ``i`` would answer to a READ (raw words: its family's report)."""
        return self.servos[self._link(i)].report()

    def reports(self) -> tuple[Any, ...]:
        """Every servo's report, in joint order."""
        return tuple(s.report() for s in self.servos)

    def energy(self) -> tuple[float, float]:
        """(kinetic incl. rotors, gravitational potential) J of the true state."""
        return (kinetic_energy(self.model, self._q, self._qd, armature=self._armature),
                potential_energy(self.model, self._q))
