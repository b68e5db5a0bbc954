"""Lessons of the browser lab: one module each, whose :class:`Lesson` value (its
``LESSON``) is listed in :data:`armlab.app.lessons.catalog.LESSONS`.

A lesson is a value (:class:`Lesson`) saying:

- ``name``: short id (``"compliance"``), used by ``armlab serve --lesson``;
- ``title``: what the lesson switcher shows, a word or two (at most about 14
  characters: the switcher shows it whole on a projector page; ``help`` says the rest);
- ``help``: one paragraph for the page and ``--help``;
- ``first_step``: the first action, one sentence with the control's label in bold, shown
  under the status line ("Press **Run thesis line** ...");
- ``robots``: robot names the lesson works with (first = its default robot);
  ``ANY_URDF`` in it means any ``.urdf`` file given as the robot;
- ``order`` (default 100): place in the switcher; for a robot the lesson with the
  smallest ``order`` listing it opens first;
- ``build(server: Surface, ctx: LessonContext) -> LessonHandle``: adds the lesson's GUI
  and scene to ``server`` (:class:`armlab.app.page.surface.Surface`: the lab's server, for
  every page, or one student's page) and starts whatever runs behind it (a control
  loop), returning a handle;
- ``private`` (default False): the lesson can be built on one page
  (:class:`armlab.app.classroom.private_page.Page`) with ``ctx.arms``, a student's private
  arm, hand or quadruped ("My arm");
- ``figures``: the names its handle's ``run_figures()`` reports (each with its unit in
  the name: ``_deg``, ``_pct``, ``_s``, ``_n``), and ``overview``, those a class overview
  shows and their columns' heads (default the first four, by name). The overview and the
  challenges ask the lesson for them; no list of every lesson's figures exists.

The handle (:class:`LessonHandle`) is all the lab and the classroom use of a built
lesson: ``close()`` stops what runs (loop shut down, hardware torque off) and removes
everything the lesson added, so another lesson can be opened in the same page;
``estop()`` is what the lab's always-visible E-STOP button calls; ``gui_handles()``,
``gain_controls()`` and ``run_figures()`` are what a classroom hides, copies and shows.
A lesson without one of these parts answers so (no gains: None), as
:class:`armlab.app.lessons._common.LessonBase` does by default.

Making a lesson private takes its own module only: ``private=True``, and its build
drives ``ctx.arms`` (when given) instead of opening a backend of its own.

The other modules (``_common``, ``compliance_plots``, ...) are the lessons' helpers.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from armlab.app.arm.student_law import StudentLaw
    from armlab.app.page.publisher import FrameThread
    from armlab.app.page.surface import Surface
    from armlab.app.workers.remote_gait import RemoteGait
    from armlab.app.workers.remote_hand import RemoteHand
    from armlab.app.workers.worker_process import ArmProcess
    from armlab.control.backend import Backend
    from armlab.control.grip import GripParams
    from armlab.control.loop import ControlLoop
    from armlab.control.params import Params
    from armlab.control.walking import GaitSpec
    from armlab.hardware.sim.hand_plant import GraspObject
    from armlab.kinematics.model import SerialChain



@dataclass(frozen=True)
class LessonContext:
    """What a lesson is built for (from ``armlab serve``'s options).

    Attributes:
        robot: robot name (``kinematics.load_robot``).
        backend: "sim" or "serial".
        port: serial device for "serial".
        baud: serial baud rate (None: the backend's default).
        realtime: run loops against the wall clock (False: as fast as possible).
        tip_link: for a URDF robot, its end-effector link (None: the file's default).
        package_paths: folders holding the URDF's ``package://`` meshes.
        joint_map: joint map file for "serial" (None: the robot's default map).
        arms: a student's private arm (:class:`ArmSource`): the lesson drives it instead
            of opening a backend and a loop of its own (None: the shared arm).
        arm_process: where the shared simulated arm runs in a classroom (a worker
            process of its own, :class:`armlab.app.workers.worker_process.ArmProcess`; None: in
            the server, as outside a classroom and on real servos).
        frames: the thread that makes the lesson's frames, shared with other lessons (a
            classroom's private pages share one; None: a thread of the lesson's own).
        law: a student's own law (``armlab serve --exercise``): a servo-arm lesson's loop
            runs it in place of the lab's, beside a reference arm (None: the lab's own).
        who: client id -> the name that page goes by in a class (None: no class); a run
            file says who saved it.
        kept: what this lesson kept when it was last closed in this lab (its
            :meth:`LessonHandle.keep`: its gains, link lengths and measurements), so that a
            switch away and back loses nothing; None: a first open.
    """

    robot: str = "receptionist_arm"
    backend: str = "sim"
    port: str | None = None
    baud: int | None = None
    realtime: bool = True
    tip_link: str | None = None
    package_paths: tuple[str, ...] = ()
    joint_map: str | None = None
    arms: ArmSource | None = None
    arm_process: ArmProcess | None = None
    frames: FrameThread | None = None
    law: StudentLaw | None = None
    who: Callable[[int], str] | None = None
    kept: object | None = None


class ArmSource(Protocol):
    """Where a private lesson gets its arm (``armlab.app.classroom.sandboxes.Seat``) or the arm's
    hand:
    kept across the lesson's closing, so a reload of the page finds the same one."""

    def kept(self) -> tuple[str, Params] | None:
        """(link preset, gains) of the arm already there, or None."""
        ...

    def arm_for(self, model: SerialChain, params: Params, *, preset: str, q0: np.ndarray,
                history_s: float) -> tuple[Backend, ControlLoop]:
        """The arm for ``preset`` (the kept one, or a new one at ``q0``), its loop running."""
        ...

    def hand_for(self, obj: GraspObject, params: GripParams, *,
                 history_s: float) -> RemoteHand:
        """The student's hand (the kept one, or a new one, open, around ``obj``), running."""
        ...

    def quadruped_for(self, spec: GaitSpec, *, speed: float, history_s: float) -> RemoteGait:
        """The student's quadruped (the kept one, or a new one standing), its loop running."""
        ...


#: In a lesson's ``ROBOTS``: it works with any serial arm given as a ``.urdf`` file.
ANY_URDF = "*.urdf"


#: A lesson's figures of its last runs, by name: each its :attr:`Lesson.figures` declares,
#: None until measured. What the class overview (its :attr:`Lesson.overview` of them), the
#: challenges (a challenge judges figures its lesson declares) and Save run read.
Figures = Mapping[str, float | None]


class Gains(Protocol):
    """A lesson's gain controls: the gains its arm runs, and setting them as a person does."""

    @property
    def params(self) -> Params:
        """The gains in force."""
        ...

    def set_params(self, params: Params) -> None:
        """Put ``params`` in force and on the controls (raises ValueError to refuse them,
        the message saying why)."""
        ...


@runtime_checkable
class LessonHandle(Protocol):
    """What ``build`` returns: a built lesson, as the lab and the classroom use it."""

    def close(self) -> None:
        """Stop the lesson and remove its GUI and scene nodes."""
        ...

    def estop(self) -> None:
        """Torque off now (the lab's E-STOP button); never raises. Nothing to stop: nothing."""
        ...

    def keep(self) -> object | None:
        """What the lesson hands its next opening in this lab (``LessonContext.kept``),
        taken just before it closes: its settings and measurements (None: nothing)."""
        ...

    def gui_handles(self) -> tuple[Any, ...]:
        """The lesson's top-level GUI elements (hiding them hides the whole lesson panel)."""
        ...

    def gain_controls(self) -> Gains | None:
        """The gains of the lesson's arm, to read and set (None: the lesson has none)."""
        ...

    def run_figures(self) -> Figures:
        """The figures of the last runs: each of its module's ``FIGURES`` (None: not
        measured yet; {}: the lesson declares none)."""
        ...

    def page_only_buttons(self) -> tuple[Any, ...]:
        """Buttons that change nothing shared and answer only the page that pressed them
        (Save run, Export page, a CSV download): in a classroom any page may press them."""
        ...


@dataclass(frozen=True)
class Lesson:
    """One lesson of the lab, as the switcher, ``--help``, the classroom and the challenges
    ask it (the package's docstring says what each field is for)."""

    name: str
    title: str
    help: str
    first_step: str
    robots: tuple[str, ...]
    build: Callable[[Surface, LessonContext], LessonHandle]
    order: float = 100.0
    private: bool = False
    figures: tuple[str, ...] = ()
    overview: Mapping[str, str] | None = None

    def works_with(self, robot: str) -> bool:
        """Whether the lesson lists ``robot`` (or ``ANY_URDF`` and robot is a .urdf)."""
        return robot in self.robots or (ANY_URDF in self.robots
                                        and robot.lower().endswith(".urdf"))

    def figures_of(self, **values: float | None) -> dict[str, float | None]:
        """The lesson's figures (its :attr:`figures`, in order), each None unless given.

        Raises:
            ValueError: a figure the lesson does not declare.
        """
        unknown = sorted(set(values) - set(self.figures))
        if unknown:
            raise ValueError(f"lesson {self.name}: {', '.join(unknown)} not among its figures")
        return {key: values.get(key) for key in self.figures}

    def overview_figures(self) -> dict[str, str]:
        """The figures a class overview shows, each with its column's head (its
        :attr:`overview`; else its first four :attr:`figures`, headed by their names)."""
        if self.overview is not None:
            return dict(self.overview)
        return {key: key for key in self.figures[:4]}

    @property
    def sort_key(self) -> tuple[float, str]:
        """Its place in the switcher: :attr:`order`, then its title."""
        return (self.order, self.title)
