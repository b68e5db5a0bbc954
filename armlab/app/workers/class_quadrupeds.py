"""Private quadrupeds on one clock: every student's copy of the seed 003 quadruped.

The quadruped lesson's own robot is a :class:`armlab.control.gait_loop.GaitLoop` over a
:class:`armlab.hardware.families.dynamixel1.quadruped.QuadrupedSimBackend` (four simulated legs of
AX-12A
servos carrying the body). A copy per student would cost a third of a core each. So the
class's quadrupeds live in one
:class:`armlab.hardware.families.dynamixel1.batched_quadruped.BatchedQuadrupeds`
(one batched plant per group of alike legs, the body's load for every robot at once),
stepped by one :class:`armlab.control.periodic.SharedClock` thread, and each student's
``GaitLoop`` runs on that clock (``clock=``) over a
:class:`armlab.hardware.families.dynamixel1.batched_quadruped.BatchedQuadrupedBackend`: the lesson's
own loop, its
commands, record and eq. 4.1 figures, not a lookalike.

:class:`armlab.app.classroom.sandboxes.Sandboxes` keeps each robot with its student's seat; the
robots run in the class's worker process (:mod:`armlab.app.workers.worker`), mirrored into the
server by :class:`armlab.app.workers.remote_gait.RemoteGait`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from armlab.app.workers.remote_gait import FREED
from armlab.control.commands import Reset
from armlab.control.gait_loop import Command, GaitLoop, SetPlan
from armlab.control.periodic import SharedClock
from armlab.control.restart import RestartableArm
from armlab.control.walking import GaitPlan, GaitSpec, Walker, plan_gait
from armlab.hardware.families.dynamixel1.batched_quadruped import (
    BatchedQuadrupedBackend,
    BatchedQuadrupeds,
)
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import Quadruped

#: s, the gait loop's period (as the lesson's on simulated servos)
PERIOD = 0.02
#: s, the class's plant step and servo tick: the shared robot's is 2 ms
#: (``armlab.hardware.families.dynamixel1.quadruped.SIM_DT``); at 5 ms a class costs 2.5 times less,
#: and the
#: lesson's figures agree with 1 ms within 2 % (eq. 4.1 error and body tilt: the trot at
#: 0.5 and 1.5 cycles/s, the crawl). It divides the body's LOAD_STEP and the period.
CLASS_DT = 5e-3


@dataclass
class ClassQuadruped:
    """One student's robot: its id in the batch, its servos (its
    :class:`BatchedQuadrupedBackend` inside a :class:`RestartableArm` that resets its row
    of the batch) and its gait loop."""

    robot: int
    backend: RestartableArm
    loop: GaitLoop


class ClassQuadrupeds:
    """Every private quadruped of a class on one clock (see the module docstring); the
    clock runs from the start.

    Args:
        realtime: pace the clock by the wall clock (False: as fast as possible, for tests).
        model: the robot (default ``load_robot("quadruped")``).
    """

    def __init__(self, *, realtime: bool = True, model: Quadruped | None = None) -> None:
        self.model = model if model is not None else load_robot("quadruped")
        self.batch = BatchedQuadrupeds(self.model, dt=CLASS_DT)
        self.realtime = realtime
        self.clock = SharedClock(self.batch.step, dt=CLASS_DT, realtime=realtime,
                                 name="armlab-class-quadrupeds", batch_s=0.01,
                                 max_catch_up=0.1)
        self.lock = self.clock.lock
        self._robots: dict[int, ClassQuadruped] = {}
        self.clock.start()

    @property
    def n_robots(self) -> int:
        return len(self._robots)

    def add(self, spec: GaitSpec, *, speed: float, history_s: float) -> ClassQuadruped:
        """A new robot standing in the pose ``spec``'s gait starts from, its loop (speed
        ``speed`` cycles/s) running on the class's clock (ValueError: a gait its legs
        cannot walk, a speed out of range)."""
        plan = plan_gait(spec)
        walker = Walker(plan)
        with self.lock:  # joined and started on the same tick: robot and loop share t = 0
            robot = self.batch.add(walker.state().q)
            servos = BatchedQuadrupedBackend(self.batch, robot, lock=self.lock)
            try:
                backend = self._restartable(servos, walker.state().q)
                loop = GaitLoop(walker, backend, period=PERIOD, realtime=self.realtime,
                                speed=speed, history_s=history_s, clock=self.clock)
            except BaseException:
                self.batch.remove(robot)
                raise
            loop.start()
            made = self._robots[robot] = ClassQuadruped(robot, backend, loop)
            return made

    def _restartable(self, servos: BatchedQuadrupedBackend, q0: np.ndarray
                     ) -> RestartableArm:
        """``servos`` restartable (:class:`RestartableArm`): a restart resets the robot's
        row of the batch in place (:meth:`BatchedQuadrupeds.reset`: at the pose, at rest,
        its time started again in that tick), so the robot keeps its id and the loop's
        periods stay on the same ticks of the clock: robot time = loop time since the
        restart, as at the robot's join. The gait loop applies its Reset before it syncs
        (``sync_first=False``)."""
        def make(q: np.ndarray) -> BatchedQuadrupedBackend:
            with self.lock:
                self.batch.reset(servos.robot, q)
            return servos

        return RestartableArm(make, q0, drop=lambda _b: None, sync_first=False)

    def restart(self, made: ClassQuadruped, q: np.ndarray, plan: GaitPlan,
                timed: Sequence[tuple[int, Command]]) -> int:
        """Start ``made`` again standing at rest at ``q`` (12,) rad, ``plan`` its gait
        (:class:`SetPlan`, then :class:`Reset`, applied in one period), ``timed``'s
        (periods, command) posted that many periods after the restart
        (:meth:`RestartableArm.restart`); the restart's number (ValueError: freed)."""
        with self.lock:  # the three in one period
            if self._robots.get(made.robot) is not made:
                raise ValueError(FREED)
            number = made.backend.restart(q, list(timed), made.loop.post)
            made.loop.post(SetPlan(plan))
            made.loop.post(Reset())
            return number

    def free(self, made: ClassQuadruped) -> None:
        """Stop ``made``'s loop (torque off) and take its robot out (nothing if it is out)."""
        with self.lock:
            if self._robots.pop(made.robot, None) is None:
                return
            made.loop.shutdown(torque_off=True)
            made.backend.close()
            self.batch.remove(made.robot)

    def close(self) -> None:
        """Stop the clock and free every robot."""
        self.clock.stop(timeout=2.0)
        with self.lock:
            for made in list(self._robots.values()):
                self.free(made)


__all__ = ["CLASS_DT", "ClassQuadruped", "ClassQuadrupeds", "PERIOD"]
