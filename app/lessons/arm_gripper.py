"""The arm lesson's gripper: Open / Close buttons, a slider of the finger's travel (mm) and
a readout, for an arm whose backend drives a gripper's own servo (the OpenManipulator-X's
ID 15, simulated or on the bus: :class:`armlab.control.backend.Gripping`); the 3D view's fingers
(the URDF's finger joint and the one that mimics it) follow what the servo reports.
"""

from __future__ import annotations

import math

import viser

from armlab.app.lessons._common import esc, guarded, set_content
from armlab.app.lessons._loop_state import check_running
from armlab.app.page.arm_view import ArmView
from armlab.control.backend import Backend, Gripping
from armlab.control.commands import SetGripper
from armlab.control.loop import ControlLoop
from armlab.hardware.backends.joint_map import ROBOT_GRIPPERS
from armlab.kinematics.model import SerialChain

#: The Teach tab's words on the gripper (an arm that drives one).
TEACH = ("**Gripper**: its own servo, in current-based position control (operating mode "
         "5): Goal Current bounds the horn's torque, so fingers closing on an object press "
         "with a bounded force (shown under the buttons) and never crush it; closing on "
         "nothing they reach their limit. The slider is the travel of one finger (the "
         "URDF's finger joint); the other mirrors it.")


class GripperControls:
    """The gripper's controls, built in the current GUI container (nothing for an arm whose
    backend drives no gripper).

    Args:
        gui: the server's GUI.
        model: the arm (for the Teach tab's note on a private arm).
        backend: the arm's backend (a :class:`~armlab.control.backend.Gripping` one drives it).
        loop: the arm's control loop (goals go through it; it reads the fingers).
        view: the 3D arm whose fingers follow the servo.

    Attributes:
        range: (closed, open) m of the finger, or None without a gripper.
    """

    def __init__(self, gui: viser.GuiApi, *, model: SerialChain, backend: Backend,
                 loop: ControlLoop, view: ArmView) -> None:
        self.model, self.loop, self.view = model, loop, view
        self.range = backend.gripper_range if isinstance(backend, Gripping) else None
        self._shown = math.nan  # finger position the 3D view shows, m
        if self.range is None:
            return
        lo, hi = (round(x * 1e3, 1) for x in self.range)
        self._setting = False  # the slider is being placed, not moved by a person
        self._placed = False  # the slider shows the fingers once they are read
        self.slider = gui.add_slider(
            "gripper mm", min=lo, max=hi, step=0.5, initial_value=lo,
            hint=f"Finger travel: {lo:+.1f} mm closed .. {hi:+.1f} mm open")
        self.slider.on_update(lambda e: None if self._setting else guarded(
            e, lambda: self.grip(float(self.slider.value) * 1e-3)))
        for label, mm in (("Open gripper", hi), ("Close gripper", lo)):
            button = gui.add_button(label, icon=viser.Icon.HAND_GRAB)
            button.on_click(lambda e, mm=mm: guarded(e, lambda: self.grip(mm * 1e-3)))
        self.text = gui.add_markdown("Gripper: not read yet")

    def add_teach(self, gui: viser.GuiApi) -> None:
        """The Teach tab's note: what the gripper's servo does, or that a private copy of
        an arm with a gripper has none."""
        if self.range is not None:
            gui.add_markdown(TEACH)
        elif self.model.name in ROBOT_GRIPPERS:
            gui.add_markdown("**Gripper**: driven on the teacher's arm (simulated or "
                             "servos); a private arm has none.")

    def grip(self, position: float) -> None:
        """Move the finger to ``position`` m (the backend clamps it into the gripper's
        range); the slider shows the goal.

        Raises:
            ValueError: the loop is stopped (a lost link, a fault, E-STOP): saying why.
        """
        check_running(self.loop.status)
        self.loop.post(SetGripper(position))
        self._place(position)

    def _place(self, position: float) -> None:
        """Put the slider at ``position`` m (clamped, its 0.5 mm step), sending nothing."""
        assert self.range is not None
        self._placed = self._setting = True
        try:
            lo, hi = (x * 1e3 for x in self.range)
            self.slider.value = round(min(max(position * 1e3, lo), hi) * 2.0) / 2.0
        finally:
            self._setting = False

    def pose_frame(self) -> None:
        """Pose the 3D view's fingers where the servo reported them."""
        grip = self.loop.gripper
        if grip is not None and grip.position != self._shown:
            self._shown = grip.position
            self.view.set_joint(grip.joint, grip.position)

    def status_frame(self) -> None:
        """The readout: the finger's position, the force of each finger, torque and alarm."""
        grip = self.loop.gripper
        if grip is None or self.range is None:
            return
        if not self._placed:  # the fingers hold where they were found
            self._place(grip.position)
        set_content(self.text, (
            f"Gripper: finger {grip.position * 1e3:+.1f} mm, pressing "
            f"{abs(grip.force):.0f} N a finger ({grip.effort:+.2f} N·m at the horn)"
            + ("" if grip.torque_on else ", torque off")
            + (f", **{esc(grip.alarm)}**" if grip.alarm else "")))
