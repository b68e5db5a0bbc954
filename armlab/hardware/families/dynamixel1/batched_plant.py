"""N simulated arms of one model stepped together: :class:`armlab.hardware.sim.plant.Plant`, numpy
over arms.

A classroom gives every student a private arm of the same model (``receptionist_arm``:
three RX-24F). Instead of N ``Plant`` objects stepped by a Python loop each, one
:class:`BatchedPlant` keeps every arm's state in arrays and runs each step's
arithmetic once for all arms. The semantics are those of N independent ``Plant``
objects (tests/test_batched_plant.py checks q, qd to 1e-9 and every raw report word
exactly, at every step):

1. every servo's firmware ticks (:meth:`BatchedPlant._tick`, the vectorised
   :meth:`armlab.hardware.families.dynamixel1.firmware.ServoModel.update`, thesis §2.3): the 10-bit
   Present Position,
   the set-point moved towards Goal Position at Moving Speed, the compliance curve
   (margin, punch, slope, Torque Limit; thesis Table 2.4 / Gambar 2.20) giving the
   PWM duty held over the step, wheel mode, the overload alarm with Alarm Shutdown;
2. (q, qd) is integrated by classical RK4 with ``qdd = forward_dynamics(q, qd, tau)``
   (thesis eq. 2.41–2.50 inverted; :mod:`armlab.kinematics.batched_dynamics` runs the float
   path's generated code over arrays), tau = motor line at the held duty
   (stall torque · duty − back-EMF · omega) − gear friction (viscous + tanh-smoothed
   Coulomb) + joint stops + pushes (J^T F, held over the step).

Layout: the public arrays are arm-major, (N, n) (arm, joint), in *row order*; inside,
every array is joint-major (n, N) so that one joint of all arms is a contiguous row
for the generated code. Arms are named by a stable integer **id** that
:meth:`add_arm` returns; rows are the arms in the order they joined. Storage is
exact-size: :meth:`add_arm` appends a column and :meth:`remove_arm` deletes one
(both reallocate, O(N n), microseconds; rows after a removed arm move up by one, ids
never change). ``arm_ids`` maps rows to ids. All arms share one clock t = k·dt; an arm
added later starts at the current t. Forces and points are in the model's base frame,
as in ``Plant``.

Per arm, as ``Plant``: pushes (held over a step), a spring (a hand dragging) and a wall
(a plane or a box to press on, met as Plant's), both re-evaluated at each RK stage (the
wall's touches from their Jacobian held at the step's start,
:mod:`armlab.hardware.sim.contact`). Left out of
``Plant`` (say so where it matters): :meth:`Plant.truth` / energies; the servo params
(rotor, friction, overload time), directions and stops are one set for all arms;
Coulomb friction uses ``numpy.tanh``, which may differ from ``math.tanh`` in the last
bit (hence "to 1e-9", not bit-equal, in the test).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields
from typing import NamedTuple, cast

import numpy as np

from armlab.hardware.families.dynamixel1 import compiled_contact, compiled_firmware
from armlab.hardware.families.dynamixel1.firmware import (
    ERROR_ANGLE_LIMIT,
    ERROR_OVERLOAD,
    ServoRegisters,
    ServoReport,
    effective_slope,
)
from armlab.hardware.servos.servo_spec import DIRECTION_BIT, ServoSpec, signed_word
from armlab.hardware.sim.contact import (
    FRICTION_DAMPING,
    HOLD_MARGIN_M,
    Touch,
    checked_friction,
    checked_size,
    checked_wall,
    face_axes,
    touch_groups,
)
from armlab.hardware.sim.plant import JointStops
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.batched_dynamics import FLOAT_ARMS, batched_dynamics
from armlab.kinematics.collision import contact_balls
from armlab.kinematics.compiled_dynamics import POINTS, as_input
from armlab.kinematics.machine_code import Kernel
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import clamp
from armlab.kinematics.validate import index, scalar, vector

#: The registers the firmware acts on, held per (joint, arm) as int64 arrays.
REGISTERS: tuple[str, ...] = tuple(f.name for f in fields(ServoRegisters))
_SLOPES = np.array([effective_slope(v) for v in range(256)], dtype=np.int64)  # Table 2.4
_STOPS = JointStops()  #: Plant's default stops
#: the registers the compiled tick reads, in its order (compiled_firmware.tick_servos)
_TICK_REGISTERS = ("torque_limit", "torque_enable", "cw_angle_limit", "ccw_angle_limit",
                   "goal_position", "moving_speed", "cw_compliance_margin",
                   "ccw_compliance_margin", "cw_compliance_slope", "ccw_compliance_slope",
                   "punch", "alarm_shutdown")
#: the state it writes, in its order after the three it updates
_TICK_OUTPUTS = ("present", "velocity", "enabled", "setpoint", "duty", "moving",
                 "angle_error", "drive", "damping")

#: The spring and the wall per arm: name -> (leading shape, dtype); arrays (*shape, N).
_FIELDS: dict[str, tuple[tuple[int, ...], type]] = {
    "spring_on": ((), np.bool_), "spring_anchor": ((3,), np.float64),
    "spring_k": ((), np.float64), "spring_c": ((), np.float64),
    "spring_link": ((), np.int64), "spring_point": ((3,), np.float64),
    "wall_on": ((), np.bool_), "wall_origin": ((3,), np.float64),
    "wall_normal": ((3,), np.float64), "wall_k": ((), np.float64),
    "wall_c": ((), np.float64), "wall_link": ((), np.int64), "wall_point": ((3,), np.float64),
    "wall_mu": ((), np.float64),
    # a box (Plant's): its (width, height, thickness) m, the directions of its width and
    # height (3,), and whether the links' contact balls meet it beside the point
    "wall_box": ((), np.bool_), "wall_size": ((3,), np.float64),
    "wall_across": ((3,), np.float64), "wall_up": ((3,), np.float64),
    "wall_balls": ((), np.bool_),
    # m the wall's contact point is at least off its plane now (its depth when last
    # computed, less what the joints' speeds may have moved it since; 0: compute it)
    "wall_gap": ((), np.float64),
}

#: Firmware state per (joint, arm): name -> dtype (see ServoModel's private fields).
_STATE: dict[str, type] = {
    "q": np.float64, "qd": np.float64, "present": np.int64, "setpoint": np.float64,
    "velocity": np.float64, "enabled": np.bool_, "duty": np.float64, "stall": np.float64,
    "overload": np.bool_, "shutdown": np.bool_, "angle_error": np.bool_, "moving": np.bool_,
    "drive": np.float64, "damping": np.float64, "push_tau": np.float64,
}


class _WallHold(NamedTuple):
    """The walls near their arms' touches at one state, as the step from it holds them
    (Plant's :class:`~armlab.hardware.sim.contact.HeldTouch`, over P touches of the R
    arm rows ``rows``): the state's step count; the arm rows; each touch's row (P,) and
    its place in ``rows`` (P,), and whether every row has one touch; q₀ (n, P), the
    touch's Jacobian columns (n, 3, P) there and them along the normal (n, P), its depth
    inside (P,) m (negative: outside), the obstacle's normal there (3, P), its stiffness,
    damping and friction (P,), and whether any of them has friction."""

    step: int
    rows: np.ndarray
    touch_rows: np.ndarray
    slot: np.ndarray
    single: bool
    q0: np.ndarray
    cols: np.ndarray
    along: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    k: np.ndarray
    c: np.ndarray
    mu: np.ndarray
    rubs: bool


class ReportWords(NamedTuple):
    """One arm's raw words as its servos report them, per joint in joint order (ints)."""

    position: list[int]  #: Present Position 0..1023
    speed: list[int]  #: Present Speed (bit 10 = CW)
    load: list[int]  #: Present Load (bit 10 = CW)
    error: list[int]  #: status error byte (angle limit, overload)
    torque_enable: list[int]  #: Torque Enable register


