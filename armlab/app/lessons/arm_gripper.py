"""The arm lesson's gripper: Open / Close buttons, a slider of the finger's position and a
readout, for an arm whose backend drives a gripper's own servo (the OpenManipulator-X's
ID 15, the SO-101's ID 6, simulated or on the bus: :class:`armlab.control.backend.Gripping`);
the 3D view's fingers (the URDF's finger joint and any that mimic it) follow what the servo
reports. The page speaks the finger joint's kind: mm of travel for a finger that slides
(the OpenManipulator-X's prismatic joint), degrees for a jaw that turns (the SO-101's
revolute ``gripper``); the Teach tab says how the servo's family bounds the grip.
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


def teach_note(*, revolute: bool, grip: str) -> str:
    """The Teach tab's words on the gripper: how its servo bounds the grip (``grip``, the
    backend's :attr:`~armlab.control.backend.Gripping.gripper_note`) and what the slider
    moves (a jaw's angle, or one sliding finger's travel)."""
    slider = ("The slider is the jaw's angle, in degrees (the URDF's revolute jaw joint)."
              if revolute else "The slider is the travel of one finger, in mm (the URDF's "
              "prismatic finger joint); the other mirrors it.")
    return f"**Gripper**: {grip} {slider}"


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
        range: (closed, open) of the finger in its URDF units (m, or rad for a jaw), or
            None without a gripper.
        revolute: whether the finger is a jaw that turns (shown in degrees) rather than a
            finger that slides (shown in mm).
        unit: what the page shows the finger in, "°" or "mm".
    """

    def __init__(self, gui: viser.GuiApi, *, model: SerialChain, backend: Backend,
                 loop: ControlLoop, view: ArmView) -> None:
        self.model, self.loop, self.view = model, loop, view
        self.range = backend.gripper_range if isinstance(backend, Gripping) else None
        self._shown = math.nan  # finger position the 3D view shows, URDF units
        if self.range is None:
            return
        assert isinstance(backend, Gripping)
        self.revolute = backend.gripper_revolute
        self._note = backend.gripper_note
        self.unit = "°" if self.revolute else "mm"
        self._scale = 180.0 / math.pi if self.revolute else 1e3  # URDF units -> the page's
        lo, hi = (round(x * self._scale, 1) for x in self.range)
        self._setting = False  # the slider is being placed, not moved by a person
        self._placed = False  # the slider shows the fingers once they are read
        what = "Jaw angle" if self.revolute else "Finger travel"
        self.slider = gui.add_slider(
            f"gripper {self.unit}", min=lo, max=hi, step=0.5, initial_value=lo,
            hint=f"{what}: {lo:+.1f} {self.unit} closed .. {hi:+.1f} {self.unit} open")
        self.slider.on_update(lambda e: None if self._setting else guarded(
            e, lambda: self.grip(float(self.slider.value) / self._scale)))
        for label, end in (("Open gripper", self.range[1]), ("Close gripper", self.range[0])):
            button = gui.add_button(label, icon=viser.Icon.HAND_GRAB)
            button.on_click(lambda e, end=end: guarded(e, lambda: self.grip(end)))  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
        self.text = gui.add_markdown("Gripper: not read yet")

    def add_teach(self, gui: viser.GuiApi) -> None:
        """The Teach tab's note: how the gripper's servo bounds the grip and what the
        slider moves, or that a private copy of an arm with a gripper has none."""
        if self.range is not None:
            gui.add_markdown(teach_note(revolute=self.revolute, grip=self._note))
        elif self.model.name in ROBOT_GRIPPERS:
            gui.add_markdown("**Gripper**: driven on the teacher's arm (simulated or "
                             "servos); a private arm has none.")

    def grip(self, position: float) -> None:
        """Move the finger to ``position`` in its URDF units (m, or rad for a jaw; the
        backend clamps it into the gripper's range); the slider shows the goal.

        Raises:
            ValueError: the loop is stopped (a lost link, a fault, E-STOP): saying why.
        """
        check_running(self.loop.status)
        self.loop.post(SetGripper(position))
        self._place(position)

    def _place(self, position: float) -> None:
        """Put the slider at ``position`` (URDF units; clamped, its 0.5 step of the page's
        unit), sending nothing."""
        assert self.range is not None
        self._placed = self._setting = True
        try:
            lo, hi = (x * self._scale for x in self.range)
            shown = min(max(position * self._scale, lo), hi)
            self.slider.value = round(shown * 2.0) / 2.0  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        finally:
            self._setting = False

    def pose_frame(self) -> None:
        """Pose the 3D view's fingers where the servo reported them."""
        grip = self.loop.gripper
        if grip is not None and grip.position != self._shown:
            self._shown = grip.position
            self.view.set_joint(grip.joint, grip.position)

    def status_frame(self) -> None:
        """The readout: the finger's position (a jaw's angle, or a finger's travel), the
        force it presses with, the horn's torque, torque off and alarm."""
        grip = self.loop.gripper
        if grip is None or self.range is None:
            return
        if not self._placed:  # the fingers hold where they were found
            self._place(grip.position)
        where = (f"jaw {grip.position * self._scale:+.1f}°, pressing {abs(grip.force):.0f} N"
                 if self.revolute else f"finger {grip.position * self._scale:+.1f} mm, "
                 f"pressing {abs(grip.force):.0f} N a finger")
        set_content(self.text, (
            f"Gripper: {where} ({grip.effort:+.2f} N·m at the horn)"
            + ("" if grip.torque_on else ", torque off")
            + (f", **{esc(grip.alarm)}**" if grip.alarm else "")))
