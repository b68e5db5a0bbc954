"""Every exercise by name, and its starter (``armlab/exercises/starters/NAME.py``, package data)."""

from __future__ import annotations

from importlib import resources

from armlab.exercises.control_set import COMPLIANCE, ENVIRONMENT, OBSERVER, PD, STIFFNESS
from armlab.exercises.core import Exercise
from armlab.exercises.kinematics_set import (
    FK,
    JACOBIAN,
    LEG_IK,
    NULL_SPACE,
    PLANAR_IK,
    RMRC_STEP,
)

#: The one list of exercises, in course order: the thesis arm's kinematics, then its
#: control, then the other seeds (002's null space, 003's leg, 004's planar arm). An
#: exercise is an :class:`Exercise` value in ``kinematics_set.py`` or ``control_set.py``
#: named here (``tests/test_exercises.py`` fails on one defined but not listed) and its
#: starter ``starters/NAME.py``.
EXERCISES: tuple[Exercise, ...] = (FK, JACOBIAN, RMRC_STEP, PD, ENVIRONMENT, COMPLIANCE,
                                   OBSERVER, STIFFNESS, PLANAR_IK, NULL_SPACE, LEG_IK)
BY_NAME: dict[str, Exercise] = {ex.name: ex for ex in EXERCISES}
BY_FUNCTION: dict[str, Exercise] = {ex.function: ex for ex in EXERCISES}
assert len(BY_FUNCTION) == len(EXERCISES), "each exercise's function needs its own name"


def get(name: str) -> Exercise:
    """The exercise ``name``.

    Raises:
        ValueError: an unknown name (the message lists the known ones).
    """
    try:
        return BY_NAME[name]
    except KeyError:
        raise ValueError(f"no exercise {name!r}; known: {', '.join(BY_NAME)}") from None


def starter_text(name: str) -> str:
    """The starter file of exercise ``name``: its function to fill in, raising
    NotImplementedError until it is."""
    get(name)
    return resources.files("armlab.exercises").joinpath("starters", f"{name}.py").read_text(
        encoding="utf-8")
