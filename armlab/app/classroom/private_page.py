"""One browser page standing in for the server a lesson is built on (a private arm).

A lesson adds its controls to ``server.gui``, its scene to ``server.scene``, sends its
frames inside ``server.atomic()`` and asks ``server.get_clients()`` whether anyone
watches. :class:`Page` offers the same for one page (viser's client-scoped GUI and
scene), so the same lesson code builds a private copy on one student's page: its
controls reach only that page, and its scene nodes, named as the shared lesson's,
*shadow* the shared ones there (viser draws a page's own node in place of the server's
of the same name). A lesson's camera (``armlab.app.page.camera.show``) frames this page alone.
"""

from __future__ import annotations

import warnings
from contextlib import AbstractContextManager

import viser

from armlab.app.viser_ext.clients import behind, server_of

# A page may leave while its own lesson is sending a frame; viser then warns once per
# code line that the message "will never be delivered". Nothing is wrong: the lesson is
# closed right after (armlab.app.classroom.room), so the warning only fills the log.
warnings.filterwarnings("ignore", message=r"Queued a \w+ on a closed connection",
                        category=UserWarning)


class Page:
    """A lesson's "server" that is one page (:class:`viser.ClientHandle`): an
    :class:`armlab.app.page.surface.Surface`, as the lab's server is.

    Attributes:
        client: the page.
        gui, scene: its own GUI and scene (seen by this page only).
    """

    def __init__(self, client: viser.ClientHandle) -> None:
        self.client = client
        self.gui = client.gui
        self.scene = client.scene

    def atomic(self) -> AbstractContextManager[None]:
        """Group the messages sent inside the block; the page applies them together."""
        return self.client.atomic()

    def flush(self) -> None:
        """Send what is buffered for the page now."""
        self.client.flush()

    def behind(self) -> bool:
        """Whether messages of an earlier frame still wait to be sent to the page (the page
        or the server cannot keep up): a publisher then skips a frame instead of making one
        that viser would only fold into the waiting one."""
        return behind(self.client)

    def get_clients(self) -> dict[int, viser.ClientHandle]:
        """The one page, or nothing once it has left."""
        connected = server_of(self.client).get_clients()
        cid = self.client.client_id
        return {cid: self.client} if cid in connected else {}
