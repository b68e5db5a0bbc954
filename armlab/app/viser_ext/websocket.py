"""The gate's hook: where the lab reaches into viser to put something in front of its
websocket server (:mod:`armlab.app.classroom.gate` decides what; this module only knows where).

viser builds its ``websockets`` server inside ``ViserServer``'s start-up, calling
``websockets.asyncio.server.serve(..., process_request=...)`` through the module name
``websockets`` of ``viser.infra._infra``, and reads each connection's messages with that
module's ``_message_consumer``. :func:`front` gives that module a stand-in for the
``websockets`` name (every other name is the real module's) whose ``serve`` wraps
``process_request`` for the one server built inside the block, and replaces the
consumer. Nothing else in the process changes.

The hook fails closed: :func:`missing` says what of the above this viser lacks (the lab
then refuses to start), and :meth:`Front.confirm` raises :class:`HookNotPlaced` when a
server was built inside the block without passing through the hook (the caller stops
it).
"""

from __future__ import annotations

import asyncio
import inspect
import threading
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import websockets.asyncio.server
import websockets.datastructures
import websockets.exceptions

from armlab.app.viser_ext import HooksMissing
from armlab.app.viser_ext.probe import code_names

#: relies on: viser.infra._infra's module name ``websockets`` (used as
#: ``websockets.asyncio.server.serve`` in ``WebsockServer._background_worker``) and its
#: ``_message_consumer(websocket, handle_message, message_class)``; seen in viser 1.1.1
RELIES_ON = ("viser.infra._infra: websockets.asyncio.server.serve(process_request=...) in "
             "WebsockServer._background_worker, _message_consumer(websocket, handle_message, "
             "message_class)")

#: what the start-up code must name for the stand-in to be the one it calls
_START_NAMES = frozenset({"websockets", "asyncio", "server", "serve", "_message_consumer"})
_CONSUMER_PARAMS = ("websocket", "handle_message", "message_class")


class HookNotPlaced(HooksMissing):
    """viser built its websocket server without passing through the gate's hook."""


def _infra() -> Any:
    from viser.infra import _infra

    return _infra


def missing() -> list[str]:
    """What the gate's hook needs of this viser and does not find (empty: all there)."""
    try:
        infra = _infra()
    except ImportError as exc:
        return [f"the module viser.infra._infra ({exc})"]
    out = []
    ws = getattr(infra, "websockets", None)
    serve = getattr(getattr(getattr(ws, "asyncio", None), "server", None), "serve", None)
    if not callable(serve):
        out.append("viser.infra._infra.websockets.asyncio.server.serve")
    consumer = getattr(infra, "_message_consumer", None)
    if not (inspect.iscoroutinefunction(consumer)
            and tuple(inspect.signature(consumer).parameters) == _CONSUMER_PARAMS):
        out.append("viser.infra._infra._message_consumer(websocket, handle_message, "
                   "message_class)")
    worker = getattr(getattr(infra, "WebsockServer", None), "_background_worker", None)
    if worker is None or not hasattr(worker, "__code__"):
        out.append("viser.infra._infra.WebsockServer._background_worker")
    elif not _START_NAMES <= code_names(worker):
        out.append("WebsockServer._background_worker calling websockets.asyncio.server.serve "
                   "and _message_consumer by those names")
    return out


class Front:
    """One use of :func:`front`: whether the server built in its block went through it."""

    def __init__(self, wrap: Callable[[Any], Any]) -> None:
        self.wrap = wrap
        self.placed = 0  #: websocket servers built with ``wrap`` in front

    def confirm(self) -> None:
        """Raises :class:`HookNotPlaced` unless a server was built through the hook."""
        if not self.placed:
            import viser

            raise HookNotPlaced(
                f"viser {viser.__version__} built its websocket server without the gate's "
                f"hook (it relies on {RELIES_ON})")


_lock = threading.Lock()
_pending: Front | None = None


def _serve(handler: Any, *args: Any, process_request: Any = None, **kwargs: Any) -> Any:
    """``websockets.asyncio.server.serve`` with the pending front's wrap around
    ``process_request`` (never raises of its own: it runs in viser's server thread)."""
    pending = _pending
    if pending is not None:
        process_request = pending.wrap(process_request)
        pending.placed += 1
    return websockets.asyncio.server.serve(handler, *args, process_request=process_request,
                                           **kwargs)


def _install(consumer: Callable[..., Any]) -> None:
    """Put the stand-in ``websockets`` and ``consumer`` into viser (once)."""
    infra = _infra()
    if not asyncio.iscoroutinefunction(consumer):
        raise TypeError("consumer: must be an async function")
    infra._message_consumer = consumer
    if getattr(infra.websockets, "armlab_gate", False):
        return
    server = types.SimpleNamespace(**vars(websockets.asyncio.server))
    server.serve = _serve
    infra.websockets = types.SimpleNamespace(
        asyncio=types.SimpleNamespace(server=server),
        datastructures=websockets.datastructures, exceptions=websockets.exceptions,
        armlab_gate=True)


@contextmanager
def front(wrap: Callable[[Any], Any], *, consumer: Callable[..., Any]) -> Iterator[Front]:
    """Inside this block, the ``viser.ViserServer`` constructed gets
    ``wrap(process_request)`` as its websocket server's ``process_request`` (viser's own
    static files are the argument), and every connection's messages are read by
    ``consumer`` (viser's ``_message_consumer`` signature).

    Raises:
        HookNotPlaced: (on entry) the hook cannot be put in place in this viser.
    """
    global _pending
    lacking = missing()
    if lacking:
        import viser

        raise HookNotPlaced(f"viser {viser.__version__} lacks what the gate's hook needs: "
                            + "; ".join(lacking))
    record = Front(wrap)
    with _lock:
        _install(consumer)
        _pending = record
        try:
            yield record
        finally:
            _pending = None
