"""The simulated arm: rigid-body dynamics + one Dynamixel firmware/motor model per joint.

Each step of ``dt`` (1 ms default):

1. every servo's firmware ticks once
(each family's firmware model, ``update``): it
   senses its horn, moves its set-point, fixes its PWM duty for the step;
2. the state (q, qd) is integrated by classical Runge–Kutta 4 with
   ``qdd = forward_dynamics(q, qd, tau)`` (thesis eq. 2.41–2.50 inverted), where tau =
   servo torques (motor line at the held duty, gear friction) + joint stops + external
   forces (push, spring, wall) + applied joint torques (a known disturbance), all
   re-evaluated at each RK stage except the push, the applied torques and the duty (the
   wall's touches at each stage from their Jacobian held at the step's start:
   :mod:`armlab.hardware.sim.contact`). The rotor inertias enter as armature (diagonal
   extra inertia).

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
from functools import partial
from typing import Any, cast

import numpy as np

from armlab.hardware.servos.registry import FAMILIES, family_of_spec
from armlab.hardware.servos.servo_spec import ServoSpec, TurnEncoder
from armlab.hardware.sim.contact import (
    HOLD_MARGIN_M,
    HeldTouch,
    Obstacle,
    Touch,
    checked_friction,
    checked_size,
    checked_wall,
    clear,
    face_axes,
    held_push,
    held_touch,
    surface,
    touch_groups,
)
from armlab.hardware.sim.plant_step import rk4_step
from armlab.hardware.sim.servo_motor import GearedMotor, ServoParams
from armlab.kinematics.collision import contact_balls
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
class JointStops:
    """Soft mechanical stops at the model's joint limits (the arm hitting its own body).

    Attributes:
        stiffness: N·m/rad beyond a limit. damping: N·m·s/rad while beyond it.
    """

    stiffness: float = 50.0
    damping: float = 0.5



def _floats(v: np.ndarray) -> tuple[float, float, float]:
    """A (3,) array as a tuple of Python floats."""
    x, y, z = v.tolist()
    return float(x), float(y), float(z)


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
            1.0, ``XRegisters`` for an X-series joint) to use (default: factory values,
            goal at the initial position, torque off).
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
        self._wall: Obstacle | None = None
        self._wall_reach = 1.0  #: m a touch moves at most per rad of the joints
        #: (step count, the touches held there): :meth:`_near_touches`' last answer
        self._near: tuple[int, list[HeldTouch]] | None = None
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
        self._near = None

    # -- external forces (base frame) ------------------------------------------

    def push(self, force_base: np.ndarray, *, link: int, point: np.ndarray,
             duration: float) -> None:
        """Apply ``force_base`` (3,) N, **base frame**, at ``point`` (3,) m in link ``link``'s
        frame, for ``duration`` s from now. Pushes add up while they overlap."""
        f = vector("force_base", force_base, 3)
        p = vector("point", point, 3)
        k = self._link(link)
        d = scalar("duration", duration, nonnegative=True)
        self._pushes.append(_Push(_floats(f), k, _floats(p), self.t + d))

    def set_spring(self, anchor_base: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray, damping: float = 0.0) -> None:
        """Pull ``point`` (3,) m on ``link`` towards ``anchor_base`` (3,) m, base frame, with
        a spring of ``stiffness`` N/m and ``damping`` N·s/m (a hand dragging); None releases."""
        if anchor_base is None:
            self._spring = None
            return
        k = scalar("stiffness", stiffness, nonnegative=True)
        c = scalar("damping", damping, nonnegative=True)
        self._spring = _Spring(_floats(vector("anchor_base", anchor_base, 3)), k, c,
                               self._link(link), _floats(vector("point", point, 3)))

    def set_wall(self, origin_base: np.ndarray | None, normal_base: np.ndarray | None = None, *,
                 stiffness: float = 5000.0, damping: float = 30.0, link: int | None = None,
                 point: np.ndarray | None = None, friction: float = 0.0,
                 size: Sequence[float] | None = None) -> None:
        """A rigid-ish obstacle the arm can press on (:mod:`armlab.hardware.sim.contact`):
        a plane, or a box with one face on it; None removes it.

        Args:
            origin_base: (3,) m, a point of the plane, base frame.
            normal_base: (3,) the plane's normal pointing to the free side, base frame.
            stiffness: N/m of penetration; damping: N·s/m while in contact (never pulls).
            friction: μ of its Coulomb friction along the surface.
            size: None: the plane (a wall); (width, height, thickness) m: a box (a table
                top, a block) with its face on the plane, centred at ``origin_base``,
                its width across (horizontal in the base frame), the thickness behind.
            link, point: one contact point on the arm (default: the end effector's tip;
                a box is met by every ball of the model's collision shapes too, each
                link's ``<collision>`` of its URDF,
                :func:`armlab.kinematics.collision.contact_balls`. A plane is met by the
                one point: unbounded, it would cut through the arm's own links wherever
                they reach past it, as the receptionist arm's elbow does past a wall
                across the thesis line).
        """
        self._near = None
        if origin_base is None:
            self._wall = None
            return
        origin, normal, k, c, li, pt = checked_wall(
            origin_base, normal_base, stiffness, damping, link, point, n=self.n,
            tip=self.model.tip[:3, 3], link_index=self._link)
        touches = [Touch(li, cast("tuple[float, float, float]", tuple(float(x) for x in pt)))]
        if link is None and point is None and size is not None:
            touches += [Touch(b.link, b.centre, b.radius) for b in contact_balls(self.model)]
        across, up = face_axes(normal)
        self._wall = Obstacle(  # (of Python floats: numpy's scalars would make every
            # stage's arithmetic, the dynamics' too, several times slower)
            _floats(origin), _floats(normal), k, c, touch_groups(touches),
            checked_friction(friction), checked_size(size), _floats(across), _floats(up))
        # (a point p of link L moves |Σ_j ω_j × (p − o_j)| <= Σ|θ̇| · max |p − o_j|; a
        # prismatic joint moves it |θ̇| itself: at least 1 m per unit)
        self._wall_reach = max(1.0, float(
            sum(np.linalg.norm(j.origin[:3, 3]) for j in self.model.joints)
            + max(math.hypot(*t.point) + t.radius for t in touches)))

    @property
    def wall(self) -> tuple[np.ndarray, np.ndarray, float, float, float] | None:
        """The wall :meth:`set_wall` placed: (origin (3,) m, unit normal (3,), stiffness
        N/m, damping N·s/m, friction μ), base frame; None without one."""
        w = self._wall
        return None if w is None else (np.array(w.origin), np.array(w.normal),
                                       w.stiffness, w.damping, w.friction)

    @property
    def wall_size(self) -> tuple[float, float, float] | None:
        """The box's (width, height, thickness) m :meth:`set_wall` placed, or None (a
        plane, or no wall)."""
        return None if self._wall is None else self._wall.size

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

        A step where no joint-limit stop acts runs as the straight-line code of
        :mod:`armlab.hardware.sim.plant_step` (with a spring or wall, their torques
        re-evaluated at each stage by :meth:`_field_torques`), which does the same float
        operations as :meth:`_readable_step`, in the same order."""
        q, qd = self._q, self._qd
        if self._pushes:
            self._update_pushes(q)
        # Stops only when a joint is within reach of a limit this step (13 rad/s × dt << 0.05).
        stops = self.stops is not None and any(
            x < lo + 0.05 or x > hi - 0.05
            for x, lo, hi in zip(q, self._lower, self._upper, strict=True))
        held = self._held_torques()
        fields = self._spring is not None or self._wall is not None
        if stops:
            self._readable_step(q, qd, held, self._near_touches(), stops=stops)
        else:
            field = (partial(self._field_torques, near=self._near_touches(), q0=q)
                     if fields else None)
            self._q, self._qd = rk4_step(self.n, self._coulomb_joints, len(held), fields)(
                q, qd, self.servos, self.directions, self._viscous, self._coulomb_pairs, held,
                self._dyn.fd, self._gravity, self._armature, self.dt, field)
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
                       near: list[HeldTouch], *, stops: bool) -> None:
        """One step as the equations read: tick the servos, then classical RK4 with the
        duties and ``held`` torques fixed and the stops (when ``stops``), spring and wall
        re-evaluated at each stage (the wall's touches ``near`` held from q)."""
        dt = self.dt
        dirs = self.directions
        servos = self.servos
        for i in range(self.n):
            d = dirs[i]
            servos[i].update(dt, d * q[i], d * qd[i])
        deriv = self._derivative(held, near, q, stops=stops)
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

    def _derivative(self, held: tuple[list[float], ...], near: list[HeldTouch],
                    q0: list[float], *, stops: bool
                    ) -> Callable[[list[float], list[float]], tuple[float, ...]]:
        """qdd(q, qd) for this step: servo duties and ``held`` torques fixed, the stops (when
        ``stops``), spring and wall re-evaluated (the wall's touches ``near`` held at the
        step's start ``q0``)."""
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
                tau = [a + b for a, b in zip(tau, self._field_torques(q, qd, near, q0),
                                             strict=True)]
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

    def _field_torques(self, q: Sequence[float], qd: Sequence[float], near: list[HeldTouch],
                       q0: Sequence[float]) -> list[float]:
        """J^T F of the spring and the wall at (q, qd): the spring's at q itself, the
        wall's on its touches ``near`` held at ``q0`` (:func:`held_push`)."""
        tau = [0.0] * self.n
        s = self._spring
        if s is not None:
            p, cols = self._point(self._dyn.frames(q), s.link, s.point)
            v = _velocity(cols, qd)
            f = [s.stiffness * (s.anchor[r] - p[r]) - s.damping * v[r] for r in range(3)]
            _add_torque(tau, cols, f)
        w = self._wall
        if w is not None and near:
            dq = [a - b for a, b in zip(q, q0, strict=True)]
            for touch in near:
                held_push(w, touch, dq, qd, tau)
        return tau

    def _near_touches(self) -> list[HeldTouch]:
        """The wall's touches held at the state now (:class:`HeldTouch`): those the
        joints' speeds can bring within :data:`HOLD_MARGIN_M` of it in a step (a link's
        touches only where the ball bounding them can). Worked out once a state: the
        force the loop reads at a step's end is the next step's start."""
        w = self._wall
        if w is None:
            return []
        near = self._near
        if near is not None and near[0] == self._k:
            return near[1]
        q, qd = self._q, self._qd
        fr = self._dyn.frames(q)
        reach = HOLD_MARGIN_M + 2.0 * self.dt * self._wall_reach * sum(abs(x) for x in qd)
        out: list[HeldTouch] = []
        for g in w.groups:
            if len(g.touches) > 1 and clear(w, self._at(fr, g.link, g.centre),
                                            g.reach + reach):
                continue
            for touch in g.touches:
                dist, nrm = surface(w, self._at(fr, touch.link, touch.point))
                depth = touch.radius - dist
                if depth <= -reach:
                    continue
                _, cols = self._point(fr, touch.link, touch.point)
                out.append(held_touch(cols, depth, nrm))
        self._near = (self._k, out)
        return out

    @staticmethod
    def _at(fr: tuple[float, ...], link: int, point: Sequence[float]) -> list[float]:
        """Base-frame position of a point (3,) of link ``link`` at frames ``fr``."""
        o = 12 * link
        px, py, pz = point
        return [fr[o] * px + fr[o + 1] * py + fr[o + 2] * pz + fr[o + 9],
                fr[o + 3] * px + fr[o + 4] * py + fr[o + 5] * pz + fr[o + 10],
                fr[o + 6] * px + fr[o + 7] * py + fr[o + 8] * pz + fr[o + 11]]

    def wall_peak(self) -> float:
        """N, the largest wall force at the end of any step since the last call (then
        forgotten): an impact's peak, which a controller's period may fall between. The
        plant keeps it from the first call on (until then its steps skip the work)."""
        peak, self._wall_peak = self._wall_peak, 0.0
        return self.wall_force() if peak is None else max(peak, self.wall_force())

    def wall_force(self) -> float:
        """N, the wall's normal force on the arm now, summed over every touch pressing on
        it (ground truth: 0 off the wall, or without one): what a force plate under the
        wall would read."""
        w = self._wall
        if w is None:
            return 0.0
        still, scratch = [0.0] * self.n, [0.0] * self.n
        return sum(held_push(w, touch, still, self._qd, scratch)
                   for touch in self._near_touches())

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
            ext = [a + b for a, b in zip(ext, self._field_torques(q, qd, self._near_touches(),
                                                                  q), strict=True)]
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


def _velocity(cols: Sequence[Sequence[float]], qd: Sequence[float]) -> list[float]:
    """(3,) m/s of a point whose Jacobian columns are ``cols`` at joint speeds ``qd`` (in
    joint order, as sum() adds)."""
    vx = vy = vz = 0.0
    for col, w in zip(cols, qd, strict=False):
        vx += col[0] * w
        vy += col[1] * w
        vz += col[2] * w
    return [vx, vy, vz]


def _add_torque(tau: list[float], cols: Sequence[Sequence[float]], f: Sequence[float]) -> None:
    """``tau`` += Jᵀ f of a force ``f`` (3,) N at a point of Jacobian columns ``cols``."""
    for j, col in enumerate(cols):
        tau[j] += col[0] * f[0] + col[1] * f[1] + col[2] * f[2]
