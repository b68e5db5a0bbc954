"""The lab served through jupyter-server-proxy on a real ``jupyter_server`` (loopback only):
the launcher tile's address loads the page, and a slider set through the prefixed websocket
reaches the control loop (issue 16, "Beyond one machine").

The test starts ``python -m jupyter_server`` with its own token, reads the launcher tile
from the proxy's ``/server-proxy/servers-info`` (as JupyterLab does), asks for that address
(the proxy starts ``armlab serve``), then opens two websockets on the address viser's page
would compute (its own address less query and trailing slash), with the browser's headers:
``Origin`` (the Jupyter server's), the ``armlab_token`` cookie the page set and Jupyter's
login. Once the status line shows the arm holding (gains are refused while it is being
built), one moves Kp; the other sees the slider's new value and the Teach panel's design
table (ωp = √Kp) written from the running loop's parameters; a page of another site is
refused. At the end the Jupyter server stops and takes
the lab with it (no process left).
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from http.cookies import SimpleCookie
from pathlib import Path
from typing import Any

import pytest
import viser
import websockets.exceptions
from websockets.sync.client import connect

pytest.importorskip("jupyter_server")
pytest.importorskip("jupyter_server_proxy")

from websockets.datastructures import Headers  # noqa: E402
from websockets.http11 import Request, Response  # noqa: E402

from armlab.app.classroom.gate import COOKIE, Gate  # noqa: E402
from armlab.app.lab.jupyter import TOKEN_ENV, setup_armlab  # noqa: E402
from armlab.app.testing.wsclient import HeadlessClient  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
JUPYTER_TOKEN = "jupyter-test-token-4f1c"
TIMEOUT = 120.0  # s: a loaded 2-core machine starting two servers
KP = "Kp (1/s²)"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def poll(what: str, attempt: Callable[[], Any], timeout: float = TIMEOUT) -> Any:
    """``attempt()``'s first result that is not None (retried on OSError/HTTP errors)."""
    deadline = time.monotonic() + timeout
    last: object = None
    while time.monotonic() < deadline:
        try:
            result = attempt()
            if result is not None:
                return result
        except (OSError, urllib.error.URLError) as exc:
            last = exc
        time.sleep(0.2)
    raise TimeoutError(f"{what}: nothing in {timeout} s (last: {last})")


class NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args: Any, **kwargs: Any) -> None:
        return None


def get(url: str, *, follow: bool = True) -> tuple[int, dict[str, list[str]], bytes]:
    """GET with Jupyter's login header: (status, headers, body); 3xx returned as is."""
    request = urllib.request.Request(url, headers={"Authorization": f"token {JUPYTER_TOKEN}"})
    opener = urllib.request.build_opener() if follow else urllib.request.build_opener(NoRedirect)
    try:
        with opener.open(request, timeout=30) as reply:
            headers: dict[str, list[str]] = {}
            for k, v in reply.headers.items():
                headers.setdefault(k.lower(), []).append(v)
            return reply.status, headers, reply.read()
    except urllib.error.HTTPError as exc:
        headers = {}
        for k, v in exc.headers.items():
            headers.setdefault(k.lower(), []).append(v)
        return exc.code, headers, exc.read()


def page_text(client: HeadlessClient) -> str:
    """Every markdown and HTML text the page shows, joined."""
    with client._lock:
        return "\n".join(str(e.props.get(k, "")) for e in client.gui.values()
                         for k in ("_markdown", "content"))


