"""What the server's proxy of something running in a worker process needs of that worker.

:class:`armlab.app.workers.worker_process.ArmProcess` is the worker; its arms' proxies live
beside it, and the class's hands and quadrupeds have theirs
(:mod:`armlab.app.workers.remote_hand`,
:mod:`armlab.app.workers.remote_gait`), which know the worker only as a :class:`WorkerLink`.
"""

from __future__ import annotations

from typing import Any, Protocol

#: s a call waits for the worker's answer
CALL_TIMEOUT_S = 20.0
#: s an E-STOP waits for the worker's answer (then it says it could not be sure)
ESTOP_TIMEOUT_S = 2.0


class WorkerLink(Protocol):
    """A worker process as its members' proxies use it."""

    @property
    def ended(self) -> str | None:
        """Why the worker is gone (None while it runs)."""
        ...

    def silent(self) -> str | None:
        """Why its members' state is not known now (it sent nothing for a while), or None."""
        ...

    def call(self, op: str, member_id: int, *args: object,
             timeout: float = CALL_TIMEOUT_S) -> Any:
        """Run ``op`` on member ``member_id`` in the worker and return its answer (its
        exception raised here; ``BackendError``: the worker has ended or not answered)."""
        ...


class RemoteMember:
    """What a proxy of a worker's member (a hand, a quadruped) does whatever it is: its
    commands go to the worker as ``KIND_post`` calls, and its mirrored state is told as a
    fault once it was freed, once the worker has ended, or while the worker is silent.

    A subclass names its :attr:`KIND` (the worker's ops and mirror messages carry it) and
    what its status says once freed (:attr:`FREED`).
    """

    KIND = ""
    FREED = ""

    def __init__(self, owner: WorkerLink, member_id: int) -> None:
        self._owner = owner
        self.member_id = member_id
        self.freed = False  #: set when its seat let it go (the worker's member is gone)

    def _send(self, command: object) -> None:
        """To the worker's member, waiting for its answer (ValueError: refused or freed;
        ``BackendError``: the worker has ended or does not answer)."""
        self._owner.call(f"{self.KIND}_post", self.member_id, command)

    def _fault(self) -> str | None:
        """Why the mirrored state is not the member's now, or None."""
        return self.FREED if self.freed else self._owner.ended or self._owner.silent()

    def start(self) -> None:
        """Nothing: the member runs in the worker from the moment it was made."""
