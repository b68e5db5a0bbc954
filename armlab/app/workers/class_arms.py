"""Private arms on one clock: the class's simulation, without the seats that own the arms.

The arms of one link-length preset live in one
:class:`armlab.hardware.families.dynamixel1.batched_plant.BatchedPlant`
(numpy over arms); one :class:`armlab.control.periodic.SharedClock` thread steps every plant at
1 kHz and, in the same thread, each arm's :class:`armlab.control.loop.ControlLoop` when its
period is due. A loop is the lesson's own (commands, trajectories, the step test,
pushes, drags, recording, faults) over a
:class:`armlab.hardware.families.dynamixel1.batched_backend.BatchedArmBackend`:
one arm of the plant behind the ``Backend`` protocol, with a wall of its own (``Touchable``:
the Contact tab's, the contact challenge's; each plant's
:class:`armlab.hardware.families.dynamixel1.batched_walls.BatchedWalls`, which the clock
steps in the plant's place, keeps each wall's force and its peak at every step). So a
private arm is the shared lesson's arm, not a lookalike, and a hundred of them cost one
thread. An arm that ships
with servos of a family with its own firmware model (X-series: the OpenManipulator-X,
:class:`armlab.hardware.families.xseries.sim_backend.XSimBackend`; Feetech STS: the SO-101,
:class:`armlab.hardware.families.feetech.sim_backend.StsSimBackend`) is simulated with it as its
shared arm is (``make_backend("sim", ...)``, without the gripper: a plant of its own that its loop
steps, on the same clock): the batched plant models protocol-1.0 servos only.

:class:`armlab.app.classroom.sandboxes.Sandboxes` holds the seats; it runs the batched arms in a
process of their own (:mod:`armlab.app.workers.worker_process`, whose worker
:mod:`armlab.app.workers.worker` hosts a
``ClassArms``) and the X-series and STS ones in a ``ClassArms`` of its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.app.arm.backends import has_firmware_sim, loop_over, make_backend
from armlab.control.backend import Backend
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.periodic import SharedClock
from armlab.control.restart import RestartableArm
from armlab.hardware.families.dynamixel1.batched_backend import BatchedArmBackend, add_sim_arm
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.families.dynamixel1.batched_walls import BatchedWalls
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics.model import SerialChain

#: plant step, s (as the shared arm's SimBackend)
DT = 1e-3


@dataclass
class Arm:
    """One private arm of a :class:`ClassArms`.

    Attributes:
        preset: the link-length preset it was made for.
        row: its id in the preset's batched plant (None: a plant of its own).
        backend, loop: what the lesson drives (the loop runs on the class's clock).
    """

    preset: str
    row: int | None
    backend: Backend
    loop: ControlLoop


class ClassArms:
    """Private arms stepped together (see the module docstring); the clock runs from the
    start.

    Args:
        realtime: step against the wall clock (False: as fast as possible, for tests).

    Attributes:
        clock: the :class:`SharedClock` every arm's loop runs on.
        lock: the clock's lock (held while it ticks; taken to add and free arms).
    """

    def __init__(self, *, realtime: bool = True) -> None:
        self._plants: dict[str, BatchedPlant] = {}
        #: each plant's walls (one per arm: the Contact tab's, a challenge's), stepped in
        #: its place so that each wall's peak force is kept at every step
        self._walls: dict[str, BatchedWalls] = {}
        self.clock = SharedClock(self._step, dt=DT, realtime=realtime, name="armlab-class")
        self.lock = self.clock.lock  # a HandOverLock: a waiting thread gets in between ticks
        self.clock.start()

    def _step(self) -> None:
        for walls in self._walls.values():
            walls.step()

    def add(self, model: SerialChain, params: Params, *, preset: str, q0: np.ndarray,
            history_s: float) -> Arm:
        """A new arm of ``model`` (link lengths ``preset``) at ``q0`` (n,) rad with gains
        ``params``, its compliance loop (``history_s`` s recorded) started on the clock."""
        with self.lock:
            plant: BatchedPlant | None = None
            if has_firmware_sim(model):  # X-series, STS: their firmware model, own plant
                backend = make_backend("sim", model, dt=DT, q0=q0, gripper=None)
                row = None
            else:
                plant = self._plants.get(preset)
                if plant is None:
                    plant = self._plants[preset] = BatchedPlant(model, RX24F, dt=DT)
                    self._walls[preset] = BatchedWalls(plant)
                backend = _restartable_arm(self._walls[preset], q0, self.lock)
                row = backend.arm
            try:
                loop = loop_over(backend, model, params, history_s=history_s, clock=self.clock)
            except BaseException:  # (the backend is closed)
                if plant is not None and row is not None:
                    self._walls[preset].forget(backend.arm)  # type: ignore[attr-defined]  # row set: the batched plant's backend
                    plant.remove_arm(backend.arm)  # type: ignore[attr-defined]  # row set: the batched plant's backend
                raise
            loop.start()
            return Arm(preset, row, backend, loop)

    def free(self, arm: Arm) -> None:
        """Stop ``arm``'s loop (torque off), close its backend and take it out of its plant."""
        with self.lock:
            arm.loop.shutdown(torque_off=True)
            arm.backend.close()
            if arm.row is not None:  # (the arm's id now: a restart makes a new one)
                row = getattr(arm.backend, "arm", arm.row)
                self._walls[arm.preset].forget(row)
                self._plants[arm.preset].remove_arm(row)

    def close(self, arms: list[Arm] | tuple[Arm, ...] = ()) -> None:
        """Stop the clock, then free ``arms`` (the ones still held).

        The arms are freed holding the lock, after the clock stopped: a tick that stepped
        a plant while one of its arms was taken out would leave the plant's arrays of
        different widths."""
        self.clock.stop()
        with self.lock:
            for arm in arms:
                self.free(arm)


def _restartable_arm(walls: BatchedWalls, q0: np.ndarray, lock: Any) -> RestartableArm:
    """A new arm of ``walls``' plant at ``q0`` that a challenge's run can start again at a
    pose (:class:`RestartableArm`: a fresh arm of the plant in its place, the old one and
    its wall taken out, the fresh one meeting the wall it names; ``lock`` is the clock's,
    held while it ticks)."""
    plant = walls.plant

    def make(q: np.ndarray) -> BatchedArmBackend:
        return BatchedArmBackend(plant, add_sim_arm(plant, q0=q, lock=lock), lock=lock,
                                 walls=walls)

    def drop(old: Any) -> None:
        old.close()
        with lock:
            walls.forget(old.arm)
            plant.remove_arm(old.arm)

    return RestartableArm(make, q0, drop=drop)


class OwnArms:
    """Arms each on a thread of its own, as a lesson runs its arm in the server: a
    :class:`armlab.hardware.families.dynamixel1.sim_backend.SimBackend` and a paced ``ControlLoop``
    per arm (the
    shared arm of a classroom, in a process of its own: :mod:`armlab.app.workers.worker_process`).

    Args:
        realtime: pace each loop by the wall clock (False: as fast as possible).
    """

    def __init__(self, *, realtime: bool = True) -> None:
        self.realtime = realtime

    def add(self, model: SerialChain, params: Params, *, preset: str, q0: np.ndarray,
            history_s: float) -> Arm:
        """A new simulated arm of ``model`` at ``q0`` (n,) rad, its compliance loop
        started (``preset`` names it)."""
        backend = RestartableArm(lambda q: make_backend("sim", model, q0=q), q0)
        loop = loop_over(backend, model, params, realtime=self.realtime,
                         history_s=history_s)
        loop.start()
        return Arm(preset, None, backend, loop)

    def free(self, arm: Arm) -> None:
        """Stop ``arm``'s loop with torque off and close its backend."""
        try:
            arm.loop.shutdown(torque_off=True)
            arm.backend.estop()
        finally:
            arm.backend.close()

    def close(self, arms: list[Arm] | tuple[Arm, ...] = ()) -> None:
        """Free ``arms`` (the ones still held)."""
        for arm in arms:
            self.free(arm)
