"""``XSimBackend``: a simulated arm of X-series servos behind the ``Backend`` protocol.

The simulated counterpart of :class:`armlab.hardware.families.xseries.backend.XSeriesBackend`, as
:class:`armlab.hardware.families.dynamixel1.sim_backend.SimBackend` is of the protocol-1.0 backend:
the servos are
:class:`armlab.hardware.families.xseries.firmware.XServoModel` firmware in the plant, configured as
the X-series backend configures real ones (current-based position control where the servo senses its
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
from typing import Any

import numpy as np

from armlab.control.backend import GripperState, JointState
from armlab.hardware.backends.gripper import (
    GripperServo,
    gripper_plant,
)
from armlab.hardware.families.dynamixel1.sim_backend import GrippedSimBackend
from armlab.hardware.families.xseries.firmware import XRegisters, XReport
from armlab.hardware.families.xseries.gripper import (
    GRIPPER_PROFILE_VELOCITY,
    decode_gripper,
    gripper_settings,
)
from armlab.hardware.families.xseries.table import (
    VELOCITY_UNIT,
    OperatingMode,
    XSpec,
    hardware_alarm,
    lab_mode,
    lab_settings,
    x_table_for,
)
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.model import SerialChain


def backend_registers(spec: XSpec, *, goal: int, min_limit: int, max_limit: int,
                      torque_limit: float = 1.0, torque_on: bool = True) -> XRegisters:
    """Registers as :class:`~armlab.hardware.families.xseries.backend.XSeriesBackend` configures a
    servo:
    the lab's mode and its settings (:func:`armlab.hardware.families.xseries.table.lab_mode`,
    :func:`~armlab.hardware.families.xseries.table.lab_settings`), no profile limits."""
    regs = XRegisters.factory(x_table_for(spec.model_number), goal_position=goal)
    regs.operating_mode = lab_mode(spec)
    for item, value, _ in lab_settings(spec, torque_limit=torque_limit):
        setattr(regs, item, value)
    regs.min_position_limit, regs.max_position_limit = min_limit, max_limit
    regs.torque_enable = int(torque_on)
    return regs


def gripper_registers(spec: XSpec, *, torque_on: bool = True) -> XRegisters:
    """Registers as :class:`~armlab.hardware.families.xseries.backend.XSeriesBackend` configures a
    gripper's servo: current-based position control with
    :func:`armlab.hardware.families.xseries.gripper.gripper_settings`,
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


class XSimBackend(GrippedSimBackend):
    """A simulated arm of X-series servos (one model for every joint).

    Args:
        model: the serial chain.
        spec: the servos' datasheet (``armlab.hardware.families.xseries.table.XM430_W350`` etc.).
        dt, q0, directions, params, torque_on: as
        :class:`~armlab.hardware.families.dynamixel1.sim_backend.SimBackend`.
        gripper: the gripper's servo (same model, current-based position control), or None.
    """

    spec: XSpec

    def __init__(self, model: SerialChain, *, spec: XSpec, dt: float = 1e-3,
                 q0: np.ndarray | None = None, directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 torque_on: bool = True, gripper: GripperServo | None = None) -> None:
        self._open_arm(model, spec, registers=backend_registers, dt=dt, q0=q0,
                       directions=directions, params=params, torque_on=torque_on)
        self.gripper = gripper
        self.gripper_plant = None if gripper is None else gripper_plant(
            gripper, spec, dt=dt, registers=gripper_registers(spec, torque_on=torque_on))

    def _decode(self, reports: Sequence[XReport], t: float) -> JointState:
        """The servos' raw reports as the controller sees them (:func:`decode_x_reports`)."""
        return decode_x_reports(reports, self.spec, self.directions, t)

    def _decode_gripper(self, r: XReport) -> GripperState:
        assert self.gripper is not None
        alarm = hardware_alarm(r.hardware_error, servo_id=self.gripper.servo_id) \
            if r.hardware_error else ""
        return decode_gripper(self.gripper, self.spec, position=r.position,
                              velocity=r.velocity, current=r.current,
                              torque_on=bool(r.torque_enable), alarm=alarm)

    def _speed_words(self, speed: np.ndarray) -> list[int]:
        """Checked speeds (n,) rad/s as Profile Velocity (a magnitude, at least 1 count: 0
        would mean "no limit")."""
        return [max(1, round(abs(v) / VELOCITY_UNIT)) for v in speed]

    @staticmethod
    def _set_speed(regs: XRegisters, word: int) -> None:
        """A servo's Profile Velocity, never above its Velocity Limit."""
        regs.profile_velocity = min(word, regs.velocity_limit or word)

    def _before_torque_on(self, servo: Any) -> None:
        """A servo that shut down on a hardware error is REBOOTed (the only way back on an
        X-series servo)."""
        if servo.hardware_error:
            servo.reboot()
