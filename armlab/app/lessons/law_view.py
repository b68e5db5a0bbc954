"""What a servo-arm lesson shows of a student's own law (``armlab serve --exercise FILE``):
"Your law: FILE" where the gains are, its error (file, line, error) on the page, and the
reference arm, run by the lab's own law on the same commands, as a see-through ghost.

A lesson makes one :class:`LawView` when its loop is a
:class:`~armlab.app.arm.student_law.LawLoop` (see :func:`law_loop_of`) and calls
:meth:`LawView.draw` from its pose frames and :meth:`LawView.status_extra` from its status.
"""

from __future__ import annotations

import threading

import numpy as np
import viser

from armlab.app.arm.student_law import LawLoop, StudentLaw
from armlab.app.lessons._common import esc, set_content
from armlab.app.page.arm_view import ArmView
from armlab.app.page.surface import Surface
from armlab.control.loop import ControlLoop
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import all_finite

#: The reference arm's colour: see-through grey-green, apart from the blue command ghost.
REFERENCE_RGBA = (0.2, 0.75, 0.35, 0.3)
#: The colour of the law's error, and of the status dot while it fails.
ERROR_COLOR = "#b00020"
ERROR_STYLE = f"color:{ERROR_COLOR};font-size:0.85em;white-space:pre-wrap"


def law_loop_of(loop: ControlLoop | None) -> LawLoop | None:
    """``loop`` when it runs a student's law beside the reference, else None."""
    return loop if isinstance(loop, LawLoop) else None


def law_html(law: StudentLaw) -> str:
    """The note where the gains are: the file and what runs, and the error if any."""
    error = law.error
    body = f"<b>{esc(law.note())}</b>"
    body += ("<div style='font-size:0.85em;color:#555'>the green ghost is the lab's own law "
             "on the same commands; the angle chart dashes its angle</div>")
    if error is not None:
        body += f"<div style='{ERROR_STYLE}'>{esc(error_line(law))}</div>"
    return f"<div style='padding:4px 0'>{body}</div>"


def error_line(law: StudentLaw) -> str:
    """One line: the student's file, line and error, and what the arm does meanwhile."""
    error = law.error
    if error is None:
        return ""
    hold = ("torque off: save a fix, then Reset" if law.servos
            else "the arm holds until you save a fix")
    return f"Your law: {error} — {hold}"


class LawView:
    """The page's side of a student's law (see the module docstring).

    Args:
        server: where the ghost is drawn.
        gui: the GUI API; the note is added where the gains are (call inside that tab).
        law: the student's law.
        root: scene node of the reference ghost.
    """

    def __init__(self, server: Surface, gui: viser.GuiApi, law: StudentLaw, *,
                 root: str) -> None:
        self.server = server
        self.law = law
        self.root = root
        self.note = gui.add_html(law_html(law))
        self._shown = law_html(law)
        self._ghost: ArmView | None = None
        self._lock = threading.Lock()
        self._closed = False

    def status_extra(self) -> str:
        """The error line for the status (""), and the note refreshed when it changed."""
        text = law_html(self.law)
        if text != self._shown:
            self._shown = text
            set_content(self.note, text)
        line = error_line(self.law)
        return f"<div style='{ERROR_STYLE}'>{esc(line)}</div>" if line else ""

    def failing_state(self) -> str | None:
        """The status's state while the law fails ("holding: your law failed", shown in
        :data:`ERROR_COLOR`), or None while it runs."""
        if self.law.error is None:
            return None
        return ("stopped: your law failed" if self.law.servos
                else "holding: your law failed")

    def refuse_commands(self, what: str) -> None:
        """Raise ValueError (the page shows it) while the law fails: ``what`` (a command:
        "Run thesis line") would run on a law that does not work."""
        if self.law.error is not None:
            raise ValueError(f"{what} refused while your law fails ({self.law.error}): "
                             "save a fix first")

    def draw(self, loop: LawLoop, model: SerialChain, *, visible: bool = True) -> None:
        """Pose the reference ghost at the reference arm's newest angles (made on first
        use, again for another model)."""
        snap = loop.reference.recorder.snapshot(0.05)
        if len(snap["t"]) == 0 or not all_finite(snap["q"][-1]):
            return
        with self._lock:
            if self._closed:
                return
            ghost = self._ghost
            if ghost is None or ghost.model is not model:
                if ghost is not None:
                    ghost.remove()
                ghost = self._ghost = ArmView(self.server, model, root=self.root,
                                              color=REFERENCE_RGBA)
                ghost.see_through("torso", opacity=0.0)  # the arm only, as the command ghost
            ghost.root.visible = visible
            ghost.set_q(snap["q"][-1])

    def remove(self) -> None:
        """Remove the ghost (the note goes with the lesson's GUI)."""
        with self._lock:
            self._closed = True
            ghost, self._ghost = self._ghost, None
        if ghost is not None:
            ghost.remove()


def reference_angle(loop: LawLoop, t: np.ndarray, joint: int) -> np.ndarray:
    """The reference arm's angle of ``joint`` at the times ``t`` of the student's record
    (rad; NaN where it has none)."""
    ref = loop.reference.recorder.snapshot(float(t[-1] - t[0]) + 1.0 if len(t) else 1.0)
    out = np.full(len(t), np.nan)
    if len(ref["t"]) >= 2 and len(t):
        q = ref["q"][:, joint]
        ok = np.isfinite(q)
        if np.count_nonzero(ok) >= 2:
            out = np.interp(t, ref["t"][ok], q[ok], left=np.nan, right=np.nan)
    return out
