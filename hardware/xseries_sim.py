"""``XSimBackend``: a simulated arm of X-series servos behind the ``Backend`` protocol.

The simulated counterpart of :class:`hardware.xseries_backend.XSeriesBackend`, as
:class:`hardware.sim_backend.SimBackend` is of the protocol-1.0 backend: the servos are
:class:`hardware.xservo.XServoModel` firmware in the plant, configured as the X-series
backend configures real ones (current-based position control where the servo senses its
current, with Goal Current as the torque bound and a Position D Gain, else Goal PWM; no
profile limits, Min/Max Position Limit at the joint limits); goals go in as Goal
Position and Profile Velocity counts, readings come back as the servos report them (4096
counts a turn, 0.229 rpm, the current's or the load's unit) and are decoded with the
same conversions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from control.backend import JointState
from hardware.plant import Plant
from hardware.servo import ServoParams
from hardware.sim_backend import SimBackend
from hardware.xseries import COUNTS, VELOCITY_UNIT, XSpec, lab_mode, lab_settings, x_table_for
from hardware.xseries_backend import hardware_alarm
from hardware.xservo import XRegisters, XReport
from kinematics.model import SerialChain
from kinematics.validate import vector


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
    """Registers as :class:`~hardware.xseries_backend.XSeriesBackend` configures a servo:
    the lab's mode and its settings (:func:`hardware.xseries.lab_mode`,
    :func:`~hardware.xseries.lab_settings`), no profile limits."""
    regs = XRegisters.factory(x_table_for(spec.model_number), goal_position=goal)
    regs.operating_mode = lab_mode(spec)
    for item, value, _ in lab_settings(spec, torque_limit=torque_limit):
        setattr(regs, item, value)
    regs.min_position_limit, regs.max_position_limit = min_limit, max_limit
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
        spec: the servos' datasheet (``hardware.xseries.XM430_W350`` etc.).
        dt, q0, directions, params, torque_on: as :class:`~hardware.sim_backend.SimBackend`.
    """

    def __init__(self, model: SerialChain, *, spec: XSpec, dt: float = 1e-3,
                 q0: np.ndarray | None = None, directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 torque_on: bool = True) -> None:
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

    def read(self) -> JointState:
        """Every joint as its servo reports it (decoded raw values, quantised)."""
        with self._lock:
            self._check_open()
            reports = self.plant.reports()
            t = self.plant.t
        return decode_x_reports(reports, self.specs[0], self.directions, t)  # type: ignore[arg-type]

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
        """Torque Enable on every servo; switching on REBOOTs a servo that shut down on a
        hardware error first (the only way back on an X-series servo)."""
        with self._lock:
            self._check_open()
            for servo in self.plant.servos:
                if on and servo.hardware_error:
                    servo.reboot()
                servo.regs.torque_enable = int(bool(on))
