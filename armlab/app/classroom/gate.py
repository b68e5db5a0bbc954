"""The gate in front of the lab's websocket: only the lab's own page, holding the token,
gets the robot's state and controls.

viser has no credential and no Origin check: any web page open in the teacher's
browser could open ``ws://127.0.0.1:8080`` and drive the arm (cross-site websocket
hijacking). The lab therefore prints ``url: http://HOST:PORT/?token=TOKEN`` (a random
token per start, as Jupyter does) and this gate checks every websocket upgrade before
viser sees it, answering HTTP 403 (no state is ever sent) unless

- the request presents the token: ``?token=`` (or ``?armlab_token=``, the name used
  behind Jupyter, whose login owns ``?token=``: :mod:`armlab.app.lab.jupyter`) on the websocket URL
  (scripts, the headless client) or the ``armlab_token`` cookie, which the lab sets on
  the page it serves for a URL with the right token (``HttpOnly; SameSite=Strict``:
  another site's page never sends it; no ``Path``: the page's folder, so behind
  jupyter-server-proxy only this lab's prefix gets it); and
- its ``Origin``, when there is one (every browser sends it), is the lab's own: the
  scheme and the ``Host`` the request was made to.

Static files (the page's JavaScript, fonts) stay public; they hold nothing of the
robot. Where the gate sits in viser (the one private hook it needs) is
:mod:`armlab.app.viser_ext.websocket`; it fails closed: a lab whose gate cannot be put in
place does not start (tests/test_gate.py, tests/test_viser_hooks.py).
"""

from __future__ import annotations

import hmac
import http
import math
import secrets
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any
from urllib.parse import parse_qs, parse_qsl, urlencode, urlsplit

from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from armlab.app.viser_ext.websocket import Front, front

COOKIE = "armlab_token"
#: the cookie a presenter link (``?presenter=PASSCODE``) leaves in the browser, named
#: ``armlab_presenter_<start>`` (:attr:`Gate.presenter_cookie`: a link of an earlier
#: start, whose passcode is gone, is not even read); the classroom reads it when the
#: page's websocket opens (armlab.app.classroom.room), not the gate
PRESENTER_COOKIE = "armlab_presenter"
PRESENTER_QUERY = "presenter"
_TOKEN_CHARS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_")


def new_token() -> str:
    """A random token (128 bits, URL-safe)."""
    return secrets.token_urlsafe(16)


def check_token(token: str) -> str:
    """``token`` if it can stand in a URL and a cookie unquoted (8-128 of A-Z a-z 0-9 - _).

    Raises:
        ValueError: naming what is wrong.
    """
    if not isinstance(token, str) or not 8 <= len(token) <= 128 or set(token) - _TOKEN_CHARS:
        raise ValueError("token: use 8 to 128 letters, digits, '-' or '_'")
    return token


class Gate:
    """Who may open the lab's websocket (see the module docstring).

    Args:
        token: the secret the page's URL carries.
    """

    def __init__(self, token: str) -> None:
        self.token = check_token(token)
        self.refused = 0  #: upgrades answered 403
        #: the name of this start's presenter-link cookie
        self.presenter_cookie = f"{PRESENTER_COOKIE}_{secrets.token_hex(4)}"
        self._lock = threading.Lock()

    def _matches(self, presented: str | None) -> bool:
        return presented is not None and hmac.compare_digest(presented.encode(),
                                                             self.token.encode())

    def presented_in_query(self, request: Request) -> bool:
        """The request's URL carries the right ``?token=`` or ``?armlab_token=`` (the name
        used behind Jupyter, whose own login reads ``?token=``: :mod:`armlab.app.lab.jupyter`)."""
        query = parse_qs(urlsplit(request.path).query)
        values = query.get("token", []) + query.get(COOKIE, [])
        return any(self._matches(v) for v in values)

    def presented_in_cookie(self, request: Request) -> bool:
        """The request carries the right ``armlab_token`` cookie."""
        return any(self._matches(v) for v in cookie_values(request.headers, COOKIE))

    def refusal(self, request: Request) -> str | None:
        """Why a websocket upgrade is refused, or None to let it through."""
        origin = request.headers.get("Origin")
        host = request.headers.get("Host", "")
        if origin is not None and origin not in (f"http://{host}", f"https://{host}"):
            return f"origin {origin[:100]!r} is not the lab's own page"
        if not (self.presented_in_query(request) or self.presented_in_cookie(request)):
            return "no valid token: open the URL armlab serve printed"
        return None

    def wrap(self, inner: Callable[[Any, Request], Response | None] | None
             ) -> Callable[[Any, Request], Response | None]:
        """``process_request`` for the websockets server: this gate, then ``inner``
        (viser's static files)."""

        def process_request(connection: Any, request: Request) -> Response | None:
            if request.headers.get("Upgrade", "").lower() == "websocket":
                why = self.refusal(request)
                if why is not None:
                    with self._lock:
                        self.refused += 1
                    body = f"403 Forbidden: {why}\n".encode()
                    return Response(http.HTTPStatus.FORBIDDEN, "Forbidden",
                                    Headers({"Content-Type": "text/plain; charset=utf-8",
                                             "Content-Length": str(len(body))}), body)
                return inner(connection, request) if inner is not None else None
            if PROXY_PREFIX_HEADER in request.headers and urlsplit(request.path).path == "/":
                return _to_index_html(request)
            if self.presented_in_query(request) and _query_has(request, PRESENTER_QUERY):
                return self._presenter_link(request)
            response = inner(connection, request) if inner is not None else None
            if response is not None and self.presented_in_query(request):
                response.headers["Set-Cookie"] = self._token_cookie()
            return response

        return process_request

    def _token_cookie(self) -> str:
        # no Path: the cookie's path is the page's folder ("/" when served directly,
        # "/user/NAME/armlab" behind jupyter-server-proxy: this lab only)
        return f"{COOKIE}={self.token}; HttpOnly; SameSite=Strict"

    def _presenter_link(self, request: Request) -> Response:
        """A presenter link's page request (the right token and ``?presenter=CODE``): a
        redirect to the same URL without the passcode, so the projected address bar never
        shows it, setting the token cookie and :data:`PRESENTER_COOKIE` (``CODE`` if it
        is made of passcode characters; the classroom checks it)."""
        pairs = parse_qsl(urlsplit(request.path).query)
        code = next((v for k, v in pairs if k == PRESENTER_QUERY), "")
        rest = urlencode([(k, v) for k, v in pairs if k != PRESENTER_QUERY])
        headers = Headers({"Location": f"?{rest}", "Content-Length": "0",
                           "Cache-Control": "no-store"})
        headers["Set-Cookie"] = self._token_cookie()
        if code.isalnum() and code.isascii() and len(code) <= 64:
            headers["Set-Cookie"] = f"{self.presenter_cookie}={code}; HttpOnly; SameSite=Strict"
        return Response(http.HTTPStatus.SEE_OTHER, "See Other", headers, b"")


