"""The push controls of the arm lessons: force, direction, duration and the Push button.

A push is a force at the hand for a short time, given to the simulated arm through
its backend's :class:`armlab.control.backend.Pushable` (the lesson posts a
:class:`armlab.control.commands.Push`). Real servos are pushed by a hand: there the inputs
and the button are hidden and the lesson says so. The values pass
:class:`armlab.app.page.inputs.GuardedNumber` guards: a typed NaN or out-of-range number is
refused with one notification and the slider goes back.
"""

from __future__ import annotations

from collections.abc import Callable

import viser

from armlab.app.lessons._common import guarded
from armlab.app.page.inputs import guarded_slider


class PushControls:
    """The inputs and the button, added to ``gui`` (inside the caller's tab or folder).

    Args:
        gui: where to add them.
        directions: the labels the "Direction" dropdown offers (the caller turns the
            chosen one into a force direction).
        servos: real servos: everything is added hidden (a hand pushes the arm).
        on_push: called when "Push" is clicked; a ValueError it raises is shown to the
            person who clicked.
        force, duration: first values, N and s.

    Attributes:
        button: the "Push" button.
        result: markdown under the button for what the last push measured.
    """

    def __init__(self, gui: viser.GuiApi, directions: tuple[str, ...], *, servos: bool,
                 on_push: Callable[[], None], force: float = 4.0,
                 duration: float = 2.0) -> None:
        sim = not servos
        self._force = guarded_slider(gui, "Push force (N)", name="push force", lo=0.5,
                                     hi=20.0, step=0.5, initial=force, apply=lambda v: None,
                                     visible=sim)
        self._direction = gui.add_dropdown("Direction", directions, visible=sim)
        self._duration = guarded_slider(gui, "Duration (s)", name="duration", lo=0.1, hi=10.0,
                                        step=0.1, initial=duration, apply=lambda v: None,
                                        visible=sim)
        self.button = gui.add_button("Push", icon=viser.Icon.HAND_FINGER, visible=sim,
                                     hint="Push the hand with this force for this long")
        self.button.on_click(lambda e: guarded(e, on_push))
        self.result = gui.add_markdown("")

    @property
    def force(self) -> float:
        """The push's size, N."""
        return float(self._force.value)

    @property
    def direction(self) -> str:
        """The chosen direction's label."""
        return str(self._direction.value)

    @property
    def duration(self) -> float:
        """How long the push lasts, s."""
        return float(self._duration.value)
