"""The gate in front of the lab's websocket (armlab/app/classroom/gate.py): token and Origin, before
any state.

Raw websocket clients and a real Chromium, against the whole lab on a free loopback port.
"""

from __future__ import annotations

import http.client
import http.server
import threading
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from urllib.parse import urlsplit

import pytest
import viser
from _helpers import wait_for
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from armlab.app.classroom.gate import COOKIE, PRESENTER_COOKIE, Gate, check_token
from armlab.app.testing.wsclient import HeadlessClient
from armlab.control.params import DEFAULT

pytestmark = pytest.mark.realtime  # a served lab whose loop runs on the wall clock

PROTOCOL = [f"viser-v{viser.__version__}"]


def ws_base(lab) -> str:  # noqa: ANN001
    """``ws://127.0.0.1:PORT/`` of the lab (no token)."""
    parts = urlsplit(lab.url)
    return f"ws://{parts.netloc}/"


def refused(url: str, **kwargs: object) -> int:
    """The HTTP status of a refused websocket upgrade (fails if it was accepted)."""
    with pytest.raises(InvalidStatus) as e:
        with connect(url, subprotocols=PROTOCOL, open_timeout=30, **kwargs):
            pass
    return e.value.response.status_code


def test_a_websocket_without_the_token_or_from_another_origin_is_refused_before_any_state(lab):
    base = ws_base(lab)
    assert refused(base) == 403
    assert refused(base + "?token=" + "x" * 22) == 403
    assert refused(base, additional_headers={"Cookie": f"{COOKIE}=wrong-token-123"}) == 403
    # the right token from a page of another site: the Origin gives it away
    assert refused(f"{base}?token={lab.token}", origin="http://evil.example:8080") == 403
    assert refused(f"{base}?token={lab.token}",
                   origin=f"http://127.0.0.1:{urlsplit(lab.url).port + 1}") == 403
    assert lab.gate.refused >= 5
    # with the token (a script, the headless client): the lab's whole page arrives
    with HeadlessClient(lab.url.replace("http://", "ws://")).connect() as client:
        client.wait_for(lambda: any(e.label == "E-STOP" for e in client.gui.values()),
                        what="the E-STOP button")
    # the lab's own origin with the token is let in
    with connect(f"{base}?token={lab.token}", subprotocols=PROTOCOL, open_timeout=30,
                 origin=f"http://{urlsplit(lab.url).netloc}") as ws:
        assert len(ws.recv(timeout=30)) > 0


def test_the_page_from_the_printed_url_sets_the_cookie_its_websocket_presents(lab):
    with urllib.request.urlopen(lab.url, timeout=30) as reply:  # the URL armlab serve prints
        cookie = reply.headers["Set-Cookie"]
    assert cookie.startswith(f"{COOKIE}={lab.token};")
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    assert "Path=" not in cookie  # the page's folder: "/" here, the proxy's prefix in Jupyter
    with urllib.request.urlopen(lab.url.split("?")[0], timeout=30) as reply:  # no token
        assert reply.status == 200 and reply.headers["Set-Cookie"] is None  # static: public
    with connect(ws_base(lab), subprotocols=PROTOCOL, open_timeout=30,
                 additional_headers={"Cookie": f"{COOKIE}={lab.token}"},
                 origin=f"http://{urlsplit(lab.url).netloc}") as ws:
        assert len(ws.recv(timeout=30)) > 0


def _head(url: str) -> tuple[int, str | None, list[str]]:
    """(status, Location, Set-Cookie values) of a GET of ``url``, not following redirects."""
    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=30)
    try:
        conn.request("GET", f"{parts.path or '/'}?{parts.query}")
        reply = conn.getresponse()
        return reply.status, reply.getheader("Location"), reply.headers.get_all("Set-Cookie") or []
    finally:
        conn.close()


def test_a_presenter_link_moves_the_passcode_from_the_address_bar_to_a_cookie(lab):
    status, location, cookies = _head(f"{lab.url}&presenter=K7QMR2XD")
    assert status == 303 and location == f"?token={lab.token}"  # the same page, no passcode
    assert lab.gate.presenter_cookie.startswith(f"{PRESENTER_COOKIE}_")  # this start's
    assert f"{lab.gate.presenter_cookie}=K7QMR2XD; HttpOnly; SameSite=Strict" in cookies
    assert any(c.startswith(f"{COOKIE}={lab.token};") for c in cookies)
    # without the token: the static page, no cookie of either kind
    status, _, cookies = _head(f"{lab.url.split('?')[0]}?presenter=K7QMR2XD")
    assert status == 200 and cookies == []
    # a value that is no passcode is not passed on
    _, _, cookies = _head(f"{lab.url}&presenter=%3Cscript%3E")
    assert not any(c.startswith(PRESENTER_COOKIE) for c in cookies)


@pytest.mark.parametrize("bad", ["", "short", "has space 123", "a/b/c/d/e", "x" * 129])
def test_a_token_that_cannot_stand_in_a_url_is_refused(bad):
    with pytest.raises(ValueError, match="token"):
        Gate(bad)
    assert check_token("Abc-def_123") == "Abc-def_123"


@contextmanager
def another_site(html: str) -> Iterator[str]:
    """A second local web server (another origin) serving ``html`` at /; yields its URL."""
    body = html.encode()

    class Page(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.browser
def test_in_chromium_the_lab_works_and_another_sites_page_gets_nothing(browser, lab):
    loop = lab.lesson.rig.loop
    page = browser.new_page()
    try:
        # the lab's own page, from the URL armlab serve prints, and again after a reload
        page.goto(lab.url)
        page.get_by_role("button", name="E-STOP").wait_for()
        page.reload()
        page.get_by_role("button", name="E-STOP").wait_for()
        # a page of another site, open in the same browser (the lab's cookie is set now),
        # opens a websocket to the lab and tries to move a gain
        ws = ws_base(lab)
        evil = f"""<html><body><script>
          window.result = {{opened: false, messages: 0, closed: false}};
          const ws = new WebSocket({ws!r}, [{PROTOCOL[0]!r}]);
          ws.onopen = () => {{ window.result.opened = true;
            ws.send("x"); }};
          ws.onmessage = () => {{ window.result.messages += 1; }};
          ws.onclose = () => {{ window.result.closed = true; }};
          ws.onerror = () => {{ window.result.closed = true; }};
        </script></body></html>"""
        with another_site(evil) as url:
            other = browser.new_page()
            try:
                refused_before = lab.gate.refused
                other.goto(url)
                wait_for(lambda: other.evaluate("window.result && window.result.closed"), 60,
                         "the other site's websocket to be refused")
                result = other.evaluate("window.result")
            finally:
                other.close()
        assert result == {"opened": False, "messages": 0, "closed": True}
        assert lab.gate.refused > refused_before
        assert loop.params == DEFAULT  # nothing reached the controller
    finally:
        page.close()
