"""Running a small script in one page, through the message viser itself uses to load
Plotly (``RunJavascriptMessage``): viser has no public API for it, and its page runs
the source with ``new Function(source)()`` in its message loop, with nothing around it.
:func:`run_javascript` therefore wraps every script in ``try``/``catch``: a script that
throws (an element it expected is missing in some release) logs to the console and the
page goes on handling the server's messages.
"""

from __future__ import annotations

import time

import viser

try:  # viser's own message (viser._messages is private: another release may move it)
    from viser._messages import RunJavascriptMessage
except ImportError:  # pragma: no cover - not this viser
    RunJavascriptMessage = None  # type: ignore[assignment,misc]

#: viser's page keeps ``client.local_storage`` keys under this prefix (its
#: MessageHandler.tsx), so a script writes ``PREFIX + key`` for the server to read ``key``.
LOCAL_STORAGE_PREFIX = "viser-user:"


def guarded(source: str, *, name: str) -> str:
    """``source`` inside ``try``/``catch`` that logs ``armlab <name>: <error>`` instead of
    throwing into viser's message loop."""
    return (f"try {{\n{source}\n}} catch (e) {{ console.warn('armlab {name}: ' + e); }}")


def run_javascript(client: viser.ClientHandle, source: str, *, name: str) -> bool:
    """Run ``source`` once in ``client``'s page (after every message queued before it).

    Returns False, doing nothing, on a viser without the message."""
    if RunJavascriptMessage is None:
        return False
    client._websock_connection.queue_message(  # type: ignore[attr-defined]
        RunJavascriptMessage(source=guarded(source, name=name)))
    return True


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
