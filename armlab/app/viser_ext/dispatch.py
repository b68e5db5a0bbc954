"""Screens in front of viser's handlers of what a page sends (the checks right after
the gate: :class:`armlab.app.page.inputs.UpdateScreen`, :class:`armlab.app.classroom.roles.Roles`).

relies on: ``GuiApi._websock_interface`` (``register_handler``, ``unregister_handler``),
``GuiApi._handle_gui_updates``, ``ViserServer._websock_server._handle_incoming_message``
(looked up per message by ``WebsockServer._background_worker``); seen in viser 1.1.1
"""

from __future__ import annotations

from collections.abc import Callable, Coroutine
from typing import Any

import viser

from armlab.app.viser_ext.messages import GuiUpdateMessage
from armlab.app.viser_ext.probe import code_names

#: ``async screen(client_id, message)``
Handler = Callable[[Any, Any], Coroutine[Any, Any, None]]


def missing() -> list[str]:
    """What of the above this viser lacks."""
    from viser import _gui_api
    from viser.infra import _infra

    out = []
    if not hasattr(_gui_api.GuiApi, "_handle_gui_updates"):
        out.append("GuiApi._handle_gui_updates")
    for name in ("register_handler", "unregister_handler", "_handle_incoming_message"):
        if not hasattr(_infra.WebsockMessageHandler, name):
            out.append(f"WebsockMessageHandler.{name}")
    if "_handle_incoming_message" not in code_names(_infra.WebsockServer._background_worker):
        out.append("WebsockServer._background_worker dispatching through "
                   "_handle_incoming_message")
    if GuiUpdateMessage is None:
        out.append("viser._messages.GuiUpdateMessage")
    return out


def screen_gui_updates(gui: viser.GuiApi, screen: Handler) -> Handler:
    """Put ``screen`` in place of ``gui``'s handler of the GUI updates pages send (a
    server's ``gui``, or a page's own); returns viser's handler, for ``screen`` to call
    with what it lets through."""
    iface = gui._websock_interface
    inner = gui._handle_gui_updates
    iface.unregister_handler(GuiUpdateMessage, inner)
    iface.register_handler(GuiUpdateMessage, screen)
    return inner


def screen_server_messages(server: viser.ViserServer, screen: Handler) -> Handler:
    """Put ``screen`` in front of ``server``'s dispatch of every message a page sends to
    the server's own handlers (the shared GUI and scene; a page's own elements' messages
    go to that page's handlers, not through it); returns viser's dispatch, for
    ``screen`` to call with what it lets through."""
    iface = server._websock_server
    inner = iface._handle_incoming_message
    iface._handle_incoming_message = screen  # type: ignore[method-assign,assignment]  # armlab's screen wraps viser's handler
    return inner
