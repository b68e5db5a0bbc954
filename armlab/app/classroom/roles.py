"""Roles in a classroom (``armlab serve --classroom``): who may change the shared arm.

The **shared arm** is the one every page shows (the projected arm; the real servos
with ``--backend serial``). In a classroom only a **presenter** changes it: a browser
becomes one by typing the passcode ``armlab serve`` printed into its "Passcode" field.
Every other browser follows: it sees the arm, its plots and its status, and may press
E-STOP (that only makes things safe), but the server *refuses* anything else it sends
to the shared arm. Hiding controls would not be enough: a hand-made websocket message
from a student must not move the arm.

Where the check sits: every message a browser sends passes the gate
(:mod:`armlab.app.classroom.gate`: token, Origin, unreadable messages dropped), then
:meth:`Roles.admits`, installed in front of viser's dispatch to the server's own
handlers (the shared GUI and scene). A message for an element a page owns by itself
(its Passcode and name fields) goes to that page's handlers only and is
not the shared arm's business. Refused: a change of a shared control (the page's
widget is put back to the server's value), a click or drag in the shared scene, an
upload, a command. Admitted from anyone: the controls :meth:`Roles.open` lists
(E-STOP, Frame, a lesson's Save run and Export page), the camera, the share request
(which the lab refuses anyway), and the page's answers to the server's questions (its
localStorage, a render), which its person did not send.

Passcodes are compared in constant time (``hmac.compare_digest``), and guesses from
one network address are slowed down (:class:`Guesses`).
"""

from __future__ import annotations

import hmac
import math
import secrets
import threading
import time
from collections.abc import Callable
from typing import Any

import viser

from armlab.app.classroom.gate import cookie_values
from armlab.app.page.inputs import notify
from armlab.app.viser_ext.clients import connection_of
from armlab.app.viser_ext.dispatch import screen_server_messages
from armlab.app.viser_ext.handles import gui_inputs, scene_scope_of, uuid_of
from armlab.app.viser_ext.messages import is_gui_update
from armlab.app.viser_ext.page_js import set_props

#: letters and digits that cannot be mistaken for one another on a projector
PASSCODE_ALPHABET = "ABCDEFGHJKMNPQRSTUVWXYZ23456789"
#: characters of a passcode (31^8 ≈ 8.5e11 codes)
PASSCODE_LENGTH = 8
#: message types anyone may send to the server's handlers (they change nothing shared);
#: the last two are a page's answers to the server's own questions (its localStorage, a
#: render), which the page sends by itself (three on every connect): only the asking
#: page's own handlers take them
OPEN_MESSAGES = frozenset({"ViewerCameraMessage", "ShareUrlRequest", "ShareUrlDisconnect",
                           "GuiFormDirtyMessage", "LocalStorageGetItemResponseMessage",
                           "GetRenderResponseMessage"})
#: viser's inputs that are pressed, not set
BUTTONS = (viser.GuiButtonHandle, viser.GuiButtonGroupHandle, viser.GuiUploadButtonHandle)
#: s between two "only the presenter" notifications to one page
REFUSAL_INTERVAL = 2.0
#: a page's longest name, characters
MAX_NAME = 30


def new_passcode() -> str:
    """A random passcode: :data:`PASSCODE_LENGTH` characters of :data:`PASSCODE_ALPHABET`."""
    return "".join(secrets.choice(PASSCODE_ALPHABET) for _ in range(PASSCODE_LENGTH))


def normal_passcode(text: str) -> str:
    """What a person typed, as a passcode: spaces and dashes dropped, upper case."""
    return "".join(c for c in str(text) if c not in " -\t").upper()