def labs_running(jupyter_pid: int) -> list[int]:
    """Pids of the ``armlab.app serve`` children of the Jupyter server (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid == jupyter_pid and b"serve" in cmd and b"armlab.app" in cmd:
            found.append(int(entry.name))
    return found


@pytest.fixture
def jupyter(tmp_path: Path) -> Iterator[tuple[str, subprocess.Popen, Callable[[], str]]]:
    port = free_port()
    env = {k: v for k, v in os.environ.items() if k != "ARMLAB_TOKEN"}
    env.update(PYTHONUNBUFFERED="1", JUPYTER_RUNTIME_DIR=str(tmp_path / "runtime"),
               JUPYTER_CONFIG_DIR=str(tmp_path / "config"),
               JUPYTER_DATA_DIR=str(tmp_path / "data"))
    args = [sys.executable, "-m", "jupyter_server", "--ServerApp.ip=127.0.0.1",
            f"--ServerApp.port={port}", "--ServerApp.port_retries=0",
            f"--ServerApp.token={JUPYTER_TOKEN}", "--no-browser",
            f"--ServerApp.root_dir={tmp_path}"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        args.append("--allow-root")
    log = open(tmp_path / "jupyter.log", "w")  # noqa: SIM115 (closed below)
    proc = subprocess.Popen(args, cwd=tmp_path, env=env, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        poll("the Jupyter server", lambda: get(f"{base}/api/status")[0] == 200 or None)
        yield base, proc, lambda: (tmp_path / "jupyter.log").read_text()[-3000:]
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
        finally:
            try:  # the backstop: nothing of the session survives the test
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            log.close()


def _request(path: str, **headers: str) -> Request:
    return Request(path, Headers({"Host": "127.0.0.1:9", **headers}))


def _page(connection: object, request: Request) -> Response:  # viser's static files
    return Response(200, "OK", Headers({"Content-Length": "0"}), b"")


def test_the_entry_point_names_the_command_the_tile_and_keeps_the_token_off_the_command_line(
        monkeypatch):
    monkeypatch.delenv(TOKEN_ENV, raising=False)
    a, b = setup_armlab(), setup_armlab()
    token = a["environment"][TOKEN_ENV]
    assert token != b["environment"][TOKEN_ENV]  # new at each start of the Jupyter server
    assert a["command"][1:] == ["-m", "armlab.app", "serve", "--http-port", "{port}"]
    assert not any(token in part for part in a["command"])  # `ps` shows the command line
    entry = a["launcher_entry"]
    assert entry["path_info"] == f"armlab/index.html?armlab_token={token}"
    assert Path(entry["icon_path"]).is_file() and a["timeout"] >= 30
    monkeypatch.setenv(TOKEN_ENV, "fixed-token-for-a-course")
    assert setup_armlab()["environment"][TOKEN_ENV] == "fixed-token-for-a-course"
    monkeypatch.setenv(TOKEN_ENV, "bad token!")
    with pytest.raises(ValueError):
        setup_armlab()


def test_the_gate_reads_armlab_token_and_sends_only_proxied_root_requests_to_index_html():
    gate = Gate("the-token-1234")
    wrapped = gate.wrap(_page)
    upgrade = {"Upgrade": "websocket", "Origin": "http://127.0.0.1:9"}
    assert gate.refusal(_request("/?armlab_token=the-token-1234", **upgrade)) is None
    assert gate.refusal(_request("/?armlab_token=wrong-token-12", **upgrade)) is not None
    # the page for a URL with the token sets the cookie for the page's own folder
    cookie = wrapped(None, _request("/index.html?armlab_token=the-token-1234")
                     ).headers["Set-Cookie"]
    assert cookie.startswith(f"{COOKIE}=the-token-1234;") and "Path" not in cookie
    # through jupyter-server-proxy (its prefix header), "/" goes to index.html, query kept
    moved = wrapped(None, _request("/?armlab_token=the-token-1234",
                                   **{"X-Forwarded-Context": "/user/ana/armlab"}))
    assert moved.status_code == 302
    assert moved.headers["Location"] == "index.html?armlab_token=the-token-1234"
    assert wrapped(None, _request("/?token=the-token-1234")).status_code == 200  # direct
    # the redirect is for pages only: a proxied websocket upgrade meets the gate
    assert wrapped(None, _request("/", **upgrade, **{"X-Forwarded-Context": "/x"})
                   ).status_code == 403


@pytest.mark.realtime  # a Jupyter server and a lab on the wall clock
@pytest.mark.timeout(900)  # two servers started, each given 120 s
def test_the_launcher_tile_serves_the_lab_and_a_slider_reaches_the_loop(jupyter):
    base, proc, log_tail = jupyter
    t0 = time.monotonic()
    status, _, body = get(f"{base}/server-proxy/servers-info")
    assert status == 200, body[:300]
    (armlab,) = [s for s in json.loads(body)["server_processes"] if s["name"] == "armlab"]
    entry = armlab["launcher_entry"]
    assert entry["enabled"] and entry["title"] == "armlab" and armlab["new_browser_tab"]
    path_info = entry["path_info"]
    assert path_info.startswith("armlab/index.html?armlab_token=")
    token = path_info.split("=", 1)[1]

    # the first request starts the lab (the proxy waits for it); poll until the page loads
    page_url = f"{base}/{path_info}"
    status, headers, body = poll(
        "the lab's page through the proxy",
        lambda: r if (r := get(page_url))[0] == 200 else None)
    assert b"<title>Viser</title>" in body and b'id="root"' in body
    cookies = SimpleCookie()
    for line in headers.get("set-cookie", []):
        cookies.load(line)
    assert cookies["armlab_token"].value == token
    assert cookies["armlab_token"]["path"] == ""  # the page's folder: /armlab here
    assert (pids := labs_running(proc.pid)), "the proxy started no armlab serve"

    # a typed or bookmarked /armlab/ is sent on to index.html (keeping the query)
    status, headers, _ = get(f"{base}/armlab/?armlab_token={token}", follow=False)
    assert status == 302 and headers["location"] == [f"index.html?armlab_token={token}"]

    # the websocket the page opens: its own address less query (no trailing slash here)
    ws_url = page_url.split("?")[0].replace("http://", "ws://")
    browser = {"Origin": base, "Cookie": f"armlab_token={token}",
               "Authorization": f"token {JUPYTER_TOKEN}"}
    with HeadlessClient(ws_url, headers=browser).connect(TIMEOUT) as mover, \
            HeadlessClient(ws_url, headers=browser).connect(TIMEOUT) as watcher:
        for client in (mover, watcher):
            client.wait_for(lambda c=client: any(e.label == KP for e in c.gui.values()),
                            TIMEOUT, "the Kp slider through the proxy")
        # the arm is built after the page (gains are refused until then): its status line
        watcher.wait_for(lambda: "holding" in page_text(watcher), TIMEOUT,
                         "the status line to show the arm holding")
        kp0 = watcher.find(KP).value
        kp = 31.5 if kp0 != 31.5 else 33.5
        omega = f"√Kp (2.11) | {math.sqrt(kp):.3g} rad/s"  # the Teach panel's ωp, below
        assert omega not in page_text(watcher)
        mover.set_value(KP, kp)
        try:
            watcher.wait_for(lambda: watcher.find(KP).value == pytest.approx(kp), TIMEOUT,
                             "the other page to show the new Kp")
        except TimeoutError:
            sliders = [(c is mover, e.uuid, e.value) for c in (mover, watcher)
                       for e in list(c.gui.values()) if e.label == KP]
            raise AssertionError(f"Kp not echoed: {sliders} {mover.notifications} "
                                 f"{watcher.notifications} {log_tail()}") from None

        # the Teach panel's design table is written from the running loop's parameters
        # (loop.params, not the slider): ωp = √Kp (2.11)
        try:
            watcher.wait_for(lambda: omega in page_text(watcher), TIMEOUT,
                             f"the Teach panel to use Kp {kp}")
        except TimeoutError:
            raise AssertionError(f"no {omega!r} in the Teach panel: "
                                 f"{page_text(watcher)[:3000]}") from None

    # a page of another site is refused by the lab's gate: no state reaches it
    with pytest.raises((websockets.exceptions.InvalidStatus,
                        websockets.exceptions.ConnectionClosed)):
        with connect(ws_url, subprotocols=[f"viser-v{viser.__version__}"], open_timeout=30,
                     additional_headers={**browser, "Origin": "http://evil.example"}) as ws:
            ws.recv(timeout=30)

    # the Jupyter server's stop takes the lab down with it
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=60)
    poll("the lab to stop with the Jupyter server",
         lambda: True if not any(Path(f"/proc/{p}").exists() and
                                 "Z" not in Path(f"/proc/{p}/stat").read_text().split()[2]
                                 for p in pids) else None, 60.0)
    print(f"jupyter proxy test: {time.monotonic() - t0:.1f} s")
