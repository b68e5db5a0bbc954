"""The plant behind emulated servos, whatever their family: a joint pinned at an angle, a
pose the arm rests in with torque off, and the arm's rigid body the servos' firmware
drives (:class:`ArmPhysics`).
"""

from __future__ import annotations

import math
from typing import Any

from armlab.hardware.emulator.network import TableImage
from armlab.hardware.sim.plant import Plant


def pin(plant: Plant, j: int, angle: float) -> None:
    """Put joint ``j`` of ``plant`` at ``angle`` rad (of the plant), at rest, and tick its
    servo's firmware once there: the servo senses where the arm was put (its report is
    what it sensed at its last tick)."""
    q, qd = plant.q, plant.qd
    q[j], qd[j] = angle, 0.0
    plant.set_state(q, qd)
    plant.servos[j].update(plant.dt, plant.directions[j] * angle, 0.0)


class RestingPose:
    """Joints an emulator starts at a pose of a person's choosing (``armlab emulate
    --pose``): each stays where it was put, as an unpowered arm rests on its gears'
    friction where it was left, until its servo's torque first comes on; from then on the
    plant moves it. A physics class says where a joint lives (:meth:`_locate`)."""

    _resting: dict[int, float]  #: joint -> the angle it rests at, rad of the plant

    def _locate(self, joint: int) -> tuple[Plant, int]:
        """(plant, joint index in it) of emulated joint ``joint``; ValueError if none."""
        raise NotImplementedError

    def rest(self, joint: int, angle: float) -> None:
        """Put ``joint`` at ``angle`` rad and keep it there until its servo's torque
        comes on. ValueError for no such joint or a non-finite angle."""
        if not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle}")
        plant, j = self._locate(joint)
        pin(plant, j, float(angle))
        self._resting[joint] = float(angle)

    def _settle_resting(self) -> None:
        """After the plants stepped: joints still resting go back where they rest; one
        whose servo's torque is on is let go for good."""
        for joint, angle in list(self._resting.items()):
            plant, j = self._locate(joint)
            if plant.servos[j].regs.torque_enable:
                del self._resting[joint]
            else:
                pin(plant, j, angle)


class ArmPhysics(RestingPose):
    """A serial arm's emulated servos moved by its simulated plant, and an arm's gripper
    servo by the gripper's plant (:func:`armlab.hardware.backends.gripper.gripper_plant`):
    the servo whose ``joint`` is one past the arm's last. A family's physics
    (:class:`armlab.hardware.families.xseries.emulator.XPlantPhysics`,
    :class:`armlab.hardware.families.feetech.emulator.StsPlantPhysics`) adds how its registers go in
    and its report comes back."""

    def __init__(self, plant: Plant, *, gripper: Plant | None = None) -> None:
        self.plant = plant
        self.gripper = gripper
        self._held: dict[int, float] = {}  # joint -> angle a hand holds it at, rad
        self._resting = {}

    def advance_to(self, t: float) -> None:
        self.plant.advance_to(t)
        if self.gripper is not None:
            self.gripper.advance_to(t)
        self._settle_resting()
        for joint, angle in self._held.items():
            pin(*self._locate(joint), angle)

    def hold(self, joint: int, angle: float | None) -> None:
        """Hold ``joint`` (the gripper's horn: one past the arm's last) at ``angle`` rad
        of the plant, as a person's hand moving the arm with its torque off would
        (``armlab emulate --control``); None lets go. ValueError for no such joint or a
        non-finite angle."""
        self._locate(joint)
        if angle is None:
            self._held.pop(joint, None)
        elif not math.isfinite(angle):
            raise ValueError(f"angle must be finite, got {angle}")
        else:
            self._held[joint] = float(angle)

    def _locate(self, joint: int) -> tuple[Plant, int]:
        if 0 <= joint < self.plant.n:
            return self.plant, joint
        if joint == self.plant.n and self.gripper is not None:
            return self.gripper, 0
        raise ValueError(f"no joint {joint} on this arm")

    def _model(self, s: TableImage) -> Any:
        """The simulated servo behind ``s``: an arm joint's, or the gripper's."""
        if s.joint == self.plant.n and self.gripper is not None:
            return self.gripper.servos[0]
        return self.plant.servos[s.joint]
