"""What the server's proxy of something running in a worker process needs of that worker.

:class:`app.arm_process.ArmProcess` is the worker; its arms' proxies live beside it, and
the class's hands and quadrupeds have theirs (:mod:`app.remote_hand`,
:mod:`app.remote_gait`), which know the worker only as a :class:`WorkerLink`.
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
