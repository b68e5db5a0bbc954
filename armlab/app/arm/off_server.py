"""Headless runs off the server's interpreter: what a page asks to simulate for seconds
(the Contact tab's "Compare PD and compliance": two contact experiments on an arm of
their own) runs in one spawned process the lab's pages share, so that its simulation never
takes the GIL from the pages' frames, the shared arm's loop or a class's arms.

One process, made on the first call and kept; its calls queue in the order given, at
most :data:`MAX_QUEUED` at once (a class of 30 pressing together waits its turn; a
31st past the bound is told to try again). When the process ends (killed, crashed), the
calls it held fail with one line and the next call makes a new one: the server goes on.
"""

from __future__ import annotations

import multiprocessing
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from armlab.app.arm.backends import make_backend
from armlab.control.experiments.contact import compare_contact, run_contact
from armlab.control.params import Params
from armlab.kinematics.model import SerialChain

#: calls queued or running at most; one more is refused (ValueError) until one ends
MAX_QUEUED = 32

_lock = threading.Lock()
_pool: ProcessPoolExecutor | None = None
_queued = 0


def submit(fn: Callable[..., Any], *args: Any) -> Future[Any]:
    """``fn(*args)`` in the lab's process for headless runs (``fn`` and ``args``
    picklable: a module's function, a model, gains); its result in the future, or the
    exception it raised (a process that ended: ``RuntimeError`` saying so).

    Raises:
        ValueError: :data:`MAX_QUEUED` calls are waiting already.
    """
    global _pool, _queued
    with _lock:
        if _queued >= MAX_QUEUED:
            raise ValueError(f"the lab is running {_queued} comparisons already; try again "
                             "in a few seconds")
        if _pool is None:  # (spawn: a fresh interpreter, no copy of the server's threads)
            _pool = ProcessPoolExecutor(max_workers=1,
                                        mp_context=multiprocessing.get_context("spawn"))
        pool = _pool
        try:
            inner = pool.submit(fn, *args)
        except BrokenProcessPool:  # (it ended since the last call: a new one next time)
            _pool = None
            raise ValueError("the lab's process for headless runs had ended; "
                             "try again") from None
        _queued += 1
    out: Future[Any] = Future()

    def done(f: Future[Any]) -> None:
        global _pool, _queued
        with _lock:
            _queued -= 1
            if isinstance(f.exception(), BrokenProcessPool) and _pool is pool:
                _pool = None
        exc = f.exception()
        if isinstance(exc, BrokenProcessPool):
            out.set_exception(RuntimeError("the lab's process for headless runs ended"))
        elif exc is not None:
            out.set_exception(exc)
        else:
            out.set_result(f.result())

    inner.add_done_callback(done)
    return out


def compare_on_sim(model: SerialChain, params: Params, wall: dict[str, Any]
                   ) -> dict[str, Any]:
    """``armlab experiment contact-compare``'s two runs (PD, the compliance law) of
    ``model`` at ``params`` into one wall (``wall``: ``run_contact``'s wall keywords), on
    a simulated arm of their own: :func:`compare_contact`'s figures."""
    return compare_contact(lambda controller: run_contact(
        model, lambda m, q0: make_backend("sim", m, q0=q0), params, controller=controller,
        **wall))
