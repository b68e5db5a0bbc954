"""A student's quadruped running in the class's worker process, as the quadruped lesson
drives it.

The class's quadrupeds (:class:`armlab.app.workers.class_quadrupeds.ClassQuadrupeds`: batched leg
plants and every robot's ``GaitLoop`` on one clock) run in the class's worker
(:class:`armlab.app.workers.worker_process.ArmProcess`), off the server's interpreter. The server
keeps, per robot, a :class:`RemoteGait`: the ``GaitLoop`` surface a lesson uses. ``status``,
``state`` (what the scene draws), the walked gait's spec and the record (``snapshot``,
``angle_error``) are mirrored every :data:`armlab.app.workers.worker_process.MIRROR_S` s;
commands go to the worker's loop and wait for its answer. Its messages are the hand's
(:mod:`armlab.app.workers.remote_hand`) with ``quad`` for ``hand``; a mirror item is
``(robot_id, status, rows, state, spec or None)``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from armlab.app.workers.worker_link import ESTOP_TIMEOUT_S, RemoteMember, WorkerLink
from armlab.control.backend import BackendError
from armlab.control.gait_loop import COLUMNS, Command, GaitRecord, GaitStatus
from armlab.control.ring_buffer import RingBuffer
from armlab.control.walking import GaitPlan, GaitSpec, WalkState

#: what a freed robot's status says
FREED = "this quadruped was freed (a reload of the page makes a new one)"


class RemoteGait(RemoteMember, GaitRecord):
    """A robot of the worker's :class:`armlab.app.workers.class_quadrupeds.ClassQuadrupeds`
    (module docstring).

    Attributes:
        member_id: its id in the worker.
        spec: the gait it walks (or will from its next cycle), as last mirrored.
        freed: set when its seat let it go.
    """

    KIND = "quad"
    FREED = FREED

    def __init__(self, owner: WorkerLink, member_id: int, *, capacity: int,
                 status: GaitStatus, state: WalkState, spec: GaitSpec) -> None:
        super().__init__(owner, member_id)
        self.spec = spec
        self.state = state
        self._status = status
        self._ring = RingBuffer(sum(COLUMNS.values()), capacity)

    def estop(self) -> None:
        """Torque off at the worker's loop's next period; never raises (waits at most
        ``ESTOP_TIMEOUT_S`` s for the worker)."""
        try:
            self._owner.call("quad_estop", self.member_id, timeout=ESTOP_TIMEOUT_S)
        except (BackendError, ValueError):  # gone, freed (no torque) or not answering
            pass

    @property
    def status(self) -> GaitStatus:  # type: ignore[override]  # a property over the base's status attribute (read-only here)
        """The loop's newest status (about ``MIRROR_S`` s old); a fault once freed, once the
        worker has ended, or while it has sent nothing for ``STALE_S`` s."""
        why = self._fault()
        st = self._status
        if why is not None:
            return dataclasses.replace(st, running=False, servos=False, fault=why)
        return st

    def restart(self, q: np.ndarray, plan: GaitPlan,
                timed: list[tuple[int, Command]]) -> int:
        """Start the robot again in the worker standing at rest at ``q`` (12,) rad, at the
        origin, walking ``plan`` from its start, ``timed``'s (periods, command) posted
        that many periods after the restart
        (:meth:`armlab.app.workers.class_quadrupeds.ClassQuadrupeds.restart`); the
        restart's number (``status.restarts`` reaches it in the restart's period, whose
        loop time is ``status.restarted_at``)."""
        return int(self._owner.call("quad_restart", self.member_id,
                                    np.asarray(q, dtype=float), plan, list(timed)))

    def cancel_plan(self) -> None:
        """Post nothing more of the last restart's ``timed`` commands (its run was cut
        short); nothing when it was freed or the worker is gone (nothing posts then)."""
        try:
            self._owner.call("quad_cancel", self.member_id)
        except (BackendError, ValueError):
            pass

    def shutdown(self, *, torque_off: bool = True) -> None:
        """Nothing: the robot stays with its student's seat (the seat frees it)."""

    def _mirror(self, status: GaitStatus, rows: np.ndarray, state: WalkState,
                spec: GaitSpec | None) -> None:
        if len(rows):
            self._ring.extend(rows)
        self.state = state
        if spec is not None:
            self.spec = spec
        self._status = status


__all__ = ["FREED", "RemoteGait"]
