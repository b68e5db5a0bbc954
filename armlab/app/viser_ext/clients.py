"""What viser keeps private about a page's connection and its message queues.

relies on: ``ClientHandle._websock_connection`` (``queue_message``,
``get_message_buffer``), ``ClientHandle._viser_server``, ``ViserServer._websock_server``
(``_live_connections``, ``get_message_buffer``), the message buffer's ``done``,
``generator_cursors``, ``message_counter``, ``buffer_lock``, ``message_from_id`` and
``window_generator``; seen in viser 1.1.1
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import viser

from armlab.app.viser_ext.probe import assigned_in


def missing() -> list[str]:
    """What of the above this viser lacks (checked on its classes' code)."""
    from viser.infra import _async_message_buffer, _infra

    need = [(viser.ClientHandle, ("_websock_connection", "_viser_server")),
            (viser.ViserServer, ("_websock_server",)),
            (_infra.WebsockServer, ("_live_connections", "_broadcast_buffer")),
            (_async_message_buffer.AsyncMessageBuffer,
             ("generator_cursors", "message_counter", "buffer_lock", "message_from_id",
              "window_generator", "done"))]
    return [f"{cls.__name__}.{name}" for cls, names in need for name in names
            if not assigned_in(cls, name)]


def server_of(client: viser.ClientHandle) -> viser.ViserServer:
    """The server page ``client`` is connected to."""
    return client._viser_server


def queue(client: viser.ClientHandle, message: Any) -> None:
    """Queue viser message ``message`` (:mod:`armlab.app.viser_ext.messages`) to
    ``client``'s page only."""
    client._websock_connection.queue_message(message)


def connected(client: viser.ClientHandle) -> bool:
    """False once the page has gone (its message buffer closed). (viser has no public
    flag for it.)"""
    conn = getattr(client, "_websock_connection", None)
    get = getattr(conn, "get_message_buffer", None)
    return get is None or not getattr(get(), "done", False)


def behind(client: viser.ClientHandle) -> bool:
    """Whether messages queued to the page alone still wait to be sent to it (False on a
    viser without the buffer's counters)."""
    try:
        buffer = client._websock_connection.get_message_buffer()
        sent = buffer.generator_cursors.get(client.client_id)
        return sent is not None and buffer.message_counter - 1 > sent
    except AttributeError:
        return False


def connection_of(server: viser.ViserServer, client_id: int) -> Any:
    """The ``websockets`` connection of page ``client_id`` (its ``request.headers``,
    ``remote_address``), or None."""
    live = getattr(getattr(server, "_websock_server", None), "_live_connections", {})
    return live.get(client_id)


def broadcast_buffer(server: viser.ViserServer) -> Any:
    """viser's buffer of the messages for every page (``generator_cursors``: client id ->
    last message id sent; ``message_counter``), or None on a viser without one."""
    return getattr(getattr(server, "_websock_server", None), "_broadcast_buffer", None)


def latest_broadcast(server: viser.ViserServer, kinds: tuple[type, ...]) -> list[Any]:
    """The messages of types ``kinds`` the server keeps for pages that join later (the
    newest of each property), oldest first."""
    buffer = broadcast_buffer(server)
    if buffer is None:
        return []
    with buffer.buffer_lock:
        return [m for _, m in sorted(buffer.message_from_id.items()) if isinstance(m, kinds)]


def filter_broadcast(server: viser.ViserServer,
                     wrap: Callable[[int, Any], Any]) -> bool:
    """Pass each page's stream of shared messages through ``wrap(client_id, windows)``
    (``windows``: viser's async generator of message lists for that page; ``wrap``
    returns another async generator, and closes ``windows`` when done). False, doing
    nothing, on a viser whose broadcast buffer has no ``window_generator``."""
    buffer = broadcast_buffer(server)
    inner = getattr(buffer, "window_generator", None)
    if inner is None:
        return False

    def window_generator(client_id: int, backlog_done_message: Any = None) -> Any:
        return wrap(client_id, inner(client_id, backlog_done_message=backlog_done_message))

    buffer.window_generator = window_generator
    return True