class Guesses:
    """Wrong passcode guesses, slowed down per key (a network address).

    The first :attr:`free` wrong guesses cost nothing; after that each wrong guess makes
    the key wait ``base · 2^(k - free)`` s (at most :attr:`cap`) before its next guess is
    even compared. A right guess clears the key.

    Args:
        free: wrong guesses before any wait.
        base, cap: first wait and longest wait, s.
        clock: monotonic seconds (tests pass a fake one).
    """

    def __init__(self, *, free: int = 3, base: float = 1.0, cap: float = 60.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.free, self.base, self.cap = free, base, cap
        self._clock = clock
        self._wrong: dict[Any, int] = {}
        self._until: dict[Any, float] = {}
        self._lock = threading.Lock()

    def wait_left(self, key: Any) -> float:
        """s before ``key`` may guess again (0: now)."""
        with self._lock:
            return max(0.0, self._until.get(key, -math.inf) - self._clock())

    def wrong(self, key: Any) -> float:
        """Count a wrong guess of ``key``; returns the wait it now has, s."""
        with self._lock:
            k = self._wrong.get(key, 0) + 1
            self._wrong[key] = k
            wait = 0.0 if k <= self.free else min(self.cap, self.base * 2.0 ** (k - self.free - 1))
            self._until[key] = self._clock() + wait
            return wait

    def right(self, key: Any) -> None:
        """Forget ``key``'s wrong guesses."""
        with self._lock:
            self._wrong.pop(key, None)
            self._until.pop(key, None)


class Roles:
    """Presenters and followers of one lab; refuses followers' changes of the shared arm.

    Args:
        server: the lab's viser server; :meth:`admits` is put in front of its dispatch.
        passcode: the code that makes a page presenter (:func:`new_passcode`).
        guesses: the slowdown of wrong guesses (default :class:`Guesses`).

    Attributes:
        passcode: the code.
        guesses: the slowdown of wrong guesses.
        refused: messages refused so far.
    """

    def __init__(self, server: viser.ViserServer, passcode: str, *,
                 guesses: Guesses | None = None) -> None:
        code = normal_passcode(passcode)
        if len(code) < 6:
            raise ValueError("passcode: use at least 6 letters or digits")
        self.passcode = code
        self.refused = 0
        self._server = server
        self.guesses = guesses or Guesses()
        self._presenters: set[int] = set()
        self._names: dict[int, str] = {}
        self._open: set[str] = set()
        self._last_told: dict[int, float] = {}
        self._lock = threading.Lock()
        self._dispatch = screen_server_messages(server, self._screen)

    # -- who is who -------------------------------------------------------------

    def open(self, *handles: Any) -> None:
        """Let anyone use these shared controls (E-STOP: pressing it only makes things safe)."""
        with self._lock:
            self._open.update(uuid_of(h) for h in handles)

    def is_presenter(self, client_id: int) -> bool:
        """Whether page ``client_id`` presents (changes the shared arm)."""
        with self._lock:
            return client_id in self._presenters

    def presenters(self) -> tuple[int, ...]:
        """Client ids of the presenting pages."""
        with self._lock:
            return tuple(sorted(self._presenters))

    def name(self, client_id: int) -> str:
        """The name page ``client_id`` gave, or an automatic one."""
        with self._lock:
            given = self._names.get(client_id)
            if given:
                return given
            return f"presenter {client_id}" if client_id in self._presenters \
                else f"student {client_id}"

    def set_name(self, client_id: int, text: str) -> str:
        """Keep what page ``client_id`` typed as its name (printable, at most
        :data:`MAX_NAME` characters); returns the name kept."""
        clean = "".join(c for c in str(text) if c.isprintable()).strip()[:MAX_NAME]
        with self._lock:
            self._names[client_id] = clean
        return self.name(client_id)

    def forget(self, client_id: int) -> None:
        """Page ``client_id`` left: it presents no more."""
        with self._lock:
            self._presenters.discard(client_id)
            self._names.pop(client_id, None)
            self._last_told.pop(client_id, None)

    def try_passcode(self, client_id: int, text: str, *, key: Any = None) -> str | None:
        """Make page ``client_id`` presenter if ``text`` is the passcode.

        Args:
            key: who guesses, for the slowdown (the page's network address; default the
                client id).

        Returns:
            None when it now presents, else why not (wrong, or wait N s).
        """
        key = client_id if key is None else key
        wait = self.guesses.wait_left(key)
        if wait > 0:
            return f"too many wrong passcodes: try again in {math.ceil(wait)} s"
        if not hmac.compare_digest(normal_passcode(text).encode(), self.passcode.encode()):
            wait = self.guesses.wrong(key)
            later = f"; the next try in {math.ceil(wait)} s" if wait > 0 else ""
            return f"that is not the passcode armlab serve printed{later}"
        self.guesses.right(key)
        with self._lock:
            self._presenters.add(client_id)
        return None

    # -- the check ----------------------------------------------------------------

    def admits(self, client_id: int, message: Any) -> bool:
        """Whether the server's own handlers may act on ``message`` from ``client_id``."""
        if self.is_presenter(client_id):
            return True
        kind = type(message).__name__
        if kind in OPEN_MESSAGES:
            return True
        if is_gui_update(message):
            if message.uuid not in gui_inputs(self._server.gui):
                return True  # not a shared control: the server's handler ignores it
            with self._lock:
                return message.uuid in self._open
        owner = getattr(message, "owner", None)
        if owner is not None and owner != scene_scope_of(self._server.scene):
            return True  # a page's own scene node, not the shared scene
        source = getattr(message, "source_component_uuid", None)
        if isinstance(source, str) and source not in gui_inputs(self._server.gui):
            return True  # an upload to a page's own button: the server's handler ignores it
        return False

    async def _screen(self, client_id: Any, message: Any) -> None:
        if self.admits(client_id, message):
            await self._dispatch(client_id, message)
            return
        with self._lock:
            self.refused += 1
            now = time.monotonic()
            due = now - self._last_told.get(client_id, -math.inf) >= REFUSAL_INTERVAL
            if due:
                self._last_told[client_id] = now
        client = self._server.get_clients().get(client_id)
        if client is None:
            return
        if is_gui_update(message):
            self._put_back(client, message.uuid)
        if due:
            notify(client, "Only the presenter changes the shared arm",
                   "Type the passcode in the Passcode field to present.")

    def _put_back(self, client: viser.ClientHandle, uuid: str) -> None:
        """Show the refused control at the server's value again on that page only."""
        handle = gui_inputs(self._server.gui).get(uuid)
        if handle is None or isinstance(handle, BUTTONS):
            return  # a press has no value to put back
        set_props(client, handle, value=handle.value)


def presenter_link_code(server: viser.ViserServer, client_id: int, cookie: str
                        ) -> str | None:
    """The passcode a presenter link left in page ``client_id``'s browser (the cookie
    ``cookie``, :attr:`armlab.app.classroom.gate.Gate.presenter_cookie`, its websocket upgrade
    carried),
    or None."""
    headers = getattr(getattr(connection_of(server, client_id), "request", None), "headers",
                      None)
    values = [] if headers is None else cookie_values(headers, cookie)
    return values[-1] if values else None


def address_of(server: viser.ViserServer, client_id: int) -> str | int:
    """The network address page ``client_id`` connects from (its client id if unknown)."""
    try:
        return str(connection_of(server, client_id).remote_address[0])
    except (AttributeError, IndexError, TypeError):
        return client_id


#: The names of this machine only: a class listening on one of them cannot be joined.
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def loopback_warning(host: str) -> str | None:
    """What a class listening on ``host`` tells its teacher, on the console and on the
    presenter's page, when no other machine can join it (None: others can)."""
    if host not in LOOPBACK_HOSTS:
        return None
    return (f"The class listens on {host} only: students' phones and laptops cannot join. "
            "Start it with --host 0.0.0.0 (or this machine's address on the room's network).")


def qr_svg(url: str, *, scale: int = 4) -> str:
    """The QR code of ``url`` as inline SVG (dark on white, a quiet zone around it)."""
    import segno

    return segno.make(url, error="m").svg_inline(scale=scale, dark="#000", light="#fff")

