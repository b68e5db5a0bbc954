"""A page's scene events handled one at a time, in the order the page sent them.

viser runs a plain (synchronous) callback of a drag or a gizmo on a pool of threads,
each event as soon as it arrives, so two events sent back to back can be handled in
either order: under load a drag's "end" overtook the next drag's "start", and a drag's
last "update" could land after its "end", leaving the arm pulled by a spring nobody
holds. An ``async`` callback is awaited in order on the server's event loop, where
nothing may wait (a private arm's command goes to its worker process and waits for the
answer). :class:`InOrder` gives both: the callback viser sees is ``async`` and only
hands the event to one thread of its own, which runs the handlers in arrival order.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable, Coroutine
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

E = TypeVar("E")


def _report(done: Future[None]) -> None:
    """Print a handler's error, as viser does for its own callbacks."""
    exc = done.exception() if not done.cancelled() else None
    if exc is not None:
        traceback.print_exception(exc)


class InOrder:
    """One thread running the handlers it wraps, each event after the one before it.

    Args:
        name: the thread's name (shown in a stack dump).
    """

    def __init__(self, name: str) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)

    def __call__(self, handler: Callable[[E], None]) -> Callable[[E], Coroutine[Any, Any, None]]:
        """``handler`` as a callback for viser (``handle.on_drag(lane(handler))``): it
        queues the event at once and returns; the lane's thread runs ``handler`` with it
        after every event queued before. Events that come after :meth:`close` are
        dropped."""

        async def queued(event: E) -> None:
            try:
                self._pool.submit(handler, event).add_done_callback(_report)
            except RuntimeError:  # closed: the scene the event was for is gone
                pass

        return queued

    def close(self) -> None:
        """Drop the events not yet handled and end the thread once it is idle."""
        self._pool.shutdown(wait=False, cancel_futures=True)


__all__ = ["InOrder"]
