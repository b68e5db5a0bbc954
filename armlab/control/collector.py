"""The garbage collector kept out of the control loops' way.

CPython's cyclic collector stops every thread while it runs. A full pass (generation 2)
walks every container object the process holds: with 30 students' lessons open about
190 000 of them, 50 to 90 ms of CPU on a 2-core lab machine. Every loop due meanwhile
starts that much late: the shared arm's loop, whose jitter should stay under 1 ms, and
every student's arm on the class clock.

Most of those objects live as long as the lab (modules, the viser server, the shared
lesson) or as a page (a student's own lesson). They are *kept*: :func:`keep` freezes
what is alive once such a thing is built (``gc.freeze``: moved where the collector never
looks), so a full pass walks only what came after, a few thousand objects. A kept
lesson that closes leaves garbage the collector cannot see; :func:`closed` notes it,
and :func:`tidy` (the lab calls it before it builds the next shared lesson, and the
class at most once a :data:`TIDY_EVERY_S`) unfreezes, collects and freezes again: one
full pause at a moment something was closed, never in a class that is running. A lab
that closes calls :func:`release`: nothing of it needs keeping out of the way any more,
so what it kept is handed back to the collector, whose own passes free it later, with
no full pause at the close (a notebook or a test process that opens lab after lab would
otherwise walk its whole heap at every close).
"""

from __future__ import annotations

import gc
import threading
import time

#: s between two tidies in a running class (a student's reload leaves a closed lesson)
TIDY_EVERY_S = 60.0

_lock = threading.Lock()
_state = {"closed": 0, "last_tidy": float("-inf")}


def keep() -> None:
    """Freeze what is alive now (a lab or a page just built what it keeps): full passes
    of the collector no longer walk it."""
    gc.freeze()


def closed() -> None:
    """Something :func:`keep` froze was closed: its garbage waits for :func:`tidy`."""
    with _lock:
        _state["closed"] += 1


def release() -> None:
    """Unfreeze everything (a lab closed): what it kept is the collector's again, and its
    garbage is freed by the collector's own passes, not by a full pass now. Nothing
    frozen is left to hide garbage, so nothing closed is waiting for :func:`tidy`. (A
    second lab in the same process, a test's, is unfrozen too, until its next
    :func:`keep`; the lab a person serves is alone in its process.)"""
    with _lock:
        _state["closed"] = 0
        gc.unfreeze()


def tidy(*, every_s: float = 0.0) -> float | None:
    """Free what closed kept things left: unfreeze, collect everything, freeze again.

    Args:
        every_s: do nothing unless this many seconds passed since the last tidy.

    Returns:
        The pause, ms of wall time; None when nothing was closed since the last tidy
        (or ``every_s`` has not passed).
    """
    now = time.monotonic()
    with _lock:
        if not _state["closed"] or now - _state["last_tidy"] < every_s:
            return None
        _state["closed"] = 0
        _state["last_tidy"] = now
        t0 = time.perf_counter()
        gc.unfreeze()
        gc.collect()
        gc.freeze()
        return (time.perf_counter() - t0) * 1e3
