"""A minimal real viser client for server-side lesson tests (no browser).

It speaks the viser 1.1 websocket protocol: connects with the version
subprotocol, sends a camera message (a client counts as connected only after
its first one), sends GUI updates as the browser does when a person types or
clicks, and decodes what the server sends back (zstd-compressed msgpack) so a
test can see the notifications that person would see.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import msgspec.msgpack
import viser
import websockets.sync.client
import zstandard


class ViserTestClient:
    """One websocket client of ``server`` (use as a context manager)."""

    def __init__(self, server: viser.ViserServer, *, timeout: float = 10.0) -> None:
        self.server = server
        before = set(server.get_clients())
        self.ws = websockets.sync.client.connect(
            f"ws://127.0.0.1:{server.get_port()}",
            subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
            max_size=None, open_timeout=timeout)
        self.messages: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self._send({"type": "ViewerCameraMessage", "wxyz": (1.0, 0.0, 0.0, 0.0),
                    "position": (0.3, -0.3, 0.3), "fov": 1.0, "near": 0.01, "far": 100.0,
                    "image_height": 600, "image_width": 800, "look_at": (0.0, 0.0, 0.0),
                    "up_direction": (0.0, 0.0, 1.0)})
        deadline = time.monotonic() + timeout
        while not (set(server.get_clients()) - before):
            if time.monotonic() > deadline:
                raise TimeoutError("the server never registered the test client")
            time.sleep(0.01)
        self.client_id = max(set(server.get_clients()) - before)

    def _send(self, message: dict[str, Any]) -> None:
        self.ws.send(msgspec.msgpack.encode(message))

    def _read(self) -> None:
        dctx = zstandard.ZstdDecompressor()
        while not self._stop.is_set():
            try:
                raw = self.ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            except websockets.exceptions.ConnectionClosed:
                return
            if not isinstance(raw, bytes | bytearray) or len(raw) < 16:
                continue
            size = int.from_bytes(raw[0:8], "little")
            clen = int.from_bytes(raw[8:16], "little")
            inner = dctx.decompress(bytes(raw[16:16 + clen]), max_output_size=size)
            batch = msgspec.msgpack.decode(inner)
            with self._lock:
                self.messages.extend(batch.get("messages", ()))

    def set_value(self, handle: Any, value: Any) -> None:
        """Send a GUI value as a browser does when a person types it or clicks a button."""
        self._send({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid,
                    "updates": {"value": value}})

    def click(self, button: Any) -> None:
        """Click a GUI button."""
        self.set_value(button, True)

    def drag(self, gizmo: Any, positions: list[tuple[float, float, float]]) -> None:
        """Drag a transform-controls gizmo through ``positions`` (parent frame, m)."""
        name = gizmo.name
        self._send({"type": "TransformControlsDragStartMessage", "name": name, "owner": ""})
        for p in positions:
            self._send({"type": "TransformControlsUpdateMessage", "name": name,
                        "wxyz": (1.0, 0.0, 0.0, 0.0), "position": tuple(map(float, p)),
                        "owner": ""})
        self._send({"type": "TransformControlsDragEndMessage", "name": name, "owner": ""})

    def notifications(self) -> list[tuple[str, str]]:
        """(title, body) of every notification shown to this client so far."""
        with self._lock:
            found = [m for m in self.messages if m.get("type") == "NotificationShowMessage"]
        return [(m["props"]["title"], m["props"]["body"]) for m in found]

    def wait_notification(self, title: str, *, timeout: float = 5.0) -> str:
        """Body of the first notification titled ``title`` (waits for it)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for t, body in self.notifications():
                if t == title:
                    return body
            time.sleep(0.02)
        raise AssertionError(f"no notification {title!r}; got {self.notifications()}")

    def close(self) -> None:
        self._stop.set()
        self.ws.close()
        self._reader.join(timeout=2.0)

    def __enter__(self) -> ViserTestClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
