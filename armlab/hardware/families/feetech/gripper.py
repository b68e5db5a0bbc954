"""A Feetech STS servo driving an arm's gripper (the SO-101's STS3215, ID 6): position
control held to a Torque Limit, the STS having no current mode
(:mod:`armlab.hardware.backends.gripper` holds the jaw's geometry).
"""

from __future__ import annotations

from armlab.hardware.backends.gripper import SO101_GRIPPER_TORQUE_LIMIT
from armlab.hardware.families.feetech.table import StsSpec


def drives_gripper(spec: StsSpec) -> bool:
    """Every STS can drive a gripper: held to a Torque Limit (it has no current mode)."""
    return True


def grip_note(spec: StsSpec) -> str:
    """How an STS gripper servo holds the jaw and bounds its grip, in a person's words (the
    lesson's Teach tab): position control held to a Torque Limit."""
    return (f"its own servo (a Feetech {spec.name}), in position control held to a "
            f"Torque Limit ({SO101_GRIPPER_TORQUE_LIMIT:.0%} of its maximum, as LeRobot "
            "sets the SO-101's gripper): the STS has no current mode, so the Torque "
            "Limit bounds the horn's torque whatever the position error, and a jaw "
            "closing on an object presses with a bounded force (shown under the "
            "buttons, an estimate from the jaw's lever) and never crushes it; closing "
            "on nothing it reaches its limit.")
