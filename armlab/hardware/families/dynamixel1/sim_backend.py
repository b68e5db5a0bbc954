"""``SimBackend``: the :class:`armlab.control.backend.Backend` protocol over a simulated plant.

The controller sees exactly what it would see on a real bus: goals are turned into
raw Goal Position / Moving Speed registers, readings come back as the servos report
them (10-bit positions, 0.111 rpm speed units, Present Load as 0.1 % of full torque)
and are decoded with the same :class:`armlab.hardware.servos.servo_spec.ServoSpec` conversions.
The plant's ground truth stays available as ``.plant`` for tests and plots.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from armlab.control.backend import (
    BackendError,
    GoalLimits,
    GripperState,
    JointState,
    WallSetting,
)
from armlab.hardware.backends.gripper import GripperHolder, GripperServo
from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.firmware import ServoRegisters, ServoReport
from armlab.hardware.families.dynamixel1.table import (
    THESIS_COMPLIANCE_MARGIN,
    THESIS_COMPLIANCE_SLOPE,
)
from armlab.hardware.servos.servo_spec import COUNTS, RX24F, ServoSpec, TurnEncoder
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import scalar, vector


def thesis_registers(spec: ServoSpec, *, goal: int, cw_limit: int, ccw_limit: int,
                     torque_on: bool = True) -> ServoRegisters:
    """Registers as the thesis configures each servo (§2.3): compliance margin 0, slope 64
    (0x40), torque limit and max torque 1023, factory punch 32, speed control off."""
    margin, slope = THESIS_COMPLIANCE_MARGIN, THESIS_COMPLIANCE_SLOPE
    return ServoRegisters(
        torque_enable=int(torque_on), cw_compliance_margin=margin, ccw_compliance_margin=margin,
        cw_compliance_slope=slope, ccw_compliance_slope=slope, goal_position=goal,
        moving_speed=0, torque_limit=1023, max_torque=1023, punch=32, cw_angle_limit=cw_limit,
        ccw_angle_limit=ccw_limit,
    )


def servo_limits(model: SerialChain, specs: Sequence[ServoSpec], directions: Sequence[float],
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) (n,) rad: the model's joint limits intersected with each servo's 300°
    range (seen through its direction). ValueError when a joint's do not overlap."""
    lower, upper = [], []
    for i, (spec, d) in enumerate(zip(specs, directions, strict=True)):
        lo_s, hi_s = spec.raw_to_position(0), spec.raw_to_position(1023)
        lo_j, hi_j = (lo_s, hi_s) if d > 0 else (-hi_s, -lo_s)
        lower.append(max(float(model.lower[i]), lo_j))
        upper.append(min(float(model.upper[i]), hi_j))
    lo, hi = np.array(lower), np.array(upper)
    if np.any(lo > hi):
        raise ValueError("a joint's limits do not overlap its servo's 300° range")
    return lo, hi


def turn_limits(model: SerialChain, spec: TurnEncoder, directions: Sequence[float]
                ) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) (n,) rad: the model's joint limits inside the servos' one turn of
    position control (0..4095 of a 12-bit encoder, the X-series' and Feetech STS's, seen
    through each direction)."""
    lo_s, hi_s = spec.raw_to_position(0), spec.raw_to_position(COUNTS - 1)
    lower = [max(float(model.lower[i]), lo_s if d > 0 else -hi_s)
             for i, d in enumerate(directions)]
    upper = [min(float(model.upper[i]), hi_s if d > 0 else -lo_s)
             for i, d in enumerate(directions)]
    return np.array(lower), np.array(upper)


def start_words(specs: Sequence[ServoSpec | TurnEncoder], directions: Sequence[float],
                lower: np.ndarray, upper: np.ndarray, q0: np.ndarray,
                ) -> list[tuple[int, int, int]]:
    """Per joint its servo's raw (goal, low limit, high limit) as a simulated arm starts:
    the position limits at ``lower``/``upper`` (n,) rad and the goal at ``q0`` (n,) rad
    clamped into them, through each direction."""
    words = []
    for i, (spec, d) in enumerate(zip(specs, directions, strict=True)):
        ends = sorted(spec.position_to_raw(d * x) for x in (lower[i], upper[i]))
        goal = spec.position_to_raw(d * float(np.clip(q0[i], lower[i], upper[i])))
        words.append((goal, ends[0], ends[1]))
    return words


def sim_registers(specs: Sequence[ServoSpec], directions: Sequence[float], lower: np.ndarray,
                  upper: np.ndarray, q0: np.ndarray, *, torque_on: bool = True,
                  ) -> list[ServoRegisters]:
    """Per joint the registers a simulated arm starts with: :func:`thesis_registers` with the
    CW/CCW Angle Limits at ``lower``/``upper`` (n,) rad and the goal at ``q0`` (n,) rad
    clamped into them (:func:`start_words`)."""
    return [thesis_registers(spec, goal=goal, cw_limit=lo, ccw_limit=hi, torque_on=torque_on)
            for spec, (goal, lo, hi) in zip(specs, start_words(specs, directions, lower, upper,
                                                                 q0), strict=True)]


def decode_reports(reports: Sequence[ServoReport], specs: Sequence[ServoSpec],
                   directions: Sequence[float], t: float) -> JointState:
    """The servos' raw reports (one per joint) as the controller sees them: positions rad,
    speeds rad/s, loads N·m (n,) each, through each servo's conversions and direction."""
    pos, vel, load = [], [], []
    for r, spec, d in zip(reports, specs, directions, strict=True):
        pos.append(d * spec.raw_to_position(r.position))
        vel.append(d * spec.raw_to_present_speed(r.speed))
        load.append(d * spec.raw_to_load(r.load))
    return JointState(t=t, position=np.array(pos), velocity=np.array(vel),
                      load=np.array(load), errors=tuple(r.error for r in reports),
                      torque_on=tuple(bool(r.torque_enable) for r in reports),
                      alarms=tuple(p1.error_names(r.error) for r in reports))


