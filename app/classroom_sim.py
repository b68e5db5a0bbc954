"""A class of private simulated arms: one :class:`BatchedPlant` + one :class:`BatchedController`.

The glue between the batched controller (``control.batched``) and the batched plant
(``hardware.batched_plant``); it lives in ``app`` because it joins the two (control never
imports hardware, hardware imports only ``control.backend`` of control). It does what
:class:`control.loop.ControlLoop` over a :class:`hardware.sim_backend.SimBackend` does for
one arm, for N arms in one pass. One :meth:`ClassroomSim.step` is one
control period T of every arm (``ControlLoop._period``):

1. the plant integrates up to the period's start (``SimBackend.sync``: T / dt plant steps);
2. the servos' raw words are decoded (``SimBackend.read``: 10-bit position, Present
   Speed, Present Load as a fraction of the stall torque), (N, n) each;
3. an arm's first period (or a :meth:`reset`) holds where it is, torque on;
4. τ_dyn = RNEA(q, qd, θ̈_ref) (thesis eq. 2.41–2.50) and the compliance law
   (eq. 2.23, 2.7, 2.6/2.26/2.20) of every arm with its own gains;
5. the goals are clamped into the joint limits and written as Goal Position / Moving
   Speed words (``SimBackend.write``).

Each arm holds a command ``θ_cmd`` (:meth:`set_command`; θ̇_cmd = θ̈_cmd = 0), as the
loop's hold (no trajectories or targets here). The loop's run-time checks become a
per-arm fault: a servo error, a non-finite goal, a reference acceleration above
``max_accel``, a reference speed at the joint's limit or a joint lagging its reference by
more than ``max_lag`` for ``lag_time`` switches that arm's torque off (``faulted``,
:meth:`fault` says why) until :meth:`reset`. Not batched: trajectories, RMRC targets,
recording, e-stop of the whole class.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from control.batched import (
    BatchedController,
    BatchedGains,
    BatchedState,
    newton_euler_torques,
)
from control.loop import DEFAULT_MAX_SPEED
from control.params import DEFAULT, Params
from hardware.batched_plant import BatchedPlant
from hardware.servo import ServoParams
from hardware.servo_spec import DIRECTION_BIT, RX24F, ServoSpec
from hardware.sim_backend import thesis_registers
from kinematics.model import SerialChain
from kinematics.validate import vector


class ClassroomSim:
    """N private arms of ``model`` (one servo ``spec`` per joint), each with its own gains.

    Args:
        model: the arm (e.g. ``receptionist_arm``).
        spec: every joint's servo (default RX-24F).
        dt: plant step, s. period: control period T, s (a multiple of dt; default the
            default Params' 16 ms); every arm's Params must have it.
        params: ServoParams of every joint.
        max_accel, max_lag, lag_time: the run-time checks, as ControlLoop's.
    """

    def __init__(self, model: SerialChain, spec: ServoSpec = RX24F, *, dt: float = 1e-3,
                 period: float = DEFAULT.period, params: ServoParams | None = None,
                 max_accel: float = 500.0, max_lag: float = 0.5,
                 lag_time: float = 0.5) -> None:
        n = model.n
        self.model = model
        self.spec = spec
        self.plant = BatchedPlant(model, spec, dt=dt, params=params)
        self.period = float(period)
        lo_s, hi_s = spec.raw_to_position(0), spec.raw_to_position(1023)
        self.lower = np.maximum(model.lower, lo_s)  # SimBackend's limits, then the loop's
        self.upper = np.minimum(model.upper, hi_s)
        vel = np.array([j.velocity for j in model.joints], dtype=float)
        self.max_speed = np.where(np.isfinite(vel) & (vel > 0), vel, DEFAULT_MAX_SPEED)
        self.max_accel = float(max_accel)
        self.max_lag = float(max_lag)
        self.lag_time = float(lag_time)
        self.controller = BatchedController(self.lower, self.upper, self.max_speed)
        self._ends = [sorted(spec.position_to_raw(x) for x in (self.lower[i], self.upper[i]))
                      for i in range(n)]
        self._params: list[Params] = []
        self._gains = BatchedGains.of([])
        self.state = BatchedState.at_rest(np.zeros((0, n)))
        self._cmd = np.zeros((0, n))
        self._started = np.zeros(0, dtype=bool)
        self._commanded = np.zeros(0, dtype=bool)  # a command given before the first period
        self.faulted = np.zeros(0, dtype=bool)  #: (N,) torque off by a fault until a reset
        self._why: list[str] = []
        self._lag = np.zeros(0)  # s each arm has lagged its reference by more than max_lag
        self._k = 0

    @property
    def t(self) -> float:
        """Loop time k·T, s."""
        return self._k * self.period

    @property
    def n_arms(self) -> int:
        """N."""
        return self.plant.n_arms

    def add_arm(self, *, q0: np.ndarray | None = None, params: Params = DEFAULT) -> int:
        """A student's arm at ``q0`` (n,) (default neutral), servos as SimBackend sets them
        (thesis registers, torque on), holding where it is from its first period. Returns
        its id (the plant's)."""
        n = self.model.n
        self._check_params(params)
        q = self.model.neutral() if q0 is None else vector("q0", q0, n)
        regs = [thesis_registers(self.spec, goal=self.spec.position_to_raw(
            float(np.clip(q[i], self.lower[i], self.upper[i]))), cw_limit=self._ends[i][0],
            ccw_limit=self._ends[i][1]) for i in range(n)]
        arm = self.plant.add_arm(q0=q, registers=regs)
        self._params.append(params)
        self._gains = BatchedGains.of(self._params)
        self.state = self.state.append(BatchedState.at_rest(q.reshape(1, n)))
        self._cmd = np.vstack([self._cmd, q.reshape(1, n)])
        self._started = np.append(self._started, False)
        self._commanded = np.append(self._commanded, False)
        self.faulted = np.append(self.faulted, False)
        self._why.append("")
        self._lag = np.append(self._lag, 0.0)
        return arm

    def remove_arm(self, arm: int) -> None:
        """A student leaves: their arm goes; the others go on untouched."""
        r = self.plant.row(arm)
        self.plant.remove_arm(arm)
        del self._params[r]
        self._gains = BatchedGains.of(self._params)
        self.state = self.state.delete(r)
        self._cmd = np.delete(self._cmd, r, axis=0)
        self._started = np.delete(self._started, r)
        self._commanded = np.delete(self._commanded, r)
        self.faulted = np.delete(self.faulted, r)
        del self._why[r]
        self._lag = np.delete(self._lag, r)

    def set_params(self, arm: int, params: Params) -> None:
        """Arm ``arm``'s gains from the next period on."""
        self._check_params(params)
        self._params[self.plant.row(arm)] = params
        self._gains = BatchedGains.of(self._params)

    def set_command(self, arm: int, q_cmd: np.ndarray) -> None:
        """Arm ``arm`` holds ``q_cmd`` (n,) rad (clamped into the limits) from now on (given
        before the arm's first period, it replaces the hold of where the arm starts)."""
        r = self.plant.row(arm)
        self._cmd[r] = np.clip(vector("q_cmd", q_cmd, self.model.n), self.lower, self.upper)
        self._commanded[r] = True

    def reset(self, arm: int) -> None:
        """Arm ``arm`` holds where it is at its next period, torque on, fault cleared."""
        r = self.plant.row(arm)
        self._started[r] = False
        self._commanded[r] = False
        self.faulted[r] = False

    def _check_params(self, params: Params) -> None:
        if not isinstance(params, Params):
            raise ValueError(f"params must be a control.params.Params, got "
                             f"{type(params).__name__}")
        if params.period != self.period:
            raise ValueError(f"params: period must be the class's {self.period:g} s, "
                             f"got {params.period:g}")

    # -- one period ---------------------------------------------------------------------

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position rad, velocity rad/s, load N·m), each (N, n), decoded from the raw
        words as SimBackend.read decodes them."""
        s = self.spec
        pos = (self.plant.present_position() - 512) * s.position_unit
        spd = self.plant.present_speed()
        vel = np.where(spd & DIRECTION_BIT, -(spd & 0x3FF), spd & 0x3FF) * s.speed_unit
        ld = self.plant.present_load()
        load = np.where(ld & DIRECTION_BIT, -(ld & 0x3FF), ld & 0x3FF) / 1023.0 * s.stall_torque
        d = np.array(self.plant.directions)
        return d * pos, d * vel, d * load

    def write(self, position: np.ndarray, speed: np.ndarray, rows: np.ndarray) -> None:
        """Goals (len(rows), n) rad and speeds rad/s -> Goal Position / Moving Speed words of
        ``rows`` (SimBackend.write_checked: rounded, 1..1023 speed units)."""
        s = self.spec
        d = np.array(self.plant.directions)
        goal = np.clip(np.rint(512 + d * position / s.position_unit), 0, 1023).astype(np.int64)
        spd = np.clip(np.rint(np.abs(speed) / s.speed_unit), 1, 1023).astype(np.int64)
        self.plant.write_registers("goal_position", goal, rows)
        self.plant.write_registers("moving_speed", spd, rows)

    def step(self) -> None:
        """One control period T of every arm (see the module docstring), then t += T."""
        self.plant.advance_to(self.t)
        q, qd, load = self.read()
        fresh = ~self._started
        if fresh.any():  # hold where it is, LPF primed on the load, torque on
            rows = np.flatnonzero(fresh)
            hold = np.clip(q[rows], self.lower, self.upper)
            self.state.put(rows, BatchedState.at_rest(hold, load[rows]))
            self._cmd[rows] = np.where(self._commanded[rows, None], self._cmd[rows], hold)
            limit = self.plant.register("torque_limit")[rows]  # SimBackend.set_torque(True)
            self.plant.write_registers("torque_limit", np.where(limit == 0, 1023, limit), rows)
            self.plant.set_torque_enable(True, rows)
            self._lag[rows] = 0.0
            self._started[rows] = True
        # a servo error (overload...) stops an arm, except in the period that (re)starts it
        errors = np.any(self.plant.error() != 0, axis=1) & ~fresh & ~self.faulted
        if errors.any():
            self._fail(np.flatnonzero(errors), "a servo reports an error (overload?)")
        live = np.flatnonzero(~self.faulted)
        if live.size:
            self._control(live, q, qd, load)
        self._k += 1

    def _control(self, rows: np.ndarray, q: np.ndarray, qd: np.ndarray,
                 load: np.ndarray) -> None:
        st = self.state
        all_rows = rows.size == self.n_arms
        sub = st if all_rows else BatchedState(**{k: v[rows] for k, v in vars(st).items()})
        gains = self._gains if all_rows else BatchedGains(
            **{k: (v[rows] if isinstance(v, np.ndarray) else v)
               for k, v in vars(self._gains).items()})
        q, qd, load = q[rows], qd[rows], load[rows]
        tau_dyn = newton_euler_torques(self.model, q, qd, sub.qdd_ref)
        zero = np.zeros_like(q)
        q_ref, qd_ref = self.controller.step(gains, sub, self._cmd[rows], zero, zero, q, qd,
                                             load, tau_dyn)
        if not all_rows:
            st.put(rows, sub)
        # ControlLoop's run-time checks, per arm
        bad = ~(np.all(np.isfinite(q_ref), axis=1) & np.all(np.isfinite(qd_ref), axis=1)
                & np.all(np.isfinite(sub.qdd_ref), axis=1))
        self._fail(rows[bad], "the controller produced a non-finite goal")
        hard = np.max(np.abs(np.nan_to_num(sub.qdd_ref, nan=np.inf)), axis=1) > self.max_accel
        self._fail(rows[hard & ~bad], f"reference acceleration above {self.max_accel:g} rad/s²")
        bad |= hard
        fast = np.any(np.abs(qd_ref) >= self.max_speed * (1.0 - 1e-9), axis=1)
        self._fail(rows[fast & ~bad], "reference speed at the servo's limit")
        bad |= fast
        lagging = np.any(np.abs(q_ref - q) > self.max_lag, axis=1)
        self._lag[rows] = np.where(lagging & ~bad, self._lag[rows] + self.period, 0.0)
        late = self._lag[rows] > self.lag_time
        self._fail(rows[late], f"a joint more than {np.degrees(self.max_lag):.0f}° from its "
                   f"reference for {self.lag_time:g} s")
        ok = ~(bad | late)
        goal = np.clip(q_ref[ok], self.lower, self.upper)
        speed = np.minimum(np.abs(qd_ref[ok]), self.max_speed)
        self.write(goal, speed, rows[ok])

    def _fail(self, rows: np.ndarray, why: str) -> None:
        """The loop's fault for arm rows ``rows``: torque off, no more goals until a reset."""
        if rows.size:
            self.faulted[rows] = True
            for r in rows.tolist():
                self._why[r] = why
            self.plant.set_torque_enable(False, rows)

    def fault(self, arm: int) -> str | None:
        """Why arm ``arm`` stopped (torque off until :meth:`reset`), or None."""
        r = self.plant.row(arm)
        return self._why[r] if self.faulted[r] else None

    def gains(self, arm: int) -> Params:
        """Arm ``arm``'s Params."""
        return self._params[self.plant.row(arm)]

    def params_list(self) -> Sequence[Params]:
        """Every arm's Params in row order."""
        return tuple(self._params)
