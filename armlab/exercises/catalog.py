"""Every exercise by name, and its starter (``armlab/exercises/starters/NAME.py``, package data)."""

from __future__ import annotations

from importlib import resources

from armlab.exercises.control_set import EXERCISES as CONTROL
from armlab.exercises.core import Exercise
from armlab.exercises.kinematics_set import EXERCISES as KINEMATICS

_FK, _JAC, _RMRC, _PLANAR, _LEG, _NULL = KINEMATICS
_PD, _ENV, _COMPLIANCE, _OBSERVER, _STIFFNESS = CONTROL

#: The exercises in course order: kinematics, then control, then the other seeds.
EXERCISES: tuple[Exercise, ...] = (_FK, _JAC, _RMRC, _PD, _ENV, _COMPLIANCE, _OBSERVER,
                                   _STIFFNESS, _PLANAR, _NULL, _LEG)
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