def goal_positions(specs: Sequence[ServoSpec | TurnEncoder], directions: Sequence[float],
                   position: np.ndarray) -> list[int]:
    """Checked goals (n,) rad as Goal Position words, through each direction."""
    return [spec.position_to_raw(d * x) for spec, d, x in
            zip(specs, directions, np.asarray(position, dtype=float).tolist(), strict=True)]


def moving_speeds(specs: Sequence[ServoSpec], speed: np.ndarray) -> list[int]:
    """Speeds (n,) rad/s as Moving Speed words (magnitudes, 1..1023 units: never 0, "no
    limit")."""
    return [spec.speed_to_raw(abs(x))
            for spec, x in zip(specs, np.asarray(speed, dtype=float).tolist(), strict=True)]


def raw_goals(specs: Sequence[ServoSpec], directions: Sequence[float], position: np.ndarray,
              speed: np.ndarray) -> tuple[list[int], list[int]]:
    """Checked goals (n,) rad and speeds (n,) rad/s as Goal Position and Moving Speed words
    (speeds as magnitudes, 1..1023 units: never 0, "no limit")."""
    return goal_positions(specs, directions, position), moving_speeds(specs, speed)


class SimBackend(GoalLimits):
    """A simulated arm of Dynamixel servos behind the ``Backend`` (and ``Pushable``) protocol.

    Args:
        model: the serial chain.
        specs: one :class:`ServoSpec` per joint, or one for all (default RX-24F each).
        dt: plant step and servo tick, s.
        q0: (n,) initial joint positions (default neutral); the servos start holding it.
        directions: (n,) +1/-1 servo-to-joint signs (default +1).
        params: :class:`ServoParams` for all servos or per servo.
        torque_on: start with torque enabled (True: the arm holds its pose at once).

    Joint limits (``lower``/``upper``) are the model's limits intersected with the
    servos' 300° range; the servos' CW/CCW Angle Limit registers are set to them.
    Methods are safe to call from several threads (one lock).
    """

    def __init__(self, model: SerialChain, *, specs: ServoSpec | Sequence[ServoSpec] | None = None,
                 dt: float = 1e-3, q0: np.ndarray | Sequence[float] | None = None,
                 directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 torque_on: bool = True) -> None:
        n = model.n
        if specs is None or isinstance(specs, ServoSpec):
            spec_list = [specs or RX24F] * n
        else:
            spec_list = list(specs)
        if len(spec_list) != n:
            raise ValueError(f"specs must name {n} servos, got {len(spec_list)}")
        dirs = [1.0] * n if directions is None else [float(d) for d in directions]
        self._lower, self._upper = servo_limits(model, spec_list, dirs)
        q_start = model.neutral() if q0 is None else vector("q0", q0, n)
        regs = sim_registers(spec_list, dirs, self._lower, self._upper, q_start,
                             torque_on=torque_on)
        self._init_plant(Plant(model, spec_list, dt=dt, q0=q0, directions=dirs, params=params,
                               registers=regs), spec_list, dirs)
        self._torque_limits = tuple(r.torque_limit for r in regs)

    def _init_plant(self, plant: Plant, specs: Sequence, directions: Sequence[float]) -> None:
        """Hold ``plant``, its servos' datasheets and directions (the end of opening)."""
        self.plant = plant
        self.specs = tuple(specs)
        self.directions = tuple(directions)
        self._lock = threading.RLock()
        self._closed = False

    # -- Backend protocol ---------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.plant.n

    def sync(self, t: float) -> None:
        """Integrate the plant up to ``t`` s (no-op when already there)."""
        t = scalar("t", t)
        with self._lock:
            self._check_open()
            self.plant.advance_to(t)

    def read(self) -> JointState:
        """Every joint as its servo reports it (decoded raw words, quantised)."""
        with self._lock:
            self._check_open()
            reports = self.plant.reports()
            t = self.plant.t
        return decode_reports(reports, self.specs, self.directions, t)

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Goal positions (n,) rad and moving speeds (n,) rad/s -> Goal Position/Moving Speed.

        Positions are clamped into [lower, upper]; speeds are magnitudes, sent as
        1..1023 units (never 0, which would mean "no speed limit"). NaN/inf or a wrong
        shape raise ValueError and nothing is written.
        """
        self.write_checked(*self.checked_goal(position, speed))

    def write_checked(self, position: np.ndarray, speed: np.ndarray) -> None:
        """:meth:`write` of goals already checked and clamped (``checked_goal``), e.g. a
        slice of a bigger backend's goals: Goal Position and the family's speed word
        (:meth:`_speed_words`, :meth:`_set_speed`) on every servo."""
        goals = goal_positions(self.specs, self.directions, position)
        speeds = self._speed_words(speed)
        with self._lock:
            self._check_open()
            for servo, g, v in zip(self.plant.servos, goals, speeds, strict=True):
                servo.regs.goal_position = g
                self._set_speed(servo.regs, v)

    def _speed_words(self, speed: np.ndarray) -> list[int]:
        """Checked speeds (n,) rad/s as the servos' speed words: Moving Speed
        (:func:`moving_speeds`)."""
        return moving_speeds(self.specs, speed)

    @staticmethod
    def _set_speed(regs: Any, word: int) -> None:
        """Write a servo's speed word ``word`` into its registers ``regs``: Moving Speed."""
        regs.moving_speed = word

    def set_torque(self, on: bool) -> None:
        """Torque Enable on every servo. Switching on also restores a Torque Limit that an
        overload shutdown set to 0 (what a user does to recover a real servo)."""
        with self._lock:
            self._check_open()
            for servo, limit in zip(self.plant.servos, self._torque_limits, strict=True):
                if on and servo.regs.torque_limit == 0:
                    servo.regs.torque_limit = limit
                servo.regs.torque_enable = int(bool(on))

    def estop(self) -> bool:
        """Torque off everywhere now; never raises. Returns True (nothing can be lost)."""
        with self._lock:
            for servo in self.plant.servos:
                servo.regs.torque_enable = 0
        return True

    @property
    def senses_current(self) -> bool:
        """Whether every simulated servo measures its motor current
        (``armlab.control.backend.CurrentSensing``): the XM430/XL330 models do, the RX-24F not."""
        return all(getattr(s, "has_current", False) for s in self.specs)

    def close(self) -> None:
        """Release the backend; later calls raise BackendError (torque left as it is)."""
        with self._lock:
            self._closed = True

    # -- Pushable -----------------------------------------------------------------

    def push(self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float) -> None:
        """Apply ``force`` (3,) N, given in the model's **base frame**, at ``point`` (3,) m in
        link ``link``'s frame for ``duration`` s of simulated time from now."""
        with self._lock:
            self.plant.push(force, link=link, point=point, duration=duration)

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """Pull ``point`` on ``link`` towards ``anchor`` (3,) m, base frame, with ``stiffness``
        N/m; None releases it."""
        with self._lock:
            self.plant.set_spring(anchor, stiffness=stiffness, link=link, point=point)

    def set_wall(self, origin: np.ndarray | None, normal: np.ndarray | None = None, *,
                 stiffness: float, damping: float, friction: float = 0.0,
                 size: tuple[float, float, float] | None = None) -> None:
        """A plane the arm touches (``armlab.control.backend.Touchable``): ``origin`` (3,)
        m on it, ``normal`` (3,) towards the free side, both base frame, with Coulomb
        ``friction`` μ along it, or a box of ``size`` (width, height, thickness) m with
        its face there; the hand's tip and the links' collision shapes touch it; None
        removes it."""
        with self._lock:
            self.plant.set_wall(origin, normal, stiffness=stiffness, damping=damping,
                                friction=friction, size=size)

    def wall_force(self) -> float:
        """N, the wall's normal force on the hand now (the plant's ground truth)."""
        with self._lock:
            return self.plant.wall_force()

    def wall_peak(self) -> float:
        """N, the largest wall force at any plant step since the last call."""
        with self._lock:
            return self.plant.wall_peak()

    def wall_setting(self) -> WallSetting | None:
        """The wall in the plant's world now (None: none)."""
        with self._lock:
            wall, size = self.plant.wall, self.plant.wall_size
        return None if wall is None else WallSetting(*wall, size=size)

    def _check_open(self) -> None:
        if self._closed:
            raise BackendError("the simulated arm is closed; open a new backend")


