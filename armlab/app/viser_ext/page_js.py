"""One page alone: a small script run in it, a question to its localStorage, and
properties of shared elements set on it only.

relies on: viser._messages' ``RunJavascriptMessage``, ``GuiUpdateMessage``,
``SceneNodeUpdateMessage``; a page's own queue and the broadcast buffer's cursors
(:mod:`armlab.app.viser_ext.clients`); viser's localStorage prefix ``viser-user:``; seen
in viser 1.1.1

A script goes through the message viser itself uses to load Plotly
(``RunJavascriptMessage``): viser has no public API for it, and its page runs the
source with ``new Function(source)()`` in its message loop, with nothing around it.
:func:`run_javascript` therefore wraps every script in ``try``/``catch``: a script that
throws (an element it expected is missing in some release) logs to the console and the
page goes on handling the server's messages. :func:`set_props` sends viser's own
update messages to one page's connection (viser's handles send them to every page).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import viser

from armlab.app.viser_ext.clients import broadcast_buffer, queue, server_of
from armlab.app.viser_ext.handles import is_gui, is_removed, owner_of, scene_scope, uuid_of
from armlab.app.viser_ext.messages import (
    GuiUpdateMessage,
    RunJavascriptMessage,
    SceneNodeUpdateMessage,
)
from armlab.app.viser_ext.page_scripts import password_script

#: viser's page keeps ``client.local_storage`` keys under this prefix (its
#: MessageHandler.tsx), so a script writes ``PREFIX + key`` for the server to read ``key``.
LOCAL_STORAGE_PREFIX = "viser-user:"


def missing() -> list[str]:
    """What page scripts need of this viser and do not find (the page's DOM itself is
    only checked in a browser: tests/test_browser_*.py)."""
    return [] if RunJavascriptMessage is not None else ["viser._messages.RunJavascriptMessage"]


def guarded(source: str, *, name: str) -> str:
    """``source`` inside ``try``/``catch`` that logs ``armlab <name>: <error>`` instead of
    throwing into viser's message loop."""
    return (f"try {{\n{source}\n}} catch (e) {{ console.warn('armlab {name}: ' + e); }}")


def run_javascript(client: viser.ClientHandle, source: str, *, name: str) -> bool:
    """Run ``source`` once in ``client``'s page (after every message queued before it).

    Returns False, doing nothing, on a viser without the message."""
    if RunJavascriptMessage is None:
        return False
    queue(client, RunJavascriptMessage(source=guarded(source, name=name)))
    return True


def mask_text_input(client: viser.ClientHandle, handle: viser.GuiTextHandle) -> bool:
    """Make text input ``handle`` a password field on ``client``'s page: what is typed
    shows as dots (``type=password``, kept when viser draws the input again); its value
    reaches the server as before. viser 1.1.1's ``add_text`` has no such option, so this
    is a page script (:data:`armlab.app.viser_ext.page_scripts.PASSWORD_SCRIPT`).

    Returns False, doing nothing, on a viser without the message."""
    return run_javascript(client, password_script(uuid_of(handle)), name="password")


def ask_item(client: viser.ClientHandle, key: str, *, every: float, within: float) -> str | None:
    """``client``'s localStorage value of ``key`` (None: absent), asked every ``every`` s
    until the page answers: a page that has only just connected may miss the first
    question, and a busy one answers late.

    Raises:
        TimeoutError: no answer within ``within`` s.
        RuntimeError: the page left, or its browser keeps no localStorage.
    """
    deadline = time.monotonic() + within
    while True:
        try:
            return client.local_storage.get_item(key, timeout=every)
        except TimeoutError:
            if time.monotonic() >= deadline:
                raise


def set_props(client: viser.ClientHandle, handle: Any, **props: Any) -> None:
    """Set properties of a GUI element or scene node on ``client``'s page only, through
    the update message viser sends when a handle's property is assigned (the server's
    handle, and every other page, keep their values). Nothing is sent for an element
    already removed (the page would log an error).

    viser sends a page its own messages and the messages for every page by two separate
    queues, so an update for an element every page shows is held until the page has been
    sent everything shared that came before (:func:`after_shared`): an element created a
    moment ago exists on the page before its update arrives."""
    if is_removed(handle):
        return
    if is_gui(handle):
        message: Any = GuiUpdateMessage(uuid_of(handle), props)
    else:  # a scene node, addressed by name and the scope (server or page) it belongs to
        message = SceneNodeUpdateMessage(handle.name, props, owner=scene_scope(handle))

    def send() -> None:
        if not is_removed(handle):
            queue(client, message)

    if owner_of(handle) is client:
        send()  # the page's own element: created through the same queue
    else:
        after_shared(client, send)


#: s a page may take to be sent the shared messages before a held one (then it is dropped)
SHARED_WAIT_S = 120.0
#: s between looks at how far a page has been sent the shared messages
SHARED_POLL_S = 0.01

_held_lock = threading.Lock()
#: client id -> [(shared message id to wait for, send), ...] in order
_held: dict[Any, list[tuple[int, float, Callable[[], None]]]] = {}


def _broadcast(client: viser.ClientHandle) -> Any:
    """viser's buffer of the messages for every page (None: a viser without one)."""
    return broadcast_buffer(server_of(client))


def after_shared(client: viser.ClientHandle, send: Callable[[], None]) -> None:
    """Call ``send()`` once ``client`` has been sent every message for all pages queued
    before this call (at once if it has; in call order per page; never for a page that
    left or is not sent them within :data:`SHARED_WAIT_S`)."""
    buffer = _broadcast(client)
    cursors = getattr(buffer, "generator_cursors", None)
    if buffer is None or cursors is None:
        send()  # a viser without these: as good as it gets
        return
    mark = buffer.message_counter - 1
    key = (id(buffer), client.client_id)
    with _held_lock:
        waiting = _held.get(key)
        if waiting is None and cursors.get(client.client_id, -1) >= mark:
            send()
            return
        if waiting is None:
            _held[key] = waiting = []
            threading.Thread(target=_release, args=(key, cursors, client),
                             daemon=True, name="armlab-page-props").start()
        waiting.append((mark, time.monotonic() + SHARED_WAIT_S, send))


def held(client: viser.ClientHandle) -> int:
    """How many of ``client``'s messages :func:`after_shared` still holds."""
    key = (id(_broadcast(client)), client.client_id)
    with _held_lock:
        return len(_held.get(key, ()))


def _release(key: Any, cursors: dict, client: viser.ClientHandle) -> None:
    """Send a page's held messages as it is sent the shared ones before them."""
    server = server_of(client)
    while True:
        with _held_lock:
            waiting = _held[key]
            at = cursors.get(client.client_id, -1)
            now = time.monotonic()
            while waiting and (at >= waiting[0][0] or now > waiting[0][1]):
                mark, _, send = waiting.pop(0)
                if at >= mark:
                    send()
            if not waiting or client.client_id not in server.get_clients():
                del _held[key]  # all sent, or the page has gone
                return
        time.sleep(SHARED_POLL_S)
