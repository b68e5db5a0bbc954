"""Pointing the 3D view: the starting camera of new pages and of the pages already open.

``server.initial_camera`` only sets where a *new* page starts (and where "Reset
View" returns); a page already open keeps its camera. A lesson opened by the
lesson switcher therefore aims every connected client's camera as well, so its
scene comes into view at once.
"""

from __future__ import annotations

import viser


def aim(server: viser.ViserServer, *, position: tuple[float, float, float],
        look_at: tuple[float, float, float],
        up: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> None:
    """Camera at ``position`` looking at ``look_at`` (world, m) on new and open pages."""
    server.initial_camera.position = position
    server.initial_camera.look_at = look_at
    server.initial_camera.up = up
    show_initial_view(server)


def connected(client: viser.ClientHandle) -> bool:
    """False once the page has gone (its message buffer closed): writing to its camera
    then only makes viser warn. (viser has no public flag for it.)"""
    conn = getattr(client, "_websock_connection", None)
    get = getattr(conn, "get_message_buffer", None)
    return get is None or not getattr(get(), "done", False)


def show_initial_view(server: viser.ViserServer) -> None:
    """Move every open page's camera to ``server.initial_camera`` (after a lesson switch)."""
    ic = server.initial_camera
    up = ic.up if ic.up is not None else (0.0, 0.0, 1.0)
    for client in server.get_clients().values():
        if not connected(client):
            continue
        try:
            client.camera.up_direction = up
            client.camera.position = ic.position
            client.camera.look_at = ic.look_at  # after position, which drags look_at along
        except (AssertionError, ValueError, RuntimeError):
            pass  # a page that has not reported its camera yet starts at initial_camera
