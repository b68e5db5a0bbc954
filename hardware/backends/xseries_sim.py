"""``XSimBackend``: a simulated arm of X-series servos behind the ``Backend`` protocol.

The simulated counterpart of :class:`armlab.hardware.backends.xseries.XSeriesBackend`, as
:class:`armlab.hardware.backends.sim.SimBackend` is of the protocol-1.0 backend: the servos are
:class:`armlab.hardware.sim.xseries_servo.XServoModel` firmware in the plant, configured as the
X-series backend configures real ones (current-based position control where the servo senses its
current, with Goal Current as the torque bound and a Position D Gain, else Goal PWM; no
profile limits, Min/Max Position Limit at the joint limits); goals go in as Goal
Position and Profile Velocity counts, readings come back as the servos report them (4096
counts a turn, 0.229 rpm, the current's or the load's unit) and are decoded with the
same conversions. An arm whose gripper has its own servo (``gripper``, the
OpenManipulator-X's) gets it too: its firmware moving the fingers' load
(:func:`armlab.hardware.backends.gripper.gripper_plant`), configured as the X-series backend
configures the real one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from armlab.control.backend import GripperState, JointState
from armlab.hardware.backends.gripper import (
    GRIPPER_PROFILE_VELOCITY,
    GripperServo,
    decode_gripper,
    gripper_plant,
    gripper_settings,
)
from armlab.hardware.backends.sim import SimBackend
from armlab.hardware.servos.xseries import (
    COUNTS,
    VELOCITY_UNIT,
    OperatingMode,
    XSpec,
    hardware_alarm,
    lab_mode,
    lab_settings,
    x_table_for,
)
from armlab.hardware.sim.dynamixel_servo import ServoParams
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.xseries_servo import XRegisters, XReport
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import vector


def x_servo_limits(model: SerialChain, spec: XSpec, directions: Sequence[float]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) (n,) rad: the model's joint limits inside the servos' one turn of
    Position Control (0..4095, seen through each direction)."""
    lo_s, hi_s = spec.raw_to_position(0), spec.raw_to_position(COUNTS - 1)
    lower = [max(float(model.lower[i]), lo_s if d > 0 else -hi_s)
             for i, d in enumerate(directions)]
    upper = [min(float(model.upper[i]), hi_s if d > 0 else -lo_s)
             for i, d in enumerate(directions)]
    return np.array(lower), np.array(upper)


def backend_registers(spec: XSpec, *, goal: int, min_limit: int, max_limit: int,
                      torque_limit: float = 1.0, torque_on: bool = True) -> XRegisters:
    """Registers as :class:`~armlab.hardware.backends.xseries.XSeriesBackend` configures a servo:
    the lab's mode and its settings (:func:`armlab.hardware.servos.xseries.lab_mode`,
    :func:`~armlab.hardware.servos.xseries.lab_settings`), no profile limits."""
    regs = XRegisters.factory(x_table_for(spec.model_number), goal_position=goal)
    regs.operating_mode = lab_mode(spec)
    for item, value, _ in lab_settings(spec, torque_limit=torque_limit):
        setattr(regs, item, value)
    regs.min_position_limit, regs.max_position_limit = min_limit, max_limit
    regs.torque_enable = int(torque_on)
    return regs


def gripper_registers(spec: XSpec, *, torque_on: bool = True) -> XRegisters:
    """Registers as :class:`~armlab.hardware.backends.xseries.XSeriesBackend` configures a gripper's
    servo: current-based position control with
    :func:`armlab.hardware.backends.gripper.gripper_settings`,
    the gripper's profile velocity, the goal at the horn's centre."""
    regs = XRegisters.factory(x_table_for(spec.model_number))
    regs.operating_mode = OperatingMode.CURRENT_BASED_POSITION
    for item, value, _ in gripper_settings(spec):
        setattr(regs, item, value)
    regs.profile_velocity = GRIPPER_PROFILE_VELOCITY
    regs.torque_enable = int(torque_on)
    return regs


def decode_x_reports(reports: Sequence[XReport], spec: XSpec, directions: Sequence[float],
                     t: float) -> JointState:
    """The servos' raw reports as the controller sees them: positions rad, velocities
    rad/s, torques N·m (from the measured current, or the load), through each direction."""
    d = np.array(directions, dtype=float)
    return JointState(
        t=t, position=d * np.array([spec.raw_to_position(r.position) for r in reports]),
        velocity=d * np.array([spec.raw_to_velocity(r.velocity) for r in reports]),
        load=d * np.array([spec.raw_to_torque(r.current) for r in reports]),
        errors=tuple(r.hardware_error for r in reports),
        torque_on=tuple(bool(r.torque_enable) for r in reports),
        alarms=tuple(hardware_alarm(r.hardware_error) if r.hardware_error else ""
                     for r in reports))


