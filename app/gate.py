"""The gate in front of the robot: only the lab's own page, holding the token, gets a websocket.

viser's websocket accepts any Origin and asks for no credential, and sends the
whole scene and GUI state as soon as a socket opens. The gate cuts in at the
HTTP upgrade, before that state: a websocket request is answered ``403`` unless

- its ``Origin`` header, when present, is the lab's own (``http://`` + the
  ``Host`` the request was sent to): a page from another site, open in the
  teacher's browser, cannot open it (cross-site websocket hijacking); and
- it presents the token, in its URL query (``?token=T``) or in the cookie the
  lab sets when a page is fetched with ``?token=T``.

Static files stay public (they hold no robot state). The token is random at
each start (``secrets``), as Jupyter's is, unless one is given.

How it hooks in (checked against viser 1.x; check again when viser moves):
viser builds its ``websockets`` server inside a background event loop and
passes its static file server as ``process_request``; ``websockets`` reads
``Server.process_request`` for every new connection, so :func:`install`
wraps it in place.
"""

from __future__ import annotations

import asyncio
import hmac
import http
import secrets
import time
from collections.abc import Callable
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qs, urlsplit

import viser

#: Name of the cookie (and of the URL query parameter) that carries the token.
TOKEN_NAME = "token"
COOKIE_NAME = "armlab_token"


def new_token() -> str:
    """A fresh random token (32 url-safe characters)."""
    return secrets.token_urlsafe(24)


class Gate:
    """Decides which requests may open the lab's websocket.

    Args:
        token: the secret a client must present.

    Attributes:
        refused: how many websocket requests were refused so far.
    """

    def __init__(self, token: str) -> None:
        if not isinstance(token, str) or not token or any(c in token for c in ";,= \t\r\n\"'"):
            raise ValueError("token: expected a non-empty string without spaces, quotes, "
                             "';', ',' or '='")
        self.token = token
        self.refused = 0

    def _matches(self, candidate: str | None) -> bool:
        return candidate is not None and hmac.compare_digest(candidate.encode(),
                                                             self.token.encode())

    @staticmethod
    def _query_token(path: str) -> str | None:
        values = parse_qs(urlsplit(path).query).get(TOKEN_NAME)
        return values[0] if values else None

    @staticmethod
    def _cookie_token(header: str | None) -> str | None:
        if not header:
            return None
        try:
            morsel = SimpleCookie(header).get(COOKIE_NAME)
        except CookieError:
            return None
        return morsel.value if morsel is not None else None

    def why_refused(self, *, path: str, host: str | None, origin: str | None,
                    cookie: str | None) -> str | None:
        """Why a websocket request with these headers is refused (None: let it in)."""
        own = (host is not None and origin is not None
               and origin.lower() == f"http://{host}".lower())
        if origin is not None and not own:
            return f"origin {origin[:80]!r} is not the lab's own"
        if not (self._matches(self._query_token(path))
                or self._matches(self._cookie_token(cookie))):
            return "no valid token (open the url `armlab serve` printed)"
        return None

    def wrap(self, inner: Callable | None) -> Callable:
        """A ``process_request`` hook: refuse bad upgrades, set the cookie on token page loads."""

        def process_request(connection, request):  # websockets' hook signature
            headers = request.headers
            if headers.get("Upgrade", "").lower() == "websocket":
                reason = self.why_refused(path=request.path, host=headers.get("Host"),
                                          origin=headers.get("Origin"),
                                          cookie=headers.get("Cookie"))
                if reason is not None:
                    self.refused += 1
                    return connection.respond(http.HTTPStatus.FORBIDDEN, f"armlab: {reason}\n")
                return None
            response = inner(connection, request) if inner is not None else None
            if response is not None and self._matches(self._query_token(request.path)):
                response.headers["Set-Cookie"] = (
                    f"{COOKIE_NAME}={self.token}; Path=/; HttpOnly; SameSite=Strict")
            return response

        return process_request


def _websockets_server(server: viser.ViserServer):
    """The ``websockets`` server object viser's background loop is serving with."""
    loop = server._websock_server._background_event_loop
    try:
        tasks = list(asyncio.all_tasks(loop))
    except RuntimeError:  # the loop's task set changed while read from this thread
        return None
    for task in tasks:
        frame = getattr(task.get_coro(), "cr_frame", None)
        if frame is not None and "serve_future" in frame.f_locals:
            return frame.f_locals["serve_future"]
    return None


def install(server: viser.ViserServer, gate: Gate, *, timeout: float = 10.0) -> None:
    """Put ``gate`` in front of ``server``'s websocket (raises RuntimeError if it cannot).

    Call right after constructing the server: until this returns, no client
    should be given the address.
    """
    deadline = time.monotonic() + timeout
    while (ws := _websockets_server(server)) is None:
        if time.monotonic() > deadline:
            raise RuntimeError("gate: cannot find viser's websocket server (viser changed?)")
        time.sleep(0.01)
    ws.process_request = gate.wrap(ws.process_request)
