"""A student's hand running in the class's worker process, as the hand lesson drives it.

The class's hands (:class:`armlab.app.workers.class_hands.ClassHands`: one batched plant and
controller, 1 kHz) cost about half a core whatever their number, too much for the server's
interpreter, whose pages would wait behind it. So they run in the class's worker
(:class:`armlab.app.workers.worker_process.ArmProcess`, next to the private arms), and the server
keeps, per hand, a :class:`RemoteHand`: the ``GripLoop`` surface a lesson uses. ``status``,
``params``, ``obj`` and the record (``snapshot``, ``last_grasp``) are mirrored: the worker
sends every hand's new rows and state every :data:`armlab.app.workers.worker_process.MIRROR_S` s.
``post`` goes to the worker's hand and waits for its answer, so a refused command raises here.

Messages (besides the arms', :mod:`armlab.app.workers.worker_process`)::

    server -> worker   ("hand_add", call_id, hand_id, obj, params, history_s)
                       ("hand_post", call_id, hand_id, command)
                       ("hand_free", call_id, hand_id)
    worker -> server   ("hand", [(hand_id, status, rows, params or None,
                                  (obj,) or None)...])
"""

from __future__ import annotations

import dataclasses

import numpy as np

from armlab.app.workers.class_hands import FREED
from armlab.app.workers.worker_link import RemoteMember, WorkerLink
from armlab.control.grip import GripModel, GripParams
from armlab.control.grip_loop import COLUMNS, GripRecord, GripStatus
from armlab.control.ring_buffer import RingBuffer
from armlab.hardware.sim.hand_plant import N_FINGERS, GraspObject


class RemoteHand(RemoteMember, GripRecord):
    """A hand of the worker's :class:`armlab.app.workers.class_hands.ClassHands` (module
    docstring).

    Attributes:
        member_id: its id in the worker.
        model: what its controller knows of the hand.
        params: the grasp's settings in force, as last mirrored.
        obj: the object between the fingers (None: nothing), as last mirrored.
    """

    KIND = "hand"
    FREED = FREED

    def __init__(self, owner: WorkerLink, member_id: int, *, model: GripModel, dt: float,
                 capacity: int, status: GripStatus, params: GripParams,
                 obj: GraspObject | None) -> None:
        super().__init__(owner, member_id)
        self.model = model
        self.dt = dt
        self.params = params
        self.obj = obj
        self._status = status
        self._ring = RingBuffer(1 + N_FINGERS * len(COLUMNS), capacity)

    @property
    def status(self) -> GripStatus:  # type: ignore[override]  # a property over the base's status attribute (read-only here)
        """The hand's newest state (about ``MIRROR_S`` s old); a fault once it was freed, the
        worker has ended or while it has sent nothing for ``STALE_S`` s."""
        why = self._fault()
        st = self._status
        if why is not None:
            return dataclasses.replace(st, running=False, fault=why)
        return st

    def shutdown(self) -> None:
        """Nothing: the hand stays with its student's seat (the seat frees it)."""

    def _mirror(self, status: GripStatus, rows: np.ndarray, params: GripParams | None,
                obj: tuple[GraspObject | None] | None) -> None:
        if len(rows):
            self._ring.extend(rows)
        if params is not None:
            self.params = params
        if obj is not None:
            self.obj = obj[0]
        self._status = status


__all__ = ["RemoteHand"]
