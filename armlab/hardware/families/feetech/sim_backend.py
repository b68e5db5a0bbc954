"""``StsSimBackend``: a simulated arm of Feetech STS servos (the SO-101) behind the
``Backend`` protocol.

The simulated counterpart of :class:`armlab.hardware.families.feetech.backend.StsBackend`, as
:class:`armlab.hardware.families.xseries.sim_backend.XSimBackend` is of the X-series backend: the
servos are :class:`armlab.hardware.families.feetech.firmware.StsServoModel` firmware in the plant,
at the robot's supply (the SO-101's 5 V), configured as the STS backend configures real ones
(:func:`armlab.hardware.families.feetech.table.lab_settings`: position mode, P 16, no acceleration
limit, the torque limit; Min/Max Position Limit at the joint limits). Goals go in as Goal
Position and Goal Speed counts, readings come back as the servos report them (4096
counts a turn, counts/s, Present Current signed as Present Load) and are decoded with the
same conversions, so the simulated SO-101 and the one on the bus (or the emulator) give
the same figures. The SO-101's jaw servo moves the jaw's load, held to the gripper's
torque limit.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from armlab.control.backend import GripperState, JointState
from armlab.hardware.backends.gripper import (
    GRIPPER_SPEED,
    SO101_GRIPPER_TORQUE_LIMIT,
    GripperServo,
    gripper_plant,
    gripper_state,
)
from armlab.hardware.backends.joint_map import ROBOT_SUPPLY
from armlab.hardware.families.dynamixel1.sim_backend import GrippedSimBackend
from armlab.hardware.families.feetech.firmware import StsRegisters, StsReport
from armlab.hardware.families.feetech.table import StsSpec, lab_settings, sts_alarm, sts_table_for
from armlab.hardware.sim.servo_motor import ServoParams
from armlab.kinematics.model import SerialChain


def sts_registers(spec: StsSpec, *, goal: int, min_limit: int = 0, max_limit: int = 4095,
                  torque_limit: float = 1.0, torque_on: bool = True) -> StsRegisters:
    """Registers as :class:`~armlab.hardware.families.feetech.backend.StsBackend` configures a servo
    (:func:`~armlab.hardware.families.feetech.table.lab_settings`), its Min/Max Position Limit and
    its goal."""
    table = sts_table_for(spec.model_number)
    regs = StsRegisters.factory(table, goal_position=goal)
    for item, value, _ in lab_settings(table, torque_limit=torque_limit):
        setattr(regs, item, value)
    regs.min_position_limit, regs.max_position_limit = min_limit, max_limit
    regs.torque_enable = int(torque_on)
    return regs


class StsSimBackend(GrippedSimBackend):
    """A simulated arm of Feetech STS servos (one model for every joint).

    Args:
        model: the serial chain.
        spec: the servos' datasheet (``armlab.hardware.families.feetech.table.STS3215``).
        dt, q0, directions, torque_on: as
        :class:`~armlab.hardware.families.dynamixel1.sim_backend.SimBackend`.
        params: the servos' physical constants (default: at the robot's supply,
            :data:`~armlab.hardware.backends.joint_map.ROBOT_SUPPLY`, else the datasheet's).
        gripper: the gripper's servo (same model, held to the gripper's torque limit), or
            None.
    """

    spec: StsSpec

    def __init__(self, model: SerialChain, *, spec: StsSpec, dt: float = 1e-3,
                 q0: np.ndarray | None = None, directions: Sequence[float] | None = None,
                 params: ServoParams | Sequence[ServoParams] | None = None,
                 torque_on: bool = True, gripper: GripperServo | None = None) -> None:
        if params is None:
            params = ServoParams(voltage=ROBOT_SUPPLY.get(model.name, spec.voltage))
        self._open_arm(model, spec, registers=sts_registers, dt=dt, q0=q0,
                       directions=directions, params=params, torque_on=torque_on)
        self.gripper = gripper
        if gripper is not None:
            jaw = sts_registers(spec, goal=spec.position_to_raw(0.0),
                                torque_limit=SO101_GRIPPER_TORQUE_LIMIT, torque_on=torque_on)
            jaw.goal_speed = spec.goal_speed_to_raw(GRIPPER_SPEED)
            one = params if isinstance(params, ServoParams) else params[0]
            self.gripper_plant = gripper_plant(gripper, spec, dt=dt, registers=jaw, params=one)

    def _decode(self, reports: Sequence[StsReport], t: float) -> JointState:
        """The servos' raw reports as the controller sees them: positions rad, speeds
        rad/s, torques N·m (Present Current signed as Present Load), through each
        direction."""
        s, d = self.spec, np.array(self.directions)
        return JointState(
            t=t, position=d * np.array([s.raw_to_position(r.position) for r in reports]),
            velocity=d * np.array([s.raw_to_speed(r.speed) for r in reports]),
            load=d * np.array([s.signed_torque(r.current, r.load) for r in reports]),
            errors=tuple(r.error for r in reports),
            torque_on=tuple(bool(r.torque_enable) for r in reports),
            alarms=tuple(sts_alarm(r.error) for r in reports))

    def _decode_gripper(self, r: StsReport) -> GripperState:
        assert self.gripper is not None
        s = self.spec
        return gripper_state(self.gripper, angle=s.raw_to_position(r.position),
                             speed=s.raw_to_speed(r.speed),
                             torque=s.signed_torque(r.current, r.load),
                             torque_on=bool(r.torque_enable),
                             alarm=sts_alarm(r.error, servo_id=self.gripper.servo_id))

    def _speed_words(self, speed: np.ndarray) -> list[int]:
        """Checked speeds (n,) rad/s as Goal Speed (as the STS backend sends them)."""
        return [self.spec.goal_speed_to_raw(v) for v in speed]

    @staticmethod
    def _set_speed(regs: StsRegisters, word: int) -> None:
        """A servo's Goal Speed."""
        regs.goal_speed = word
