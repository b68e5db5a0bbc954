"""The shared lesson's stream, held back from a page that shows its own arm.

viser broadcasts every change of a server-level element to every page. A student's
page showing "My arm" hides the shared lesson (``armlab.app.classroom.room``) yet would still
receive its frames: the shared arm's pose 30 times a second and its charts, each serialised
once per page by the server. :class:`SharedStream` stops the *updates* of server-level
elements (GUI property updates, scene node poses and properties) from reaching such a
page; elements added or removed still reach it, so the page's copy of the shared scene
and panel stays whole. When the page follows again, the latest value of every update
it missed is sent to it first (the server keeps the newest update of each property for
pages that join later: :meth:`catch_up` sends those), so it shows the shared lesson as
it is now.

The stream is filtered through :func:`armlab.app.viser_ext.clients.filter_broadcast`
(viser's broadcast buffer is internal to viser); with a viser that has none, nothing
is held back.
"""

from __future__ import annotations

from collections.abc import AsyncGenerator, Sequence
from typing import Any

import viser

from armlab.app.viser_ext.clients import filter_broadcast, latest_broadcast, queue
from armlab.app.viser_ext.messages import (
    GuiUpdateMessage,
    SceneNodeUpdateMessage,
    SetOrientationMessage,
    SetPositionMessage,
)

#: the updates held back (the stream of frames); additions and removals always pass
HELD: tuple[type, ...] = (GuiUpdateMessage, SceneNodeUpdateMessage, SetOrientationMessage,
                          SetPositionMessage)


class SharedStream:
    """Holds the server's broadcast updates back from the pages it is told to.

    Args:
        server: the lab's server (its broadcast stream is filtered once, here).

    Attributes:
        installed: False when this viser's broadcast stream could not be filtered.
        held: updates not sent, counted over all pages.
    """

    def __init__(self, server: viser.ViserServer) -> None:
        self._held_from: set[int] = set()
        self.held = 0
        self._server = server
        self.installed = filter_broadcast(server, self._filtered)

    def hold(self, client_id: int) -> None:
        """Send page ``client_id`` no more updates of server-level elements."""
        self._held_from.add(client_id)

    def release(self, client: viser.ClientHandle) -> None:
        """Send ``client`` the latest of every held update, then the stream again."""
        if client.client_id not in self._held_from:
            return
        self.catch_up(client)
        self._held_from.discard(client.client_id)

    def forget(self, client_id: int) -> None:
        """The page left."""
        self._held_from.discard(client_id)

    def is_held(self, client_id: int) -> bool:
        """Whether updates are held back from page ``client_id`` now."""
        return client_id in self._held_from

    def catch_up(self, client: viser.ClientHandle) -> None:
        """Queue to ``client`` the newest update of each property the server keeps, oldest
        first (what a page that joins now would be sent of them)."""
        latest = latest_broadcast(self._server, HELD)
        with client.atomic():
            for message in latest:
                queue(client, message)

    def _filtered(self, client_id: int, windows: Any) -> AsyncGenerator[Sequence[Any], None]:
        """Page ``client_id``'s shared stream, less the held updates while it is held."""
        held_from = self._held_from

        async def filtered() -> AsyncGenerator[Sequence[Any], None]:
            try:
                async for window in windows:
                    if client_id in held_from:
                        kept = [m for m in window if not isinstance(m, HELD)]
                        self.held += len(window) - len(kept)
                        if not kept:
                            continue
                        window = kept
                    yield window
            finally:
                await windows.aclose()

        return filtered()
