"""What a lesson draws on: every page (the lab's ``viser.ViserServer``) or one page.

A lesson and the page pieces it uses (:class:`armlab.app.page.arm_view.ArmView`,
:class:`armlab.app.page.publisher.Publisher`, :func:`armlab.app.page.camera.show`) need
of it only what :class:`Surface` names, which a ``viser.ViserServer`` offers for every
page and :class:`armlab.app.classroom.private_page.Page` for one student's page (their
private arm): the same lesson code builds on either.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from typing import Protocol

import viser


class Surface(Protocol):
    """Where a lesson adds its controls and scene, and sends its frames."""

    @property
    def gui(self) -> viser.GuiApi:
        """The controls' API: what is added here shows on the surface's pages."""
        ...

    @property
    def scene(self) -> viser.SceneApi:
        """The 3D scene's API: what is added here shows on the surface's pages."""
        ...

    def atomic(self) -> AbstractContextManager[None]:
        """A block whose messages the pages apply together (one frame)."""
        ...

    def flush(self) -> None:
        """Send what is buffered for the pages now."""
        ...

    def get_clients(self) -> dict[int, viser.ClientHandle]:
        """The pages that show this surface now (client id -> page)."""
        ...
