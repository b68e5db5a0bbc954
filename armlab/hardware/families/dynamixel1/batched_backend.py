"""``BatchedArmBackend``: the :class:`armlab.control.backend.Backend` protocol over one arm of a
:class:`armlab.hardware.families.dynamixel1.batched_plant.BatchedPlant` (a student's private arm in
a class).

It is :class:`armlab.hardware.families.dynamixel1.sim_backend.SimBackend` for one arm (by its id) of
a plant that
many arms share: the same joint limits and goal clamping (:class:`GoalLimits`), the same
raw words written and read and the same decoding
(:func:`~armlab.hardware.families.dynamixel1.sim_backend.raw_goals`;
:func:`~armlab.hardware.families.dynamixel1.sim_backend.decode_reports` looked up in tables of every
word's decoded
value, :func:`word_tables`: a class reads hundreds of arms a second), the same torque,
e-stop, close and push semantics, and a wall of its own
(:class:`armlab.control.backend.Touchable`, kept by the plant's
:class:`~armlab.hardware.families.dynamixel1.batched_walls.BatchedWalls`). One
difference: :meth:`BatchedArmBackend.sync` does not step the plant. A shared clock
(:class:`armlab.control.periodic.SharedClock`) steps the whole plant once per ``dt``
and runs each arm's control period when it is due, so the plant is already at the loop's
time; ``sync`` only records it.

Every method that touches the plant holds the ``lock`` given (the one the clock's
thread holds while it steps), so a UI thread may e-stop or push an arm at any time.

An arm's life (the owner's part)::

    arm = add_sim_arm(plant, q0=q0, lock=lock)
    walls = BatchedWalls(plant)  # once per plant: the clock steps walls.step
    loop = ControlLoop(model, BatchedArmBackend(plant, arm, lock=lock, walls=walls),
                       params, clock=clock)
    loop.start()                 # attached: its periods run on the clock
    ...
    loop.shutdown()              # detached after the clock's current tick
    loop.backend.close()
    with lock:
        walls.forget(arm)
        plant.remove_arm(arm)
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from armlab.control.backend import BackendError, GoalLimits, JointState, WallSetting
from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant, ReportWords
from armlab.hardware.families.dynamixel1.batched_walls import BatchedWalls
from armlab.hardware.families.dynamixel1.firmware import ServoRegisters, ServoReport
from armlab.hardware.families.dynamixel1.sim_backend import raw_goals, servo_limits, sim_registers
from armlab.hardware.servos.servo_spec import ServoSpec
from armlab.kinematics.validate import scalar, vector

if TYPE_CHECKING:
    from armlab.control.periodic import HandOverLock

POSITION_WORDS = 1024  #: Present Position words 0..1023
SIGNED_WORDS = 2048  #: Present Speed / Present Load words: magnitude 0..1023, bit 10 = CW


#: Per joint: its decoded Present Position, Present Speed and Present Load, by raw word.
WordTables = tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]


@functools.cache
def word_tables(spec: ServoSpec, direction: float) -> WordTables:
    """Every Present Position, Present Speed and Present Load word of ``spec`` decoded for
    a joint of ``direction`` as
    :func:`~armlab.hardware.families.dynamixel1.sim_backend.decode_reports` decodes it
    (``direction · spec.raw_to_position(word)`` rad, ``raw_to_present_speed`` rad/s,
    ``raw_to_load`` N·m), indexed by the word: a lookup gives the same floats as the
    conversion (computed by it), for a fraction of its cost."""
    d = float(direction)
    return (tuple(d * spec.raw_to_position(w) for w in range(POSITION_WORDS)),
            tuple(d * spec.raw_to_present_speed(w) for w in range(SIGNED_WORDS)),
            tuple(d * spec.raw_to_load(w) for w in range(SIGNED_WORDS)))


def decode_words(words: ReportWords, tables: Sequence[WordTables], t: float) -> JointState:
    """An arm's report words (:meth:`BatchedPlant.report_words`) as the controller sees them,
    through each joint's :func:`word_tables`: what
    :func:`~armlab.hardware.families.dynamixel1.sim_backend.decode_reports`
    makes of the same words."""
    position, velocity, load = [], [], []  # one pass in Python: a few joints, every period
    for tb, x, v, f in zip(tables, words.position, words.speed, words.load, strict=True):
        position.append(tb[0][x])
        velocity.append(tb[1][v])
        load.append(tb[2][f])
    errors = tuple(words.error)
    return JointState(
        t=t, position=np.array(position), velocity=np.array(velocity), load=np.array(load),
        errors=errors, torque_on=tuple(map(bool, words.torque_enable)),
        alarms=(tuple(map(p1.error_names, errors)) if any(errors)
                else ("ok",) * len(errors)))  # healthy: error_names(0) each


def add_sim_arm(plant: BatchedPlant, *, q0: np.ndarray | None = None,
                torque_on: bool = True, lock: threading.RLock | None = None) -> int:
    """Add an arm to ``plant`` configured as a fresh :class:`SimBackend`'s (thesis
    registers, Angle Limits at the joint limits, goal at ``q0`` (n,) rad, default
    neutral; torque on unless ``torque_on`` is False), holding ``lock`` when given (the
    clock's, while it may be stepping). Returns its id."""
    q, regs = _sim_arm(plant, q0, torque_on)
    if lock is None:
        return plant.add_arm(q0=q, registers=regs)
    with lock:
        return plant.add_arm(q0=q, registers=regs)


def reset_sim_arm(plant: BatchedPlant, arm: int, *, q0: np.ndarray | None = None,
                  torque_on: bool = True) -> None:
    """Arm ``arm`` of ``plant`` made again in its row as :func:`add_sim_arm` makes a new one
    (:meth:`BatchedPlant.reset_arm`: at ``q0``, at rest, its registers fresh)."""
    q, regs = _sim_arm(plant, q0, torque_on)
    plant.reset_arm(arm, q0=q, registers=regs)


def _sim_arm(plant: BatchedPlant, q0: np.ndarray | None, torque_on: bool
             ) -> tuple[np.ndarray, list[ServoRegisters]]:
    """A fresh simulated arm's pose and registers (:func:`add_sim_arm`)."""
    lower, upper = servo_limits(plant.model, plant.specs, plant.directions)
    q = plant.model.neutral() if q0 is None else vector("q0", q0, plant.n)
    return q, sim_registers(plant.specs, plant.directions, lower, upper, q,
                            torque_on=torque_on)


class ArmOfPlant:
    """One arm of a :class:`BatchedPlant` read as a :class:`~armlab.hardware.sim.plant.Plant` is by
    the lab's panels (``SimBackend.plant``: the Servos panel calls ``reports()``); every
    read holds ``lock``.

    Attributes:
        batch: the shared plant. arm: the arm's id.
    """

    def __init__(self, batch: BatchedPlant, arm: int,
                 lock: threading.RLock | HandOverLock) -> None:
        self.batch = batch
        self.arm = arm
        self._lock = lock

    @property
    def n(self) -> int:
        return self.batch.n

    @property
    def t(self) -> float:
        """The shared plant's time, s."""
        return self.batch.t

    @property
    def q(self) -> np.ndarray:
        """(n,) the arm's true joint positions, rad."""
        with self._lock:
            return self.batch.q[self.batch.row(self.arm)]

    @property
    def qd(self) -> np.ndarray:
        """(n,) the arm's true joint velocities, rad/s."""
        with self._lock:
            return self.batch.qd[self.batch.row(self.arm)]

    def reports(self) -> tuple[ServoReport, ...]:
        """The arm's servo reports in joint order (raw words)."""
        with self._lock:
            return self.batch.reports(self.arm)


class BatchedArmBackend(GoalLimits):
    """Arm id ``arm`` of ``plant`` behind the ``Backend``, ``Pushable`` and ``Touchable``
    protocols.

    Args:
        plant: the shared plant (the caller adds the arm first, e.g. :func:`add_sim_arm`,
            and removes it after :meth:`close`).
        arm: the arm's id in ``plant``.
        lock: held around every use of the plant (the shared clock holds it while it
            steps).
        walls: the plant's walls (:class:`BatchedWalls`, stepped by the clock in the
            plant's place): this arm's wall is set and its force read there, the arm's
            own and no other's (None: the arm takes no wall, ``set_wall`` refuses one).

    Attributes:
        batch: the shared :class:`BatchedPlant`.
        plant: this arm of it as the panels read ``SimBackend.plant`` (:class:`ArmOfPlant`:
            ``reports()``, ``q``, ``qd``, ``t``).

    The torque limits restored by ``set_torque(True)`` after an overload shutdown are
    the arm's Torque Limit registers when the backend is made. Time (``read().t``) is
    the plant's time since the backend was made.
    """

    def __init__(self, plant: BatchedPlant, arm: int, *,
                 lock: threading.RLock | HandOverLock,
                 walls: BatchedWalls | None = None) -> None:
        if walls is not None and walls.plant is not plant:
            raise ValueError("walls: the walls of another plant")
        self.batch = plant
        self.walls = walls
        self.plant = ArmOfPlant(plant, int(arm), lock)
        self.arm = int(arm)
        self.specs = plant.specs
        self.directions = plant.directions
        self._lock = lock
        self._lower, self._upper = servo_limits(plant.model, plant.specs, plant.directions)
        self._tables = [word_tables(s, d) for s, d in zip(self.specs, self.directions,
                                                          strict=True)]
        with lock:
            self._torque_limits = tuple(r.torque_limit for r in plant.registers(self.arm))
            self._k0 = plant.steps
        self._t = 0.0
        self._closed = False

    # -- Backend protocol ---------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.batch.n

    @property
    def t(self) -> float:
        """The loop time of the last :meth:`sync`, s."""
        return self._t

    def sync(self, t: float) -> None:
        """Record the loop time ``t`` s; the shared clock has stepped the plant to it."""
        t = scalar("t", t)
        with self._lock:
            self._check_open()
            self._t = t

    def read(self) -> JointState:
        """Every joint as its servo reports it (decoded raw words, quantised)."""
        with self._lock:
            self._check_open()
            words = self.batch.report_words(self.arm)
            t = (self.batch.steps - self._k0) * self.batch.dt
        return decode_words(words, self._tables, t)

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Goal positions (n,) rad and moving speeds (n,) rad/s -> Goal Position/Moving
        Speed words (:meth:`SimBackend.write`: clamped; bad input raises, nothing written)."""
        self.write_checked(*self.checked_goal(position, speed))

    def write_checked(self, position: np.ndarray, speed: np.ndarray) -> None:
        """:meth:`write` of goals already checked and clamped (``checked_goal``)."""
        goals, speeds = raw_goals(self.specs, self.directions, position, speed)
        with self._lock:
            self._check_open()
            self.batch.set_goal(self.arm, goals, speeds)

    def set_torque(self, on: bool) -> None:
        """Torque Enable on every servo; switching on restores a Torque Limit an overload
        shutdown set to 0 (as :meth:`SimBackend.set_torque`)."""
        with self._lock:
            self._check_open()
            regs = self.batch.registers(self.arm)
            for j, (r, limit) in enumerate(zip(regs, self._torque_limits, strict=True)):
                if on and r.torque_limit == 0:
                    self.batch.set_registers(self.arm, j, torque_limit=limit)
            self.batch.set_registers(self.arm, torque_enable=int(bool(on)))

    def estop(self) -> bool:
        """Torque off on every servo of this arm now; never raises. True (nothing can be
        lost; an arm already removed from the plant holds no torque either)."""
        with self._lock:
            try:
                self.batch.set_registers(self.arm, torque_enable=0)
            except ValueError:  # the owner removed the arm
                pass
        return True

    def close(self) -> None:
        """Release the backend; later calls raise BackendError (the arm stays in the plant,
        its torque as it is: the owner removes it)."""
        with self._lock:
            self._closed = True

    # -- Pushable -----------------------------------------------------------------

    def push(self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float) -> None:
        """Apply ``force`` (3,) N, base frame, at ``point`` (3,) m in link ``link``'s frame
        for ``duration`` s of simulated time from now."""
        with self._lock:
            self.batch.push(self.arm, force, link=link, point=point, duration=duration)

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """Pull ``point`` on ``link`` towards ``anchor`` (3,) m, base frame, with
        ``stiffness`` N/m; None releases it."""
        with self._lock:
            self.batch.set_spring(self.arm, anchor, stiffness=stiffness, link=link,
                                  point=point)

    # -- Touchable ----------------------------------------------------------------

    def set_wall(self, origin: np.ndarray | None, normal: np.ndarray | None = None, *,
                 stiffness: float, damping: float, friction: float = 0.0,
                 size: tuple[float, float, float] | None = None) -> None:
        """A plane (``size`` None: the hand's tip meets it) or a box (the tip and the
        links' collision shapes meet it) this arm touches
        (``armlab.control.backend.Touchable``): ``origin`` (3,) m on its face, ``normal``
        (3,) towards the free side, both base frame, with Coulomb ``friction`` μ along
        it; None removes it. The other arms of the plant never meet it.

        Raises:
            ValueError: a bad argument (the wall as it was), or a backend made without
                ``walls``.
        """
        if self.walls is None:
            raise ValueError("this simulated arm takes no wall (its plant's walls were not "
                             "given: BatchedArmBackend(walls=...))")
        with self._lock:
            self._check_open()
            self.walls.set(self.arm, origin, normal, stiffness=stiffness, damping=damping,
                           friction=friction, size=size)

    def wall_force(self) -> float:
        """N, the wall's normal force on this arm's hand now (0: off it, or no wall)."""
        if self.walls is None:
            return 0.0
        with self._lock:
            return self.walls.force(self.arm)

    def wall_peak(self) -> float:
        """N, the largest wall force on this arm's hand at any plant step since the last
        call."""
        if self.walls is None:
            return 0.0
        with self._lock:
            return self.walls.peak(self.arm)

    def wall_setting(self) -> WallSetting | None:
        """This arm's wall now (None: none)."""
        if self.walls is None:
            return None
        with self._lock:
            return self.walls.setting(self.arm)

    def _check_open(self) -> None:
        if self._closed:
            raise BackendError("the simulated arm is closed; open a new backend")
