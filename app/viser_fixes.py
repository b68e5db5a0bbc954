"""A work-around for viser (seen in 1.1.1), applied once when the lab's server module loads.

viser's message buffer wakes its sender by setting an ``asyncio.Event`` twice: through
the event loop (thread-safe) and directly from the calling thread, so that synchronous
code can read it at once. The direct ``set()`` walks the event's waiters while the loop
thread may be adding one; on a busy machine this now and then raises
``RuntimeError: deque mutated during iteration`` inside a GUI call made from a callback
thread (a classroom page's welcome, one run in a few under load), and the page never
got the rest of its controls. The message itself is already buffered when this
happens; :func:`install` wraps the buffer's ``push`` so that this one error wakes the
sender the thread-safe way instead of escaping into the lab's code.
"""

from __future__ import annotations

import contextlib
import functools
from typing import Any

try:  # a private module of viser: another release may move it (then nothing is patched)
    from viser.infra._async_message_buffer import AsyncMessageBuffer
except ImportError:  # pragma: no cover - not this viser
    AsyncMessageBuffer = None  # type: ignore[assignment,misc]

#: The words of the race's error (CPython's asyncio.Event.set over a changing deque).
RACE = "mutated during iteration"


def install() -> None:
    """Make ``AsyncMessageBuffer.push`` survive the waiter race (idempotent; nothing on a
    viser without that class)."""
    if AsyncMessageBuffer is None:
        return
    push = AsyncMessageBuffer.push
    if getattr(push, "armlab_fixed", False):
        return

    @functools.wraps(push)
    def fixed_push(self: AsyncMessageBuffer, message: Any) -> None:
        try:
            push(self, message)
        except RuntimeError as exc:
            if RACE not in str(exc):
                raise
            with contextlib.suppress(RuntimeError):  # a closed loop has no sender to wake
                self.event_loop.call_soon_threadsafe(self.message_event.set)

    fixed_push.armlab_fixed = True  # type: ignore[attr-defined]
    AsyncMessageBuffer.push = fixed_push  # type: ignore[method-assign]
