"""An X-series servo driving an arm's gripper (the OpenManipulator-X's XM430-W350, ID 15):
current-based position control, whose Goal Current bounds the grip
(:mod:`armlab.hardware.backends.gripper` holds the gripper's geometry every family shares).
"""

from __future__ import annotations

from armlab.control.backend import GripperState
from armlab.hardware.backends.gripper import (
    GRIPPER_CURRENT,
    GRIPPER_SPEED,
    GripperServo,
    gripper_state,
)
from armlab.hardware.families.xseries.table import (
    CURRENT_POSITION_D_GAIN,
    VELOCITY_UNIT,
    OperatingMode,
    XSpec,
    x_table_for,
)

#: Profile Velocity counts (0.229 rpm) the gripper's goals are sent with: the horn at
#: :data:`~armlab.hardware.backends.gripper.GRIPPER_SPEED`.
GRIPPER_PROFILE_VELOCITY = round(GRIPPER_SPEED / VELOCITY_UNIT)


def drives_gripper(spec: XSpec) -> bool:
    """Whether an X-series servo of datasheet ``spec`` can drive a gripper: it has
    current-based position control (Goal Current bounds the grip)."""
    return OperatingMode.CURRENT_BASED_POSITION in spec.modes


def grip_note(spec: XSpec) -> str:
    """How an X-series gripper servo holds the finger and bounds its grip, in a person's
    words (the lesson's Teach tab): current-based position control with a Goal Current."""
    return (f"its own servo (a {spec.name}), in current-based position control (operating "
            "mode 5): Goal Current bounds the horn's torque, so fingers closing on an "
            "object press with a bounded force (shown under the buttons) and never crush "
            "it; closing on nothing they reach their limit.")


def gripper_settings(spec: XSpec) -> tuple[tuple[str, int, str], ...]:
    """The RAM items the lab sets on a gripper's servo in current-based position control,
    as (item, raw value, a line for the log): Goal Current :data:`GRIPPER_CURRENT` (never
    above the model's Current Limit) and the Position D Gain the arm's servos get."""
    limit = x_table_for(spec.model_number).item("current_limit").default
    raw = min(spec.current_to_raw(GRIPPER_CURRENT), int(limit))  # type: ignore[arg-type]  # the X tables give current_limit a default
    torque = spec.raw_to_torque(raw)
    return (("goal_current", raw, f"goal current {raw} ({spec.raw_to_current(raw):.2f} A: "
             f"at most {torque:.2f} N·m at the horn, a gentle grip)"),
            ("position_d_gain", CURRENT_POSITION_D_GAIN,
             f"position D gain {CURRENT_POSITION_D_GAIN}"))


def decode_gripper(gripper: GripperServo, spec: XSpec, *, position: int, velocity: int,
                   current: int, torque_on: bool, alarm: str = "") -> GripperState:
    """An X-series gripper servo's raw Present Position, Velocity and Current as the
    finger's state (:func:`gripper_state`)."""
    return gripper_state(gripper, angle=spec.raw_to_position(position),
                         speed=spec.raw_to_velocity(velocity),
                         torque=spec.raw_to_torque(current), torque_on=torque_on, alarm=alarm)