class GrippedSimBackend(SimBackend, GripperHolder):
    """A simulated arm of servos of one model with a 12-bit encoder, whose gripper may have
    its own servo moving the gripper's load (:func:`armlab.hardware.backends.gripper.
    gripper_plant`) beside the arm: what the X-series and Feetech STS simulations share.
    A subclass opens the arm with :meth:`_open_arm`, sets :attr:`gripper` and
    :attr:`gripper_plant` (None without a gripper) and decodes the reports
    (:meth:`_decode`, :meth:`_decode_gripper`).
    """

    gripper: GripperServo | None = None
    gripper_plant: Plant | None = None

    def _open_arm(self, model: SerialChain, spec: TurnEncoder, *,
                  registers: Callable[..., Any], dt: float, q0: np.ndarray | None,
                  directions: Sequence[float] | None,
                  params: ServoParams | Sequence[ServoParams] | None, torque_on: bool) -> None:
        """The arm's plant: joint limits the model's inside the servos' one turn
        (:func:`turn_limits`), each servo's registers ``registers(spec, goal=,
        min_limit=, max_limit=, torque_on=)`` as the family's backend configures it, its
        Min/Max Position Limit at the joint's limits and its goal at ``q0`` (default
        neutral) clamped into them (:func:`start_words`)."""
        n = model.n
        dirs = [1.0] * n if directions is None else [float(d) for d in directions]
        self._lower, self._upper = turn_limits(model, spec, dirs)
        q_start = model.neutral() if q0 is None else vector("q0", q0, n)
        regs = [registers(spec, goal=goal, min_limit=lo, max_limit=hi, torque_on=torque_on)
                for goal, lo, hi in start_words([spec] * n, dirs, self._lower, self._upper,
                                                q_start)]
        self._init_plant(Plant(model, spec, dt=dt, q0=q0, directions=dirs, params=params,
                               registers=regs), [spec] * n, dirs)

    @property
    def spec(self) -> Any:
        """The servos' datasheet (every joint's and the gripper's)."""
        return self.specs[0]

    def sync(self, t: float) -> None:
        """Integrate the arm (and the gripper) up to ``t`` s."""
        super().sync(t)
        if self.gripper_plant is not None:
            with self._lock:
                self.gripper_plant.advance_to(self.plant.t)

    def read(self) -> JointState:
        """Every joint as its servo reports it (decoded raw values, quantised), the
        gripper's too."""
        with self._lock:
            self._check_open()
            reports = self.plant.reports()
            t = self.plant.t
            grip = None if self.gripper_plant is None else self.gripper_plant.reports()[0]
        state = self._decode(reports, t)
        return state if grip is None else replace(state, gripper=self._decode_gripper(grip))

    def _decode(self, reports: Sequence[Any], t: float) -> JointState:
        """The joints' servos' raw reports at time ``t`` as the controller sees them."""
        raise NotImplementedError

    def _decode_gripper(self, report: Any) -> GripperState:
        """The gripper servo's raw report as the finger's state."""
        raise NotImplementedError

    def set_gripper(self, position: float) -> float:
        """Goal Position of the gripper's servo for the finger at ``position``, clamped
        into its range; returns the clamped goal (ValueError without a gripper)."""
        if self.gripper is None or self.gripper_plant is None:
            raise ValueError("this simulated arm has no gripper servo")
        x, raw = self._gripper_goal_raw(position)
        with self._lock:
            self._check_open()
            self.gripper_plant.servos[0].regs.goal_position = raw
        return x

    def _servos(self) -> tuple:
        """The arm's servo models, then the gripper's."""
        extra = () if self.gripper_plant is None else self.gripper_plant.servos
        return (*self.plant.servos, *extra)

    def set_torque(self, on: bool) -> None:
        """Torque Enable on every servo, the gripper's too (whose finger then holds where it
        is); switching on first does what the family's servo needs to come back
        (:meth:`_before_torque_on`)."""
        with self._lock:
            self._check_open()
            finger = None if self.gripper_plant is None else self.gripper_plant.servos[0]
            if on and finger is not None and not finger.regs.torque_enable:
                finger.regs.goal_position = finger.report().position  # it stays put
            for servo in self._servos():
                if on:
                    self._before_torque_on(servo)
                servo.regs.torque_enable = int(bool(on))

    def _before_torque_on(self, servo: Any) -> None:
        """What switching ``servo``'s torque on does first (nothing by default)."""

    def estop(self) -> bool:
        """Torque off on every servo, the gripper's too; never raises."""
        with self._lock:
            for servo in self._servos():
                servo.regs.torque_enable = 0
        return True