def cookie_values(headers: Any, name: str) -> list[str]:
    """The values of every cookie called ``name`` in ``headers`` (a request's)."""
    out = []
    for header in headers.get_all("Cookie"):
        for part in header.split(";"):
            key, _, value = part.strip().partition("=")
            if key == name:
                out.append(value)
    return out


def _query_has(request: Request, key: str) -> bool:
    return key in parse_qs(urlsplit(request.path).query, keep_blank_values=True)


#: set by jupyter-server-proxy on what it forwards: the prefix it cut off (armlab.app.lab.jupyter)
PROXY_PREFIX_HEADER = "X-Forwarded-Context"


def _to_index_html(request: Request) -> Response:
    """A redirect from the lab's root to ``index.html`` with the same query, for a page
    asked for through jupyter-server-proxy (``/user/NAME/armlab/``): viser's page opens its
    websocket on its own address less one trailing slash, and ``/user/NAME/armlab`` is
    Jupyter's (a redirect) while ``/user/NAME/armlab/index.html`` reaches the lab. The
    ``Location`` is relative, so the browser keeps the prefix. Not a security check: a
    request without the header (served directly) is never redirected."""
    query = urlsplit(request.path).query
    location = "index.html" + (f"?{query}" if query else "")
    return Response(http.HTTPStatus.FOUND, "Found",
                    Headers({"Location": location, "Content-Length": "0"}), b"")


class MessageDrops:
    """Client messages dropped before viser's handlers because they could not be read
    (an unknown type, a missing or malformed field, a text frame): counted, one log line
    per :attr:`interval` s at most, of at most 200 characters.

    Attributes:
        count: messages dropped so far (every lab of this process).
    """

    def __init__(self, *, interval: float = 1.0) -> None:
        self.count = 0
        self.interval = interval
        self._last = -math.inf
        self._lock = threading.Lock()

    def note(self, exc: BaseException) -> None:
        with self._lock:
            self.count += 1
            now = time.monotonic()
            if now - self._last < self.interval:
                return
            self._last = now
            count = self.count
        line = (f"armlab: dropped {count} unreadable client message(s) so far (last: "
                f"{type(exc).__name__}: {exc})")
        print(line[:200], file=sys.stderr, flush=True)


#: the drops of this process (read by tests and the fuzz bench)
DROPS = MessageDrops()


async def screened_consumer(websocket: Any, handle_message: Callable[[Any], None],
                            message_class: Any) -> None:
    """viser's per-connection receive loop, with a message it cannot read dropped and
    counted (:data:`DROPS`) instead of ending the connection with a traceback."""
    while True:
        raw = await websocket.recv()
        try:
            if not isinstance(raw, bytes):
                raise TypeError("a text frame")
            message = message_class.deserialize(raw)
        except Exception as exc:  # anything a client can send must not end the server's loop
            DROPS.note(exc)
            continue
        handle_message(message)


@contextmanager
def gated(gate: Gate) -> Iterator[Front]:
    """Put ``gate`` in front of the ``viser.ViserServer`` constructed inside this block
    (the constructor starts its websockets server before it returns), and
    :func:`screened_consumer` behind it. After the block, call the result's ``confirm()``
    (raises :class:`HookNotPlaced` if the server did not go through the gate: stop it).

    Raises:
        HookNotPlaced: the gate's hook cannot be put in place in the installed viser
            (:func:`armlab.app.viser_ext.websocket.missing`); nothing was started.
    """
    with front(gate.wrap, consumer=screened_consumer) as placed:
        yield placed