class XSimBackend(SimBackend):
    """A simulated arm of X-series servos (one model for every joint).

    Args:
        model: the serial chain.
        spec: the servos' datasheet (``armlab.hardware.servos.xseries.XM430_W350`` etc.).
        dt, q0, directions, params, torque_on: as :class:`~armlab.hardware.backends.sim.SimBackend`.
        gripper: the gripper's servo (same model, current-based position control), or None.
    """

    def __init__(self, model: SerialChain, *, spec: XSpec, dt: float = 1e-3,
                 q0: np.ndarray | None = None, directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 torque_on: bool = True, gripper: GripperServo | None = None) -> None:
        n = model.n
        dirs = [1.0] * n if directions is None else [float(d) for d in directions]
        self._lower, self._upper = x_servo_limits(model, spec, dirs)
        q_start = model.neutral() if q0 is None else vector("q0", q0, n)
        regs = []
        for i, d in enumerate(dirs):
            ends = sorted(spec.position_to_raw(d * x) for x in (self._lower[i], self._upper[i]))
            goal = spec.position_to_raw(d * float(np.clip(q_start[i], self._lower[i],
                                                          self._upper[i])))
            regs.append(backend_registers(spec, goal=goal, min_limit=ends[0], max_limit=ends[1],
                                          torque_on=torque_on))
        self._init_plant(Plant(model, spec, dt=dt, q0=q0, directions=dirs, params=params,
                               registers=regs), [spec] * n, dirs)
        self.gripper = gripper
        self.gripper_plant = None if gripper is None else gripper_plant(
            gripper, spec, dt=dt, registers=gripper_registers(spec, torque_on=torque_on))

    def sync(self, t: float) -> None:
        """Integrate the arm (and the gripper) up to ``t`` s."""
        super().sync(t)
        if self.gripper_plant is not None:
            with self._lock:
                self.gripper_plant.advance_to(self.plant.t)

    def read(self) -> JointState:
        """Every joint as its servo reports it (decoded raw values, quantised)."""
        with self._lock:
            self._check_open()
            reports = self.plant.reports()
            t = self.plant.t
            grip = None if self.gripper_plant is None else self.gripper_plant.reports()[0]
        state = decode_x_reports(reports, self.specs[0], self.directions, t)  # type: ignore[arg-type]
        if grip is None:
            return state
        return replace(state, gripper=self._decode_gripper(grip))

    def _decode_gripper(self, r: XReport) -> GripperState:
        assert self.gripper is not None
        alarm = hardware_alarm(r.hardware_error, servo_id=self.gripper.servo_id) \
            if r.hardware_error else ""
        return decode_gripper(self.gripper, self.specs[0], position=r.position,  # type: ignore[arg-type]
                              velocity=r.velocity, current=r.current,
                              torque_on=bool(r.torque_enable), alarm=alarm)

    @property
    def gripper_range(self) -> tuple[float, float] | None:
        """(closed, open) m of the gripper's finger, or None without a gripper."""
        return None if self.gripper is None else (self.gripper.lower, self.gripper.upper)

    def set_gripper(self, position: float) -> float:
        """Goal Position of the gripper's servo for the finger at ``position`` m, clamped
        into its range; returns the clamped goal (ValueError without a gripper)."""
        if self.gripper is None or self.gripper_plant is None:
            raise ValueError("this simulated arm has no gripper servo")
        x = self.gripper.clamp(position)
        raw = self.specs[0].position_to_raw(self.gripper.to_servo(x))  # type: ignore[attr-defined]
        with self._lock:
            self._check_open()
            self.gripper_plant.servos[0].regs.goal_position = raw
        return x

    def write_checked(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Checked goals (n,) rad and speeds (n,) rad/s -> Goal Position and Profile
        Velocity (a magnitude, at least 1 count: 0 would mean "no limit")."""
        spec = self.specs[0]
        goals = [spec.position_to_raw(d * x) for d, x in zip(self.directions, position,
                                                               strict=True)]
        speeds = [max(1, round(abs(v) / VELOCITY_UNIT)) for v in speed]
        with self._lock:
            self._check_open()
            for servo, g, v in zip(self.plant.servos, goals, speeds, strict=True):
                servo.regs.goal_position = g
                servo.regs.profile_velocity = min(v, servo.regs.velocity_limit or v)

    def set_torque(self, on: bool) -> None:
        """Torque Enable on every servo, the gripper's too (whose fingers then hold where
        they are); switching on REBOOTs a servo that shut down on a hardware error first
        (the only way back on an X-series servo)."""
        with self._lock:
            self._check_open()
            fingers = None if self.gripper_plant is None else self.gripper_plant.servos[0]
            if on and fingers is not None and not fingers.regs.torque_enable:
                fingers.regs.goal_position = fingers.report().position  # they stay put
            for servo in self._servos():
                if on and servo.hardware_error:
                    servo.reboot()
                servo.regs.torque_enable = int(bool(on))

    def _servos(self) -> tuple:
        """The arm's servo models, then the gripper's."""
        extra = () if self.gripper_plant is None else self.gripper_plant.servos
        return (*self.plant.servos, *extra)

    def estop(self) -> bool:
        """Torque off on every servo, the gripper's too; never raises."""
        with self._lock:
            for servo in self._servos():
                servo.regs.torque_enable = 0
        return True