def signed_words(units: np.ndarray) -> np.ndarray:
    """:func:`armlab.hardware.servos.servo_spec.signed_word` elementwise: signed register units ->
    words
    (magnitude 0..1023 rounded half to even, bit 10 set when negative and non-zero)."""
    a = np.abs(units)
    mag = np.where(a >= 1023.0, 1023.0, np.rint(a)).astype(np.int64)
    return mag | np.where((units < 0) & (mag != 0), DIRECTION_BIT, 0)


class BatchedPlant:
    """N arms + servos of one model, stepped together at a fixed ``dt``.

    Args:
        model: the serial chain (n joints).
        spec: the servo of every joint (one :class:`ServoSpec` for all, or one per joint).
        n_arms: arms to start with, all at ``q0`` with ``registers`` (more: :meth:`add_arm`).
        dt: step and firmware tick, s (<= 0.01).
        q0: (n,) the starting arms' joint positions (default neutral), at rest.
        directions: (n,) +1/-1 servo = direction · joint (default +1).
        params: :class:`ServoParams` for every joint or one per joint.
        registers: the starting arms' registers, one :class:`ServoRegisters` per joint
            (copied per arm; default factory values, goal at the start, torque off).
        stops: joint-limit stops (None for none).
    """

    def __init__(self, model: SerialChain, spec: ServoSpec | Sequence[ServoSpec],
                 n_arms: int = 0, *, dt: float = 1e-3, q0: np.ndarray | None = None,
                 directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 registers: Sequence[ServoRegisters] | None = None,
                 stops: JointStops | None = _STOPS) -> None:
        n = model.n
        self.model = model
        self.n = n
        self.dt = scalar("dt", dt, positive=True)
        if self.dt > 0.01:
            raise ValueError(f"dt must be <= 0.01 s for a stable servo loop, got {dt}")
        if isinstance(n_arms, bool) or not isinstance(n_arms, int | np.integer) or n_arms < 0:
            raise ValueError(f"n_arms must be an integer >= 0, got {n_arms!r}")
        specs = [spec] * n if isinstance(spec, ServoSpec) else list(spec)
        if len(specs) != n:
            raise ValueError(f"spec must name {n} servos, got {len(specs)}")
        self.specs = tuple(specs)
        if params is None or isinstance(params, ServoParams):
            plist = [params or ServoParams()] * n
        else:
            plist = list(params)
            if len(plist) != n:
                raise ValueError(f"params must have {n} entries, got {len(plist)}")
        self.params = tuple(plist)
        dirs = [1.0] * n if directions is None else [
            float(d) for d in vector("directions", directions, n)]
        if any(d not in (1.0, -1.0) for d in dirs):
            raise ValueError(f"directions must be +1 or -1, got {dirs}")
        self.directions = tuple(dirs)
        self.stops = stops
        self._dyn = batched_dynamics(model)

        def col(values: Sequence[float]) -> np.ndarray:
            return np.array(values, dtype=float).reshape(n, 1)

        self._dir = col(dirs)
        self._cpr = col([1.0 / s.position_unit for s in specs])  # counts per rad
        self._cpsu = col([s.speed_unit / s.position_unit for s in specs])  # counts per unit·s
        self._speed_unit = col([s.speed_unit for s in specs])
        self._speed_units = [s.speed_unit for s in specs]
        self._stall_torque = col([s.stall_torque for s in specs])
        self._backemf = col([s.stall_torque / s.no_load_speed for s in specs])
        self._viscous = col([p.viscous_friction for p in plist])
        self._coulomb = col([p.coulomb_friction for p in plist])
        self._rvs = col([1.0 / p.friction_speed for p in plist])
        self._has_coulomb = any(p.coulomb_friction for p in plist)
        self._stall_speed = col([p.stall_speed for p in plist])
        self._overload_time = col([p.overload_time for p in plist])
        self._voltage = [int(round(p.voltage * 10)) for p in plist]
        self._temperature = [int(round(p.temperature)) for p in plist]
        self._armature = [p.rotor_inertia for p in plist]
        self._gravity = [float(x) for x in model.gravity]
        #: per joint, what the compiled firmware tick takes (compiled_firmware.tick_servos)
        self._joint = np.ascontiguousarray(np.concatenate(
            [self._dir, self._cpr, self._cpsu, self._speed_unit, self._stall_speed,
             self._overload_time, self._stall_torque, self._backemf], axis=1).T)
        self._lower = col([float(x) for x in model.lower])
        self._upper = col([float(x) for x in model.upper])
        if not all(self._dyn.revolute):
            raise ValueError("model: BatchedPlant supports revolute joints only")
        self._axes = self._dyn.axes
        self._axes_array = np.array(self._axes, dtype=float).reshape(n, 3)
        #: m no point of a link reaches further from any joint's axis (plus its own point's
        #: offset): the bound of how far a contact point moves per rad of the joints
        self._reach = float(sum(np.linalg.norm(j.origin[:3, 3]) for j in model.joints)
                            + np.linalg.norm(model.tip[:3, 3]))
        self._k = 0
        self._hold: _WallHold | None = None  #: :meth:`_near_walls`' last answer
        none, empty = np.zeros(0, dtype=np.int64), np.zeros(0)
        self._no_walls = _WallHold(-1, none, none, none, True, np.zeros((n, 0)),
                                   np.zeros((n, 3, 0)), np.zeros((n, 0)), empty,
                                   np.zeros((3, 0)), empty, empty, empty, False)
        #: (the hold, its arms' ids, their forces N): :meth:`wall_forces`' last answer
        self._forces: tuple[_WallHold, np.ndarray, np.ndarray] | None = None
        self._next_id = 0
        self._ids = np.zeros(0, dtype=np.int64)
        self._row_of: dict[int, int] = {}  # id -> row, rebuilt when an arm joins or leaves
        self._s: dict[str, np.ndarray] = {k: np.zeros((n, 0), dtype=t) for k, t in _STATE.items()}
        self._r = {k: np.zeros((n, 0), dtype=np.int64) for k in REGISTERS}
        # pushes, one row each: arm row, link, force (3,), point (3,), until (s)
        self._p_row = np.zeros(0, dtype=np.int64)
        self._p_link = np.zeros(0, dtype=np.int64)
        self._p_force = np.zeros((0, 3))
        self._p_point = np.zeros((0, 3))
        self._p_until = np.zeros(0)
        self._f: dict[str, np.ndarray] = {k: np.zeros((*shape, 0), dtype=t)
                                          for k, (shape, t) in _FIELDS.items()}
        self._tip = tuple(float(x) for x in model.tip[:3, 3])
        # a box's touches (Plant's: the tip, then every contact ball, grouped by link),
        # their links (T,), points (3, T) and radii (T,), and how far any moves per rad
        tips = [Touch(n - 1, cast("tuple[float, float, float]", self._tip))]
        box = [t for g in touch_groups(tips + [Touch(b.link, b.centre, b.radius)
                                               for b in contact_balls(model)])
               for t in g.touches]
        self._box_link = np.array([t.link for t in box], dtype=np.int64)
        self._box_point = np.array([t.point for t in box], dtype=float).T
        self._box_radius = np.array([t.radius for t in box], dtype=float)
        self._box_reach = float(max(np.linalg.norm(t.point) + t.radius for t in box))
        for _ in range(int(n_arms)):
            self.add_arm(q0=q0, registers=registers)

    # -- arms ---------------------------------------------------------------------

    @property
    def n_arms(self) -> int:
        """N, the number of arms."""
        return int(self._ids.size)

    @property
    def arm_ids(self) -> np.ndarray:
        """(N,) the id of the arm in each row."""
        return self._ids.copy()

    def row(self, arm: int) -> int:
        """The row of arm id ``arm``; ValueError naming ``arm`` when there is no such arm."""
        if type(arm) is int:  # the usual case (every arm's every period): one lookup
            r = self._row_of.get(arm)
            if r is not None:
                return r
        if isinstance(arm, bool) or not isinstance(arm, int | np.integer):
            raise ValueError(f"arm must be an arm id (int), got {arm!r}")
        r = self._row_of.get(int(arm))
        if r is None:
            raise ValueError(f"arm {arm!r} is not in this plant (ids: {self._ids.tolist()})")
        return r

    def add_arm(self, *, q0: np.ndarray | None = None, qd0: np.ndarray | None = None,
                registers: Sequence[ServoRegisters] | None = None) -> int:
        """A new arm at ``q0`` (n,) rad (default neutral) moving at ``qd0`` (default rest),
        its servos as a fresh ``Plant``'s would be (``registers``: one per joint, copied;
        default factory values with the goal at the start, torque off). Returns its id."""
        n = self.n
        state, regs = self._fresh(q0, qd0, registers)
        for k, v in state.items():
            self._s[k] = np.concatenate([self._s[k], v.reshape(n, 1)], axis=1)
        for k, v in regs.items():
            self._r[k] = np.concatenate([self._r[k], v.reshape(n, 1)], axis=1)
        for k, (shape, t) in _FIELDS.items():
            self._f[k] = np.concatenate([self._f[k], np.zeros((*shape, 1), dtype=t)], axis=-1)
        arm = self._next_id
        self._next_id += 1
        self._ids = np.append(self._ids, arm)
        self._row_of[arm] = self._ids.size - 1
        self._hold = None
        return arm

    def reset_arm(self, arm: int, *, q0: np.ndarray | None = None,
                  qd0: np.ndarray | None = None,
                  registers: Sequence[ServoRegisters] | None = None) -> None:
        """Arm ``arm`` made again as :meth:`add_arm` makes a new one (the same arguments),
        in its own row and under its own id: its state, firmware and registers fresh, its
        pushes, spring and wall gone. The plant's time goes on."""
        r = self.row(arm)
        state, regs = self._fresh(q0, qd0, registers)
        for k, v in state.items():
            self._s[k][:, r] = v
        for k, v in regs.items():
            self._r[k][:, r] = v
        for k in self._f:
            self._f[k][..., r] = 0
        self._drop_pushes(self._p_row != r)
        self._hold = None

    def _fresh(self, q0: np.ndarray | None, qd0: np.ndarray | None,
               registers: Sequence[ServoRegisters] | None
               ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """A new arm's firmware state and registers, each (n,) by name (:meth:`add_arm`)."""
        n = self.n
        q = self.model.neutral() if q0 is None else vector("q0", q0, n)
        qd = np.zeros(n) if qd0 is None else vector("qd0", qd0, n)
        if registers is not None and len(registers) != n:
            raise ValueError(f"registers must have {n} entries, got {len(registers)}")
        angle = [d * float(x) for d, x in zip(self.directions, q, strict=True)]
        present = [s.position_to_raw(a) for s, a in zip(self.specs, angle, strict=True)]
        new: dict[str, Sequence[object]] = {k: [0] * n for k in _STATE}
        new["q"], new["qd"] = [float(x) for x in q], [float(x) for x in qd]
        new["present"] = present
        new["setpoint"] = [float(p) for p in present]
        new["velocity"] = [0.0] * n
        state: dict[str, np.ndarray] = {k: np.array(v, dtype=_STATE[k]) for k, v in new.items()}
        regs = [registers[i] if registers is not None else
                ServoRegisters(goal_position=present[i]) for i in range(n)]
        return state, {k: np.array([int(getattr(r, k)) for r in regs], dtype=np.int64)
                       for k in REGISTERS}

    def remove_arm(self, arm: int) -> None:
        """Remove arm id ``arm``, its pushes, spring and wall; the rows after it move up."""
        r = self.row(arm)
        for d in (self._s, self._r):
            for k in d:
                d[k] = np.delete(d[k], r, axis=1)
        for k in self._f:
            self._f[k] = np.delete(self._f[k], r, axis=-1)
        self._ids = np.delete(self._ids, r)
        self._row_of = {a: i for i, a in enumerate(self._ids.tolist())}
        keep = self._p_row != r
        self._drop_pushes(keep)
        self._p_row = np.where(self._p_row > r, self._p_row - 1, self._p_row)
        self._hold = None

    # -- state ----------------------------------------------------------------------

    @property
    def t(self) -> float:
        """Simulated time of every arm, s."""
        return self._k * self.dt

    @property
    def steps(self) -> int:
        """Steps taken since the plant was made (t = steps · dt)."""
        return self._k

    @property
    def q(self) -> np.ndarray:
        """(N, n) true joint positions, rad (a copy)."""
        return self._s["q"].T.copy()

    @property
    def qd(self) -> np.ndarray:
        """(N, n) true joint velocities, rad/s (a copy)."""
        return self._s["qd"].T.copy()

    def diverged(self) -> np.ndarray:
        """(k,) ids of the arms whose q or qd is not finite (after :meth:`step` raised
        FloatingPointError: put them back with :meth:`set_state` or remove them)."""
        bad = ~(np.all(np.isfinite(self._s["q"]), axis=0)
                & np.all(np.isfinite(self._s["qd"]), axis=0))
        return self._ids[bad].copy()

    def set_state(self, arm: int, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """Put arm ``arm`` at ``q`` (n,) with velocity ``qd`` (default rest); time goes on."""
        r = self.row(arm)
        self._s["q"][:, r] = vector("q", q, self.n)
        self._s["qd"][:, r] = 0.0 if qd is None else vector("qd", qd, self.n)
        self._f["wall_gap"][r] = -np.inf  # (moved: its wall's distance computed again)
        self._hold = None

    # -- registers (what a WRITE packet does) -----------------------------------------

    def registers(self, arm: int) -> tuple[ServoRegisters, ...]:
        """Arm ``arm``'s registers, one :class:`ServoRegisters` per joint (a snapshot)."""
        r = self.row(arm)
        return tuple(ServoRegisters(**{k: int(self._r[k][i, r]) for k in REGISTERS})
                     for i in range(self.n))

    def register(self, name: str) -> np.ndarray:
        """(N, n) the values of register ``name`` (a copy)."""
        if name not in self._r:
            raise ValueError(f"name must be a register ({', '.join(REGISTERS)}), got {name!r}")
        return self._r[name].T.copy()

    def set_registers(self, arm: int, joint: int | None = None, **values: int) -> None:
        """Write registers (raw ints, e.g. ``goal_position=600``) of arm ``arm``: joint
        ``joint``, or every joint when None. The firmware acts on them at the next tick."""
        r = self.row(arm)
        j = slice(None) if joint is None else self._link(joint, "joint")
        for k, v in values.items():
            if k not in self._r:
                raise ValueError(f"{k} is not a register ({', '.join(REGISTERS)})")
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or not 0 <= v <= 0xFFFF:
                raise ValueError(f"{k} must be a raw register value 0..65535, got {v!r}")
            self._r[k][j, r] = int(v)

    def write_registers(self, name: str, values: np.ndarray,
                        rows: Sequence[int] | None = None) -> None:
        """Vectorised WRITE: register ``name`` := ``values`` (N, n) raw ints, or (len(rows), n)
        for the arm rows ``rows`` only (e.g. Goal Position and Moving Speed of every arm)."""
        if name not in self._r:
            raise ValueError(f"name must be a register ({', '.join(REGISTERS)}), got {name!r}")
        v = np.asarray(values)
        cols = self._rows(rows)
        want = (self.n_arms if rows is None else int(np.size(cast(np.ndarray, cols))), self.n)
        if v.shape != want or not np.issubdtype(v.dtype, np.integer):
            raise ValueError(f"values must be integers of shape {want}, got {v.dtype} {v.shape}")
        if v.size and (v.min() < 0 or v.max() > 0xFFFF):
            raise ValueError("values must be raw register values 0..65535")
        self._r[name][:, cols] = v.T

    def set_goal(self, arm: int, goal_position: Sequence[int],
                 moving_speed: Sequence[int] | None = None) -> None:
        """Goal Position (n,) raw and optionally Moving Speed (n,) raw of arm ``arm`` (what
        ``SimBackend.write`` writes for one arm)."""
        r = self.row(arm)
        for name, values in (("goal_position", goal_position), ("moving_speed", moving_speed)):
            if values is None:
                continue
            v = list(values)  # checked in Python: this runs every period of every arm
            if len(v) != self.n or not (
                    all(type(x) is int and 0 <= x <= 0xFFFF for x in v)  # the usual case
                    or all(isinstance(x, int | np.integer) and not isinstance(x, bool)
                           and 0 <= x <= 0xFFFF for x in v)):
                raise ValueError(f"{name} must be {self.n} raw register values 0..65535, "
                                 f"got {values!r}")
            self._r[name][:, r] = v

    def set_goals(self, goal_position: np.ndarray, moving_speed: np.ndarray | None = None,
                  ) -> None:
        """Goal Position (N, n) raw and optionally Moving Speed (N, n) raw of every arm."""
        self.write_registers("goal_position", goal_position)
        if moving_speed is not None:
            self.write_registers("moving_speed", moving_speed)

    def set_torque_enable(self, on: np.ndarray | bool, rows: Sequence[int] | None = None,
                          ) -> None:
        """Torque Enable of every joint of every arm (or of the arm rows ``rows``): ``on`` one
        bool, or (N,) / (len(rows),) bools, one per arm."""
        cols = self._rows(rows)
        count = self.n_arms if rows is None else int(np.size(cast(np.ndarray, cols)))
        flags = np.asarray(on)
        if flags.dtype != np.bool_ or flags.shape not in ((), (count,)):
            raise ValueError(f"on must be a bool or ({count},) bools, got {flags.dtype} "
                             f"{flags.shape}")
        self._r["torque_enable"][:, cols] = flags.astype(np.int64)

    def _rows(self, rows: Sequence[int] | np.ndarray | None) -> slice | np.ndarray:
        if rows is None:
            return slice(None)
        r = np.asarray(rows)
        if r.ndim != 1 or (r.size and (not np.issubdtype(r.dtype, np.integer)
                                       or r.min() < 0 or r.max() >= self.n_arms)):
            raise ValueError(f"rows must be row indices 0..{self.n_arms - 1}, got {rows!r}")
        return r.astype(np.int64)

    # -- external forces (base frame) --------------------------------------------------

    def push(self, arm: int, force_base: np.ndarray, *, link: int, point: np.ndarray,
             duration: float) -> None:
        """Apply ``force_base`` (3,) N, base frame, at ``point`` (3,) m in link ``link``'s
        frame of arm ``arm`` for ``duration`` s from now (Plant.push; pushes add up)."""
        r = self.row(arm)
        f = vector("force_base", force_base, 3)
        p = vector("point", point, 3)
        k = self._link(link, "link")
        d = scalar("duration", duration, nonnegative=True)
        self._p_row = np.append(self._p_row, r)
        self._p_link = np.append(self._p_link, k)
        self._p_force = np.vstack([self._p_force, f])
        self._p_point = np.vstack([self._p_point, p])
        self._p_until = np.append(self._p_until, self.t + d)

    def push_rows(self, rows: Sequence[int] | np.ndarray, force_base: np.ndarray, *,
                  link: int, point: np.ndarray, duration: float) -> None:
        """:meth:`push` on many arms at once: on the arm in each row of ``rows`` (P,) the
        force of the same row of ``force_base`` (P, 3) N, base frame, at ``point`` (3,) m in
        link ``link``'s frame, for ``duration`` s from now (e.g. the floor on many feet; the
        pushes go after the ones given before, in ``rows`` order). Bad input adds none."""
        cols = self._rows(rows)
        if isinstance(cols, slice):
            raise ValueError("rows must name the arm rows to push, got None")
        f = np.asarray(force_base, dtype=float)
        if f.shape != (cols.size, 3) or not np.all(np.isfinite(f)):
            raise ValueError(f"force_base must be finite, of shape ({cols.size}, 3), got "
                             f"{f.shape}")
        p = vector("point", point, 3)
        k = self._link(link, "link")
        d = scalar("duration", duration, nonnegative=True)
        self._p_row = np.concatenate([self._p_row, cols])
        self._p_link = np.concatenate([self._p_link, np.full(cols.size, k, dtype=np.int64)])
        self._p_force = np.concatenate([self._p_force, f])
        self._p_point = np.concatenate([self._p_point, np.tile(p, (cols.size, 1))])
        self._p_until = np.concatenate([self._p_until, np.full(cols.size, self.t + d)])

    def set_spring(self, arm: int, anchor_base: np.ndarray | None, *, stiffness: float,
                   link: int, point: np.ndarray, damping: float = 0.0) -> None:
        """Pull ``point`` (3,) m on ``link`` of arm ``arm`` towards ``anchor_base`` (3,) m,
        base frame, with ``stiffness`` N/m and ``damping`` N·s/m (Plant.set_spring; a hand
        dragging); None releases it. Re-evaluated at each RK stage."""
        r = self.row(arm)
        f = self._f
        if anchor_base is None:
            f["spring_on"][r] = False
            return
        k = scalar("stiffness", stiffness, nonnegative=True)
        c = scalar("damping", damping, nonnegative=True)
        anchor = vector("anchor_base", anchor_base, 3)
        li = self._link(link, "link")
        pt = vector("point", point, 3)
        f["spring_anchor"][:, r], f["spring_point"][:, r] = anchor, pt
        f["spring_k"][r], f["spring_c"][r], f["spring_link"][r] = k, c, li
        f["spring_on"][r] = True

    def set_wall(self, arm: int, origin_base: np.ndarray | None,
                 normal_base: np.ndarray | None = None, *, stiffness: float = 5000.0,
                 damping: float = 30.0, link: int | None = None,
                 point: np.ndarray | None = None, friction: float = 0.0,
                 size: object = None) -> None:
        """A plane or a box arm ``arm`` can press on (Plant.set_wall); None removes it.

        Args:
            arm: the arm id.
            origin_base: (3,) m, a point of the plane, base frame.
            normal_base: (3,) the plane's normal towards the free side, base frame.
            stiffness: N/m of penetration; damping: N·s/m in contact (never pulls).
            link, point: the contact point (3,) m on the arm (default the end effector;
                a link without a point: its origin).
            friction: μ of its Coulomb friction along the surface (Plant's).
            size: None: the plane; (width, height, thickness) m: a box with its face on
                it, met by the contact point and (no ``link`` nor ``point`` given) every
                ball of the model's collision shapes, as Plant's.
        """
        r = self.row(arm)
        f = self._f
        self._hold = None
        if origin_base is None:
            f["wall_on"][r] = False
            return
        origin, normal, k, c, li, pt = checked_wall(
            origin_base, normal_base, stiffness, damping, link, point, n=self.n,
            tip=np.array(self._tip), link_index=lambda j: self._link(j, "link"))
        f["wall_origin"][:, r] = origin
        f["wall_normal"][:, r] = normal
        f["wall_k"][r], f["wall_c"][r], f["wall_link"][r] = k, c, li
        f["wall_point"][:, r] = pt
        f["wall_mu"][r] = checked_friction(friction)
        box = checked_size(size)
        f["wall_box"][r] = box is not None
        f["wall_balls"][r] = box is not None and link is None and point is None
        across, up = face_axes(normal)
        f["wall_size"][:, r] = (0.0, 0.0, 0.0) if box is None else box
        f["wall_across"][:, r], f["wall_up"][:, r] = across, up
        f["wall_gap"][r] = -np.inf  # (where the point is: computed at the next step)
        f["wall_on"][r] = True

    def clear_forces(self, arm: int | None = None) -> None:
        """Remove the pushes, spring and wall of arm ``arm`` (every arm's when None)."""
        self._hold = None
        if arm is None:
            self._drop_pushes(np.zeros(self._p_row.size, dtype=bool))
            self._f["spring_on"][:] = False
            self._f["wall_on"][:] = False
        else:
            r = self.row(arm)
            self._drop_pushes(self._p_row != r)
            self._f["spring_on"][r] = False
            self._f["wall_on"][r] = False

    def _drop_pushes(self, keep: np.ndarray) -> None:
        self._p_row, self._p_link = self._p_row[keep], self._p_link[keep]
        self._p_force, self._p_point = self._p_force[keep], self._p_point[keep]
        self._p_until = self._p_until[keep]

    def _link(self, link: int, name: str) -> int:
        return index(name, link, self.n)

    # -- stepping ---------------------------------------------------------------------

    def step(self) -> None:
        """Advance every arm one ``dt``: firmware tick, then RK4 (Plant.step, over arms)."""
        s = self._s
        dt = self.dt
        q, qd = s["q"], s["qd"]
        self._tick(q, qd)
        if self._p_row.size:
            self._update_pushes(q)
        deriv = self._derivative(q)
        k1 = deriv(q, qd)
        h = 0.5 * dt
        q2 = q + h * qd
        v2 = qd + h * k1
        k2 = deriv(q2, v2)
        q3 = q + h * v2
        v3 = qd + h * k2
        k3 = deriv(q3, v3)
        q4 = q + dt * v3
        v4 = qd + dt * k3
        k4 = deriv(q4, v4)
        sx = dt / 6.0
        s["q"] = q + sx * (qd + 2.0 * (v2 + v3) + v4)
        s["qd"] = qd + sx * (k1 + 2.0 * (k2 + k3) + k4)
        self._k += 1
        if not np.all(np.isfinite(s["qd"])):
            bad = self._ids[~np.all(np.isfinite(s["qd"]), axis=0)].tolist()
            raise FloatingPointError(f"arms {bad} diverged at t = {self.t:.3f} s")

    def compile(self, timeout: float | None = None) -> bool:
        """Compile this plant's machine code now (its dynamics and link frames, link
        points, the walls' pushes, the firmware tick; each waits up to ``timeout`` s) rather
        than in threads once the class passes FLOAT_ARMS arms: True when all of it runs
        from now on (False without numba; the numpy code gives the same numbers)."""
        return all([self._dyn.compile(timeout), POINTS.wait(timeout),
                    compiled_contact.MACHINE.wait(timeout),
                    compiled_firmware.MACHINE.wait(timeout)])

    def advance_to(self, t: float) -> int:
        """Step until the plant time reaches ``t`` s (to within dt/2); returns the steps."""
        target = scalar("t", t)
        steps = 0
        while (self._k + 0.5) * self.dt <= target:
            self.step()
            steps += 1
        return steps

    def _derivative(self, q0: np.ndarray):  # noqa: ANN202 - a closure over this step
        """qdd(q, qd) (n, N) for this step: duties and pushes held, the rest re-evaluated."""
        s = self._s
        drive = self._dir * s["drive"]
        damp = s["damping"] + self._viscous
        coulomb = self._has_coulomb
        cf, rvs = self._coulomb, self._rvs
        push = s["push_tau"] if self._p_row.size else None
        stops = None
        if self.stops is not None:  # per arm, as Plant: only near a limit this step
            near = (q0 < self._lower + 0.05) | (q0 > self._upper - 0.05)
            if near.any():
                stops = np.any(near, axis=0)
        fd, g, arm = self._dyn.fd, self._gravity, self._armature
        springs = np.flatnonzero(self._f["spring_on"])
        walls = self._near_walls()

        def deriv(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            tau = drive - damp * qd
            if coulomb:
                tau = tau - cf * np.tanh(qd * rvs)
            if stops is not None:
                tau = tau + np.where(stops, self._stop_torques(q, qd), 0.0)
            if push is not None:
                tau = tau + push
            if springs.size:
                tau[:, springs] += self._spring_torques(q[:, springs], qd[:, springs],
                                                        springs)
            if walls.rows.size:
                tau[:, walls.rows] += self._wall_torques(walls, q, qd)[0]
            return fd(q, qd, tau, g, arm)

        return deriv

    def _near_walls(self) -> _WallHold:
        """The walls held at the state now (:class:`_WallHold`): every touch that may be
        within :data:`~armlab.hardware.sim.contact.HOLD_MARGIN_M` of its arm's wall plus
        what the joints' speeds can move it in a step (2 dt · reach · Σ|θ̇|). A wall
        farther off pushes nothing at any of the step's RK4 stages, so leaving it out
        changes no number. Where an arm's touches are, is worked out by forward kinematics
        only when what the joints may have moved them since it was last worked out
        (``wall_gap``, the nearest's distance) could have brought one that close: an arm
        far from its wall costs a few multiplications a step. Worked out once a state:
        the forces read at a step's end (:meth:`wall_forces`) are the next step's start.
        Compiled when every wall is a plane (:meth:`_near_planes`)."""
        hold = self._hold
        if hold is not None and hold.step == self._k:
            return hold
        f, q, qd = self._f, self._s["q"], self._s["qd"]
        w_rows = np.flatnonzero(f["wall_on"])
        n = self.n
        if not w_rows.size:  # (no wall: nothing to work out, a step of a free class)
            self._hold = self._no_walls._replace(step=self._k)
            return self._hold
        asks = compiled_contact.MACHINE.kernel("plane_asks")
        touches = compiled_contact.MACHINE.kernel("plane_touches")
        if (asks is not None and touches is not None
                and not np.any((f["wall_balls"] | f["wall_box"]) & f["wall_on"])):
            return self._held(*self._near_planes(w_rows, asks, touches))
        touch_rows = np.zeros(0, dtype=np.int64)
        cols, depth, nrm = np.zeros((n, 3, 0)), np.zeros(0), np.zeros((3, 0))
        if w_rows.size:
            point = np.linalg.norm(f["wall_point"][:, w_rows], axis=0)
            reach = self._reach + np.where(f["wall_balls"][w_rows],
                                           np.maximum(point, self._box_reach), point)
            travel = 2.0 * self.dt * reach * np.sum(np.abs(qd[:, w_rows]), axis=0)
            gap = f["wall_gap"][w_rows]
            ask = gap < HOLD_MARGIN_M + travel  # may be close: where is it?
            if ask.any():
                asked = w_rows[ask]
                t_rows, t_link, t_point, t_radius = self._touches(asked)
                fr = self._dyn.frames(q[:, asked]).reshape(n, 12, asked.size)
                if t_radius is None:  # one point a row
                    p, t_cols = self._points(fr, t_link, t_point)
                    dist, t_nrm = self._surfaces(p, asked)
                    inside = 0.0 - dist
                    gap[ask] = dist
                else:
                    p, t_cols = self._points(fr[:, :, t_rows], t_link, t_point)
                    dist, t_nrm = self._surfaces(p, asked[t_rows])
                    inside = t_radius - dist
                    starts = np.flatnonzero(np.r_[True, t_rows[1:] != t_rows[:-1]])
                    gap[ask] = np.minimum.reduceat(-inside, starts)
                near = inside > -(HOLD_MARGIN_M + travel[ask][t_rows])
                # (C-ordered once here: the compiled pushes read them at every RK stage)
                touch_rows = asked[t_rows[near]]
                cols = np.ascontiguousarray(t_cols[..., near])
                depth, nrm = inside[near], np.ascontiguousarray(t_nrm[:, near])
            f["wall_gap"][w_rows] = gap - travel  # (at the step's end it is at least this far)
        along = cols[:, 0] * nrm[0] + cols[:, 1] * nrm[1] + cols[:, 2] * nrm[2]
        return self._held(touch_rows, cols, along, depth, nrm)

    def _near_planes(self, w_rows: np.ndarray, asks: Kernel, touches: Kernel
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_near_walls`' touches when every wall is a plane its arm's tip meets,
        compiled (``asks``, ``touches``:
        :func:`~armlab.hardware.families.dynamixel1.compiled_contact.plane_asks` and
        ``plane_touches``, its arithmetic in its order): (rows (P,), Jacobian columns
        (n, 3, P), nᵀJ (n, P), depths (P,), normals (3, P)); the walls' gaps updated."""
        f, n, W = self._f, self.n, w_rows.size
        travel, ask = np.empty(W), np.empty(W, dtype=np.int64)
        asked = asks(
            w_rows, as_input(f["wall_point"]), as_input(self._s["qd"]), float(self._reach), self.dt,
            f["wall_gap"], HOLD_MARGIN_M, travel, ask)
        ask = ask[:asked]
        rows = w_rows[ask]
        if asked:
            fr = self._dyn.frames(self._s["q"][:, rows]).reshape(n, 12, asked)
            p, cols = self._points(fr, f["wall_link"][rows], f["wall_point"][:, rows])
        else:
            p, cols = np.zeros((3, 0)), np.zeros((n, 3, 0))
        touch_rows, depth = np.empty(asked, dtype=np.int64), np.empty(asked)
        t_cols, nrm, along = np.empty((n, 3, asked)), np.empty((3, asked)), np.empty((n, asked))
        near = touches(
            w_rows, ask, as_input(p), as_input(cols), as_input(f["wall_origin"]),
            as_input(f["wall_normal"]),
            travel, HOLD_MARGIN_M, f["wall_gap"], touch_rows, t_cols, depth, nrm, along)
        return (touch_rows[:near], np.ascontiguousarray(t_cols[..., :near]),
                np.ascontiguousarray(along[:, :near]), depth[:near],
                np.ascontiguousarray(nrm[:, :near]))

    def _held(self, touch_rows: np.ndarray, cols: np.ndarray, along: np.ndarray,
              depth: np.ndarray, nrm: np.ndarray) -> _WallHold:
        """The hold of this state's touches near their walls (:meth:`_near_walls`),
        kept for this step."""
        f, q = self._f, self._s["q"]
        single = bool(touch_rows.size < 2 or np.all(touch_rows[1:] != touch_rows[:-1]))
        rows, slot = ((touch_rows, np.arange(touch_rows.size)) if single
                      else np.unique(touch_rows, return_inverse=True))
        mu = f["wall_mu"][touch_rows]
        hold = _WallHold(self._k, rows, touch_rows, slot, single,
                         q[:, touch_rows].copy(), cols, along, depth, nrm,
                         f["wall_k"][touch_rows], f["wall_c"][touch_rows], mu,
                         bool(np.any(mu > 0.0)))
        self._hold = hold
        return hold

    def _touches(self, rows: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """The touches of the walls of arm rows ``rows`` (A,), each row's in Plant's order
        (a plane's: its contact point; a box's: with the balls, :attr:`_box_link`): (their
        places in ``rows`` (T,), links (T,), points (3, T) in the link's frame, radii (T,);
        None: one point a row, T = A)."""
        f = self._f
        balls = f["wall_balls"][rows]
        if not balls.any():
            return np.arange(rows.size), f["wall_link"][rows], f["wall_point"][:, rows], None
        counts = np.where(balls, self._box_link.size, 1)
        at = np.repeat(np.arange(rows.size), counts)
        k = np.arange(at.size) - np.repeat(np.cumsum(counts) - counts, counts)
        ball = balls[at]
        link = np.where(ball, self._box_link[k], f["wall_link"][rows][at])
        point = np.where(ball, self._box_point[:, k], f["wall_point"][:, rows][:, at])
        radius = np.where(ball, self._box_radius[k], 0.0)
        return at, link, point, radius

    def _surfaces(self, p: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(signed distance (T,) m, outward unit normal (3, T)) of points ``p`` (3, T) from
        the walls of arm rows ``rows`` (T,): Plant's
        :func:`~armlab.hardware.sim.contact.surface` per point, its arithmetic in its
        order (a plane: along its normal; a box: to its nearest point outside, out of its
        nearest face inside)."""
        f = self._f
        o, nrm = f["wall_origin"][:, rows], f["wall_normal"][:, rows]
        d0, d1, d2 = p[0] - o[0], p[1] - o[1], p[2] - o[2]
        h = d0 * nrm[0] + d1 * nrm[1] + d2 * nrm[2]
        box = f["wall_box"][rows]
        if not box.any():
            return h, nrm
        ac, up, size = f["wall_across"][:, rows], f["wall_up"][:, rows], f["wall_size"][:, rows]
        x = d0 * ac[0] + d1 * ac[1] + d2 * ac[2]
        y = d0 * up[0] + d1 * up[1] + d2 * up[2]
        z = h + size[2] / 2
        sx, sy, sz = (np.where(c >= 0, 1.0, -1.0) for c in (x, y, z))
        qx, qy, qz = np.abs(x) - size[0] / 2, np.abs(y) - size[1] / 2, np.abs(z) - size[2] / 2
        out = (qx > 0.0) | (qy > 0.0) | (qz > 0.0)
        ox, oy, oz = np.maximum(qx, 0.0) * sx, np.maximum(qy, 0.0) * sy, np.maximum(qz, 0.0) * sz
        far = np.sqrt(ox * ox + oy * oy + oz * oz)
        safe = np.where(out, far, 1.0)
        fx = (qx >= qy) & (qx >= qz)  # inside: out of the nearest face
        fy = ~fx & (qy >= qz)
        fz = ~fx & ~fy
        dist = np.where(out, far, np.where(fx, qx, np.where(fy, qy, qz)))
        lx = np.where(out, ox / safe, np.where(fx, sx, 0.0))
        ly = np.where(out, oy / safe, np.where(fy, sy, 0.0))
        lz = np.where(out, oz / safe, np.where(fz, sz, 0.0))
        normal = np.array([lx * ac[0] + ly * up[0] + lz * nrm[0],
                           lx * ac[1] + ly * up[1] + lz * nrm[1],
                           lx * ac[2] + ly * up[2] + lz * nrm[2]])
        return np.where(box, dist, h), np.where(box, normal, nrm)

    def _wall_torques(self, hold: _WallHold, q: np.ndarray, qd: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """((n, R) J^T F, (R,) N the normal push) of the walls ``hold`` holds, on its R
        arm rows, at (q, qd) (n, N): Plant's :func:`~armlab.hardware.sim.contact.held_push`
        per touch, its sums in its order (the touch depth − nᵀJ (q − q₀) inside, at the
        normal speed nᵀJ q̇; the push max(0, k·depth − c·vₙ), and its friction against
        the sliding J q̇ − vₙ n, the damper FRICTION_DAMPING capped at μ·push), each
        arm's touches added in their order."""
        rows, along = hold.touch_rows, hold.along
        kernel = compiled_contact.MACHINE.kernel("pushes") if hold.single else None
        if kernel is not None:  # (compiled_contact.held_pushes: the same numbers)
            tau, mag = np.empty((self.n, rows.size)), np.empty(rows.size)
            kernel(as_input(q), as_input(qd), rows, as_input(hold.q0), as_input(along),
                   as_input(hold.depth), as_input(hold.k), as_input(hold.c),
                   as_input(hold.mu), as_input(hold.cols), as_input(hold.normal),
                   hold.rubs, FRICTION_DAMPING, tau, mag)
            return tau, mag
        if self.n_arms > FLOAT_ARMS:
            compiled_contact.MACHINE.start()
        w = qd[:, rows]
        depth = hold.depth - (along * (q[:, rows] - hold.q0)).sum(axis=0)
        vn = (along * w).sum(axis=0)
        mag = np.where(depth > 0.0, np.maximum(0.0, hold.k * depth - hold.c * vn), 0.0)
        tau = along * mag
        if hold.rubs:
            cols, nrm = hold.cols, hold.normal
            slide = (cols * w[:, None, :]).sum(axis=0) - vn * nrm  # (3, R)
            speed = np.sqrt(slide[0] * slide[0] + slide[1] * slide[1] + slide[2] * slide[2])
            cap = np.minimum(hold.mu * mag, FRICTION_DAMPING * speed)
            scale = np.where(speed > 0.0, -cap / np.where(speed > 0.0, speed, 1.0), 0.0)
            r = scale * slide
            tau = tau + (cols[:, 0] * r[0] + cols[:, 1] * r[1] + cols[:, 2] * r[2])
        if hold.single:
            return tau, mag
        by_row, push = np.zeros((self.n, hold.rows.size)), np.zeros(hold.rows.size)
        np.add.at(by_row.T, hold.slot, tau.T)  # (in touch order, as Plant adds them)
        np.add.at(push, hold.slot, mag)
        return by_row, push

    def wall_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """(arm ids (R,), N (R,)): the normal force of each wall near its arm's contact
        point at the state now (Plant.wall_force per arm; an arm not listed: 0). Worked out
        with the next step's hold of its walls, so reading it after every step costs no
        forward kinematics of its own, and reading it again at the same state nothing:
        the same arrays (do not write to them)."""
        hold = self._near_walls()
        kept = self._forces
        if kept is None or kept[0] is not hold:
            mags = (self._wall_torques(hold, self._s["q"], self._s["qd"])[1]
                    if hold.rows.size else np.zeros(0))
            kept = self._forces = (hold, self._ids[hold.rows], mags)
        return kept[1], kept[2]

    def _stop_torques(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """(n, N) joint-stop torques: spring beyond a limit, damping going further."""
        st = self.stops
        assert st is not None
        k, c = st.stiffness, st.damping
        lo, hi = self._lower, self._upper
        below = k * (lo - q) - np.where(qd < 0, c * qd, 0.0)
        above = k * (hi - q) - np.where(qd > 0, c * qd, 0.0)
        return np.where(q < lo, below, np.where(q > hi, above, 0.0))

    def _points(self, fr: np.ndarray, links: np.ndarray, points: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray]:
        """Base-frame positions (3, P) of link points and their Jacobian columns (n, 3, P).

        ``fr`` (n, 12, P): the frames of the P arms (per link R (9), o (3)); ``links`` (P,)
        the link of each point, ``points`` (3, P) in its frame. Column j of point k is
        z_j × (p − o_j) (thesis eq. 3.17) for j <= links[k], zero beyond."""
        P = links.size
        kernel = POINTS.kernel("points")
        if kernel is not None:  # (compiled_dynamics.link_points: the same numbers)
            p, cols = np.empty((3, P)), np.empty((self.n, 3, P))
            kernel(as_input(fr), np.ascontiguousarray(links, dtype=np.int64), as_input(points),
                   self._axes_array, p, cols)
            return p, cols
        if self.n_arms > FLOAT_ARMS:
            POINTS.start()
        one = int(links[0]) if P and bool(np.all(links == links[0])) else None
        lf = fr[one] if one is not None else fr[links, :, np.arange(P)].T  # (12, P)
        px, py, pz = points
        p = np.array([lf[0] * px + lf[1] * py + lf[2] * pz + lf[9],
                      lf[3] * px + lf[4] * py + lf[5] * pz + lf[10],
                      lf[6] * px + lf[7] * py + lf[8] * pz + lf[11]])
        cols = np.zeros((self.n, 3, P))
        for j in range(self.n if one is None else one + 1):  # (one link: no joint past it)
            a0, a1, a2 = self._axes[j]
            b = fr[j]
            z0 = b[0] * a0 + b[1] * a1 + b[2] * a2
            z1 = b[3] * a0 + b[4] * a1 + b[5] * a2
            z2 = b[6] * a0 + b[7] * a1 + b[8] * a2
            rx, ry, rz = p[0] - b[9], p[1] - b[10], p[2] - b[11]
            c = cols[j]
            c[0], c[1], c[2] = z1 * rz - z2 * ry, z2 * rx - z0 * rz, z0 * ry - z1 * rx
            if one is None:
                c[:, links < j] = 0.0
        return p, cols

    def _spring_torques(self, q: np.ndarray, qd: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """(n, R) J^T F of the springs of the arm rows ``rows`` at (q, qd) (n, R)
        (Plant._field_torques' spring per arm: k (anchor − p) − c v)."""
        f = self._f
        fr = self._dyn.frames(q).reshape(self.n, 12, rows.size)
        p, cols = self._points(fr, f["spring_link"][rows], f["spring_point"][:, rows])
        v = np.einsum("jrp,jp->rp", cols, qd)  # (3, R) the point's velocity
        force = f["spring_k"][rows] * (f["spring_anchor"][:, rows] - p) - f["spring_c"][rows] * v
        return np.einsum("jrp,rp->jp", cols, force)

    def _update_pushes(self, q: np.ndarray) -> None:
        """Drop expired pushes; J^T F of the rest at the step's start (held over the step).

        Per push (P of them, on the arms' rows ``_p_row``): the point's base-frame position
        p = R_link · point + o_link and, for every joint j <= link, the column
        z_j × (p − o_j) of its Jacobian (thesis eq. 3.17), dotted with F; the columns of
        one arm's pushes add up in the order they were given (as Plant's loop)."""
        now = self.t
        keep = self._p_until > now + 1e-12
        if not keep.all():
            self._drop_pushes(keep)
        n_arms = q.shape[1]
        if not self._p_row.size:
            self._s["push_tau"] = np.zeros_like(q)
            return
        rows = self._p_row
        fr = self._dyn.frames(q[:, rows]).reshape(self.n, 12, rows.size)  # R (9), o (3)
        _, cols = self._points(fr, self._p_link, self._p_point.T)
        f0, f1, f2 = self._p_force.T
        tau = np.empty_like(q)
        for j in range(self.n):
            contrib = cols[j, 0] * f0 + cols[j, 1] * f1 + cols[j, 2] * f2
            tau[j] = np.bincount(rows, weights=contrib, minlength=n_arms)  # in push order
        self._s["push_tau"] = tau

    def _tick(self, q: np.ndarray, qd: np.ndarray) -> None:
        """One firmware tick of every servo (ServoModel.update over (n, N); thesis §2.3):
        compiled (:mod:`~armlab.hardware.families.dynamixel1.compiled_firmware`) once it
        is (past FLOAT_ARMS arms it is compiled in a thread), numpy until then."""
        kernel = compiled_firmware.MACHINE.kernel("tick")
        if kernel is not None:
            self._tick_compiled(kernel, q, qd)
            return
        if self.n_arms > FLOAT_ARMS:
            compiled_firmware.MACHINE.start()
        s, r, dt = self._s, self._r, self.dt
        angle = self._dir * q
        velocity = self._dir * qd
        s["velocity"] = velocity
        present = np.rint(512.0 + angle * self._cpr)
        present = clamp(present, 0.0, 1023.0).astype(np.int64)
        s["present"] = present
        present_f = present.astype(float)
        torque_limit = r["torque_limit"] & 0x3FF
        shutdown, overload, stall = s["shutdown"], s["overload"], s["stall"]
        te = r["torque_enable"] != 0
        if shutdown.any():
            recovered = shutdown & (torque_limit > 0) & te
            if recovered.any():  # Torque Limit and Torque Enable written again
                shutdown = shutdown & ~recovered
                overload = overload & ~recovered
                stall = np.where(recovered, 0.0, stall)
        enabled = te & ~shutdown
        sp = np.where(enabled & ~s["enabled"], present_f, s["setpoint"])
        cw, ccw = r["cw_angle_limit"] & 0x3FF, r["ccw_angle_limit"] & 0x3FF
        goal = r["goal_position"] & 0x3FF
        wheel = (cw == 0) & (ccw == 0)
        # joint mode: the set-point moves towards the goal at Moving Speed
        target = np.where(goal < cw, cw, np.where(goal > ccw, ccw, goal)).astype(float)
        raw_speed = r["moving_speed"] & 0x3FF
        step = raw_speed * self._cpsu * dt
        up, down = sp + step, sp - step
        moved = np.where(sp < target, np.minimum(up, target), np.maximum(down, target))
        moved = np.where(sp == target, sp, moved)
        sp = np.where(~enabled, present_f, np.where(raw_speed == 0, target, moved))
        # the compliance curve (armlab.hardware.families.dynamixel1.firmware.compliance_duty)
        rsp = np.rint(sp).astype(np.int64)
        error = rsp - present
        pos = error > 0
        margin = np.where(pos, r["ccw_compliance_margin"], r["cw_compliance_margin"])
        slope = np.where(pos, r["ccw_compliance_slope"], r["cw_compliance_slope"])
        err = np.abs(error)
        punch = np.minimum(r["punch"], torque_limit)
        level = punch + (err - margin) * (torque_limit - punch) / _SLOPES[slope & 0xFF]
        duty = np.minimum(level, torque_limit) / 1023.0
        duty = np.where(rsp < present, -duty, duty)
        on = enabled & (torque_limit > 0) & (err > margin)
        duty = np.where(on, duty, 0.0)
        moving = (sp != target) | (np.abs(velocity) > self._speed_unit)
        angle_error = ~((cw <= goal) & (goal <= ccw))
        if wheel.any():  # wheel mode: Moving Speed is the PWM duty
            wspeed = r["moving_speed"] & 0x7FF
            wduty = np.minimum(wspeed & 0x3FF, torque_limit) / 1023.0
            wduty = np.where(wspeed & DIRECTION_BIT != 0, -wduty, wduty)
            duty = np.where(wheel, np.where(enabled, wduty, 0.0), duty)
            sp = np.where(wheel, present_f, sp)
            moving = np.where(wheel, wspeed & 0x3FF != 0, moving)
            angle_error = angle_error & ~wheel
        # overload: full duty (at Torque Limit) without moving for overload_time
        full = (torque_limit > 0) & (np.abs(duty) * 1023.0 >= torque_limit - 0.5)
        check = full | (stall != 0.0)
        if check.any():
            stall = np.where(check, np.where(full & (np.abs(velocity) < self._stall_speed),
                                             stall + dt, 0.0), stall)
            overload = np.where(check, shutdown | (stall > self._overload_time), overload)
            trip = check & overload & ~shutdown & (r["alarm_shutdown"] & ERROR_OVERLOAD != 0)
            if trip.any():  # Alarm Shutdown: torque off, Torque Limit 0 until written again
                shutdown = shutdown | trip
                r["torque_enable"] = np.where(trip, 0, r["torque_enable"])
                r["torque_limit"] = np.where(trip, 0, r["torque_limit"])
                enabled = enabled & ~trip
                duty = np.where(trip, 0.0, duty)
        s["shutdown"], s["overload"], s["stall"] = shutdown, overload, stall
        s["enabled"], s["setpoint"], s["duty"] = enabled, sp, duty
        s["moving"], s["angle_error"] = moving, angle_error
        nz = duty != 0.0
        s["drive"] = np.where(nz, duty * self._stall_torque, 0.0)
        s["damping"] = np.where(nz, self._backemf, 0.0)

    def _tick_compiled(self, kernel: Kernel, q: np.ndarray, qd: np.ndarray) -> None:
        """:meth:`_tick`'s numbers, by the compiled loop over every servo."""
        s, r = self._s, self._r
        regs = np.stack([r[name] for name in _TICK_REGISTERS])
        shape = q.shape
        out: dict[str, np.ndarray] = {name: np.empty(shape, dtype=_STATE[name])
                                      for name in _TICK_OUTPUTS}
        shutdown, overload, stall = s["shutdown"].copy(), s["overload"].copy(), s["stall"].copy()
        kernel(as_input(q), as_input(qd), regs, shutdown, overload, stall,
               np.ascontiguousarray(s["enabled"]), as_input(s["setpoint"]), self._joint,
               _SLOPES, self.dt, *out.values())
        s.update(out)
        s["shutdown"], s["overload"], s["stall"] = shutdown, overload, stall
        r["torque_limit"], r["torque_enable"] = regs[0], regs[1]  # (an overload's shutdown)

    # -- what the servos report ----------------------------------------------------------

    def present_position(self) -> np.ndarray:
        """(N, n) Present Position words 0..1023 (the last tick's 10-bit reading)."""
        return self._s["present"].T.copy()

    def present_speed(self) -> np.ndarray:
        """(N, n) Present Speed words (0.111 rpm units, bit 10 = CW)."""
        return signed_words(self._s["velocity"] / self._speed_unit).T

    def present_load(self) -> np.ndarray:
        """(N, n) Present Load words (the duty, 0..1023 of full torque, bit 10 = CW)."""
        return signed_words(self._s["duty"] * 1023.0).T

    def error(self) -> np.ndarray:
        """(N, n) status error bytes (angle limit, overload)."""
        return (np.where(self._s["angle_error"], ERROR_ANGLE_LIMIT, 0)
                | np.where(self._s["overload"], ERROR_OVERLOAD, 0)).T

    def moving(self) -> np.ndarray:
        """(N, n) Moving register (0/1)."""
        return self._s["moving"].astype(np.int64).T

    def report_words(self, arm: int) -> ReportWords:
        """What a controller reads of arm ``arm`` each period: per joint its Present
        Position, Present Speed and Present Load words, status error byte and Torque Enable
        (the fields of :meth:`reports` the loop needs, without building ServoReports)."""
        r = self.row(arm)
        s = self._s
        # the column as Python numbers: for n servos, scalar arithmetic beats numpy's
        # per-call cost (signed_word rounds as signed_words does)
        velocity, duty = s["velocity"][:, r].tolist(), s["duty"][:, r].tolist()
        angle_error, overload = s["angle_error"][:, r].tolist(), s["overload"][:, r].tolist()
        return ReportWords(
            position=s["present"][:, r].tolist(),
            speed=[signed_word(v / u) for v, u in zip(velocity, self._speed_units, strict=True)],
            load=[signed_word(d * 1023.0) for d in duty],
            error=[(ERROR_ANGLE_LIMIT if a else 0) | (ERROR_OVERLOAD if o else 0)
                   for a, o in zip(angle_error, overload, strict=True)],
            torque_enable=self._r["torque_enable"][:, r].tolist())

    def reports(self, arm: int) -> tuple[ServoReport, ...]:
        """Arm ``arm``'s servo reports in joint order, as ``Plant.reports()`` gives them
        (its column only: O(n), whatever N)."""
        w = self.report_words(arm)
        r = self.row(arm)
        moving, limit = self._s["moving"][:, r].tolist(), self._r["torque_limit"][:, r].tolist()
        return tuple(ServoReport(
            position=w.position[i], speed=w.speed[i], load=w.load[i], voltage=self._voltage[i],
            temperature=self._temperature[i], moving=int(moving[i]), error=w.error[i],
            torque_enable=w.torque_enable[i], torque_limit=limit[i]) for i in range(self.n))
