"""armlab: a browser lab for teaching robot-arm kinematics and compliance control.

The repository's folders are this package's parts: :mod:`armlab.kinematics` (what a
robot is and pure functions of it), :mod:`armlab.control` (controllers, observers,
the control loop, headless experiments), :mod:`armlab.hardware` (servos: the wire,
their tables, the simulation, the emulator, the backends) and :mod:`armlab.app` (the
browser lab and the ``armlab`` command). A notebook needs only what is here::

    import armlab
    arm = armlab.load_robot("receptionist_arm")

and coursework (:mod:`armlab.exercises`) checks a student's function in one call::

    armlab.check(hand_position)   # prints one line per case, returns the report
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from armlab.kinematics import Quadruped, SerialChain, URDFError, load_robot

if TYPE_CHECKING:
    from armlab.exercises import Report

__all__ = ["Quadruped", "SerialChain", "URDFError", "check", "load_robot"]


def check(fn: Callable[..., Any], exercise: str | None = None, *,
          quiet: bool = False) -> Report:
    """Check a student's function against its exercise (``armlab check`` in a notebook).

    The exercise is the one whose function has ``fn``'s name (``hand_position`` is
    ``thesis_fk``), or ``exercise``. Prints one line per case and the summary (unless
    ``quiet``) and returns the :class:`armlab.exercises.Report` (``.passed``, ``.score``).
    """
    from armlab.exercises import check as run_check  # the cases import the control loop

    return run_check(fn, exercise, quiet=quiet)
