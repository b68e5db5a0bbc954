"""Every lesson of the lab, in one list (adding a lesson: its module's ``LESSON`` here)."""

from __future__ import annotations

from armlab.app.lessons import Lesson, arm, compliance, hand, ik_accuracy, quadruped, redundancy

#: The lessons, each its module's :class:`~armlab.app.lessons.Lesson` value.
LESSONS: tuple[Lesson, ...] = (arm.LESSON, compliance.LESSON, hand.LESSON, ik_accuracy.LESSON,
                               quadruped.LESSON, redundancy.LESSON)


def all_lessons() -> dict[str, Lesson]:
    """Every lesson of :data:`LESSONS`, keyed by its name."""
    return {lesson.name: lesson for lesson in LESSONS}


def default_lesson(robot: str) -> str:
    """Name of the lesson to open for ``robot`` (lowest ``order`` among those listing it).

    Raises:
        ValueError: when no lesson works with ``robot`` (the message lists the robots
            that have one).
    """
    for lesson in sorted(LESSONS, key=lambda lesson: lesson.sort_key):
        if lesson.works_with(robot):
            return lesson.name
    robots = sorted({r for lesson in LESSONS for r in lesson.robots})
    raise ValueError(f"robot: no lesson for {robot!r}; lessons exist for {', '.join(robots)}")
