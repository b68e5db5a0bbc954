"""The gate (app/gate.py): only the lab's own page, holding the token, gets the websocket.

Real parts: a real lab server on a free port, raw websocket clients
(app/wsclient.py), the ``armlab serve`` command in a subprocess, and a real
headless Chromium for the page from another origin.
"""

from __future__ import annotations

import functools
import http.server
import subprocess
import sys
import threading
import urllib.request

import pytest
import websockets.asyncio.client  # noqa: F401  (the raw client's transport)

from app.gate import COOKIE_NAME, Gate
from app.server import Lab, ServeOptions
from app.wsclient import HeadlessClient


def test_gate_lets_in_only_own_origin_with_the_token():
    gate = Gate("s3cret")
    own = {"host": "127.0.0.1:8080", "cookie": None}
    assert gate.why_refused(path="/?token=s3cret", origin=None, **own) is None
    assert gate.why_refused(path="/?token=s3cret", origin="http://127.0.0.1:8080", **own) is None
    assert gate.why_refused(path="/", origin="http://127.0.0.1:8080", host="127.0.0.1:8080",
                            cookie=f"a=b; {COOKIE_NAME}=s3cret") is None
    assert "token" in gate.why_refused(path="/", origin=None, **own)
    assert "token" in gate.why_refused(path="/?token=s3cre", origin=None, **own)
    assert "token" in gate.why_refused(path="/", origin=None, host="h",
                                       cookie=f"{COOKIE_NAME}=wrong")
    assert "origin" in gate.why_refused(path="/?token=s3cret", origin="http://evil.example", **own)
    assert "origin" in gate.why_refused(path="/?token=s3cret", origin="http://127.0.0.1:9999",
                                        **own)
    for bad in ("", "a b", "x;y", 3):
        with pytest.raises(ValueError, match="token"):
            Gate(bad)  # type: ignore[arg-type]


def _ws(url: str) -> str:
    return url.replace("http://", "ws://")


def test_raw_client_needs_the_token_and_the_page_sets_the_cookie():
    with Lab(ServeOptions(http_port=0, token="abc123")) as lab:
        assert lab.url == f"{lab.base_url}/?token=abc123"
        with pytest.raises(ConnectionError, match="403"):
            HeadlessClient(_ws(lab.base_url)).connect()
        with pytest.raises(ConnectionError, match="403"):
            HeadlessClient(_ws(lab.base_url) + "/?token=wrong").connect()
        assert lab.gate.refused == 2
        with HeadlessClient(_ws(lab.url)).connect() as page:
            page.wait_for(lambda: any(e.label == "E-STOP" for e in page.gui.values()),
                          what="the E-STOP button")
        # static files stay public; fetched with the token, the page sets the cookie
        with urllib.request.urlopen(lab.base_url, timeout=5) as reply:
            assert reply.status == 200 and reply.headers.get("Set-Cookie") is None
        with urllib.request.urlopen(lab.url, timeout=5) as reply:
            cookie = reply.headers.get("Set-Cookie")
        assert cookie.startswith(f"{COOKIE_NAME}=abc123;") and "HttpOnly" in cookie


def test_each_lab_start_gets_a_new_random_token():
    with Lab(ServeOptions(http_port=0)) as a, Lab(ServeOptions(http_port=0)) as b:
        assert a.token != b.token and len(a.token) >= 32


def test_armlab_serve_prints_the_url_with_the_token():
    proc = subprocess.Popen([sys.executable, "-m", "app", "serve", "--http-port", "0",
                             "--token", "tok42"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("url: http://127.0.0.1:") and line.rstrip().endswith("/?token=tok42")
        with HeadlessClient(_ws(line.split()[1])).connect() as page:
            page.wait_for(lambda: any(e.label == "E-STOP" for e in page.gui.values()),
                          what="the E-STOP button")
    finally:
        proc.terminate()
        proc.wait(30)


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # keep the test output clean
        pass


@pytest.mark.browser
@pytest.mark.timeout(300)
def test_in_chromium_the_printed_url_works_and_another_origin_gets_nothing(browser, lab,
                                                                          tmp_path):
    pg = browser.new_page()
    try:
        pg.goto(lab.url)
        pg.get_by_role("button", name="E-STOP").wait_for(timeout=90_000)
        pg.reload()  # the cookie keeps it working (and the token stays in the url)
        pg.get_by_role("button", name="E-STOP").wait_for(timeout=90_000)
        pg.goto(lab.base_url)  # no token in the url: the cookie alone lets it in
        pg.get_by_role("button", name="E-STOP").wait_for(timeout=90_000)
    finally:
        pg.close()
    # a page from another origin opens a websocket to the lab, token in hand or not
    port = lab.base_url.rsplit(":", 1)[1]
    (tmp_path / "evil.html").write_text(f"""<script>
      window.result = [];
      for (const q of ["", "?token={lab.token}"]) {{
        const ws = new WebSocket("ws://127.0.0.1:{port}/" + q, ["viser-v{_viser_version()}"]);
        ws.binaryType = "arraybuffer";
        let bytes = 0;
        ws.onmessage = (e) => {{ bytes += e.data.byteLength; }};
        ws.onclose = () => window.result.push(bytes);
      }}
    </script>""")
    handler = functools.partial(_Quiet, directory=str(tmp_path))
    other = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=other.serve_forever, daemon=True).start()
    refused_before = lab.gate.refused
    pg = browser.new_page()
    try:
        pg.goto(f"http://127.0.0.1:{other.server_address[1]}/evil.html")
        pg.wait_for_function("window.result.length === 2", timeout=60_000)
        assert pg.evaluate("window.result") == [0, 0]  # no state, nothing to drive
        assert lab.gate.refused == refused_before + 2
    finally:
        pg.close()
        other.shutdown()


def _viser_version() -> str:
    import viser
    return viser.__version__
