"""A plainer 3D look for a page whose browser draws WebGL in software.

A school laptop without a working GPU driver (or with its GPU block-listed, or a
remote desktop) draws WebGL on the CPU (SwiftShader, llvmpipe). There the lab's full
look, viser's image-based lighting (an HDR environment map) and shadow maps, costs
seconds a frame, and since viser's page handles the server's messages between frames,
sliders, buttons and charts answer as slowly. Measured in Debian's headless Chromium
(SwiftShader) on a quiet 2-core machine, one compliance-lesson page at 1280x720 drew
2.9 frames/s with the full look, 6.0 without shadows and 9.1 without shadows or the
environment map.

:func:`install` sends each page, when it connects, :data:`PROBE_SCRIPT`, which reads
the page's WebGL renderer name into the page's localStorage; the server then reads it
back (``client.local_storage``) and, for a software renderer (the names viser's own
"Software WebGL rendering detected" notice looks for), turns that page's environment map
and shadows off, on that page only (``client.scene``). Pages with a GPU keep the full
look. :class:`Looks` records what each page draws with.
"""

from __future__ import annotations

import json
import threading

import viser

from armlab.app.viser_ext.page_js import LOCAL_STORAGE_PREFIX, ask_item, run_javascript

#: the page's localStorage key the probe writes the renderer name to
RENDERER_KEY = "armlab_webgl_renderer"
#: words in a WebGL renderer name that mean software rendering (as viser's page checks)
SOFTWARE_WORDS = ("swiftshader", "llvmpipe", "softpipe", "software")
#: s a page has to answer (a page still loading on a busy machine answers late), and s
#: between questions
ANSWER_WAIT_S = 180.0
ASK_EVERY_S = 4.0

#: What each page runs once: its WebGL renderer's name into localStorage ("" if the
#: browser has no WebGL). The throw-away context is released at once.
PROBE_SCRIPT = """
const canvas = document.createElement('canvas');
const gl = canvas.getContext('webgl2') || canvas.getContext('webgl');
let name = '';
if (gl) {
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
  const lose = gl.getExtension('WEBGL_lose_context');
  if (lose) lose.loseContext();
}
localStorage.setItem(%(key)s, name);
"""


def is_software(renderer: str) -> bool:
    """True for the name of a WebGL renderer that draws on the CPU."""
    return any(word in renderer.lower() for word in SOFTWARE_WORDS)


def plain(client: viser.ClientHandle) -> None:
    """Draw ``client``'s page without the environment map and without shadows (that page
    only; the default lights stay on)."""
    client.scene.configure_environment_map(None)
    client.scene.configure_default_lights(enabled=True, cast_shadow=False)


class Looks:
    """What each page of a server draws with, and the plain look for software renderers.

    Args:
        server: the lab's viser server (every page that connects from now on is asked).
        plain_on_software: False keeps the full look everywhere (the README's pictures,
            taken in headless Chromium, show what a page with a GPU shows).
    """

    def __init__(self, server: viser.ViserServer, *, plain_on_software: bool = True) -> None:
        self.plain_on_software = plain_on_software
        self._server = server
        self._renderers: dict[int, str] = {}
        self._plain: set[int] = set()
        self._settled: set[int] = set()
        self._lock = threading.Lock()
        server.on_client_connect(self._ask)
        server.on_client_disconnect(self._forget)

    def renderer(self, client_id: int) -> str | None:
        """The WebGL renderer page ``client_id`` named ("" without WebGL), or None until
        it has answered."""
        with self._lock:
            return self._renderers.get(client_id)

    def is_plain(self, client_id: int) -> bool:
        """True once page ``client_id`` has taken the plain look in."""
        with self._lock:
            return client_id in self._plain

    def settled(self, client_id: int) -> bool:
        """True once page ``client_id`` has its look for good: it named its renderer and,
        if that draws in software, has taken the plain look in (a test comparing
        pictures of the page over time waits for this)."""
        with self._lock:
            return client_id in self._settled

    def _ask(self, client: viser.ClientHandle) -> None:
        script = PROBE_SCRIPT % {"key": json.dumps(LOCAL_STORAGE_PREFIX + RENDERER_KEY)}
        if run_javascript(client, script, name="renderer probe"):
            threading.Thread(target=self._answer, args=(client,), daemon=True,
                             name="armlab-look").start()

    def _answer(self, client: viser.ClientHandle) -> None:
        """Wait for the page's answer (:func:`armlab.app.viser_ext.page_js.ask_item`), then give a
        software renderer the plain look."""
        try:
            renderer = ask_item(client, RENDERER_KEY, every=ASK_EVERY_S, within=ANSWER_WAIT_S)
        except (TimeoutError, RuntimeError):  # no answer, the page left, no localStorage
            return
        with self._lock:
            if client.client_id not in self._server.get_clients():
                return  # gone while it answered
            self._renderers[client.client_id] = renderer or ""
        if self.plain_on_software and is_software(renderer or ""):
            plain(client)
            try:  # the page answers after it has handled the plain look's messages
                client.local_storage.get_item(RENDERER_KEY, timeout=ANSWER_WAIT_S)
            except (TimeoutError, RuntimeError):
                return
            with self._lock:
                self._plain.add(client.client_id)
        with self._lock:
            self._settled.add(client.client_id)

    def _forget(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._renderers.pop(client.client_id, None)
            self._plain.discard(client.client_id)
            self._settled.discard(client.client_id)
