"""A headless viser client: speaks the page's websocket protocol without a browser.

Used by the UI bench (many fake browsers at once) and by the server-side tests
(click, type a value, drag the hand or a gizmo, disconnect mid-run). It does what
the page does on the wire:

- connects with the subprotocol ``viser-v<version>`` (the server refuses others);
- sends a ``ViewerCameraMessage`` (a client counts as connected only after its
  first camera message);
- decodes every server frame: ``[8 B msgpack length][8 B zstd length][zstd
  msgpack][padding][raw binary buffers]``, the msgpack holding
  ``{"messages": [...], "timestampSec", "binaryBufferLengths"}``;
- keeps a localStorage of its own (``LocalStorage*Message``) and answers the server's
  questions about it, as the page does (it runs no JavaScript: a key only a page
  script would write is absent);
- sends GUI changes as ``GuiUpdateMessage``, drags as ``SceneNodeDragMessage`` and
  gizmo moves as ``TransformControls*Message`` (plain msgpack dicts with a ``type`` key).

It keeps the latest state of every GUI element (by uuid, with its label) and
counts bytes and messages, so a test can ask "what does the page show now?".
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any
from uuid import uuid4

import msgspec.msgpack
import numpy as np
import viser
import websockets
import websockets.asyncio.client
import zstandard

from armlab.app.viser_ext.handles import uuid_of


def decode_frame(raw: bytes, zstd: zstandard.ZstdDecompressor | None = None
                 ) -> tuple[list[dict[str, Any]], float]:
    """One server frame -> (messages as dicts with numpy arrays restored, server timestamp).

    Args:
        raw: the websocket message.
        zstd: a decompressor to reuse (one per thread: they are not thread-safe).

    Raises:
        ValueError: when the frame is not viser's wire format.
    """
    zstd = zstd or zstandard.ZstdDecompressor()
    if len(raw) < 16:
        raise ValueError(f"frame of {len(raw)} bytes is too short")
    inner_len = int.from_bytes(raw[0:8], "little")
    comp_len = int.from_bytes(raw[8:16], "little")
    inner = zstd.decompress(raw[16:16 + comp_len], max_output_size=inner_len)
    payload = msgspec.msgpack.decode(inner)
    offset = 16 + comp_len
    buffers: list[memoryview] = []
    view = memoryview(raw)
    for n in payload.get("binaryBufferLengths", ()):
        offset += (8 - offset % 8) % 8
        buffers.append(view[offset:offset + n])
        offset += n

    def restore(obj: Any) -> Any:
        if isinstance(obj, dict):
            if "__binary_index" in obj and "dtype" in obj:
                return np.frombuffer(buffers[obj["__binary_index"]], dtype=np.dtype(obj["dtype"]))
            return {k: restore(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [restore(v) for v in obj]
        return obj

    return [restore(m) for m in payload["messages"]], float(payload.get("timestampSec", 0.0))


@dataclass
class GuiElement:
    """What the client knows of one GUI element."""

    uuid: str
    kind: str
    label: str | None
    value: Any = None
    props: dict[str, Any] = field(default_factory=dict)


class SharedLoop:
    """One thread running one asyncio event loop, for many :class:`HeadlessClient` pages
    (``HeadlessClient(url, loop=shared.loop)``): no thread per page."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, name="headless-pages",
                                        daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the loop (close the pages first)."""
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(5.0)


#: s an action on a control named by its label (:meth:`HeadlessClient.set_value`,
#: :meth:`~HeadlessClient.click`, :meth:`~HeadlessClient.upload`) waits for it to arrive
#: before it fails, as Playwright's actions wait: the server adds a panel's fields one
#: message at a time, and on a busy machine the next may not have arrived yet
ACTION_WAIT_S = 60.0

#: The server's camera messages: type -> (field, key in :attr:`HeadlessClient.camera`).
CAMERA_MESSAGES = {"SetCameraPositionMessage": ("position", "position"),
                   "SetCameraLookAtMessage": ("look_at", "look_at"),
                   "SetCameraUpDirectionMessage": ("position", "up")}


class HeadlessClient:
    """A fake browser connected to a viser server (runs its own asyncio thread, or on a
    :class:`SharedLoop`'s).

    Args:
        url: ``ws://host:port``; for the lab, ``ws://host:port/?token=T``
        (``armlab.app.classroom.gate``).
        on_message: called (in the client's thread) with each decoded message and the
            receive time (``time.perf_counter()``).
        headers: extra HTTP headers of the websocket upgrade (a browser's ``Origin`` and
            ``Cookie``, a proxy's login such as Jupyter's ``Authorization``).
        loop: a running event loop to use (``SharedLoop.loop``) instead of a thread of its
            own: many pages in one process then share one thread (a bench's 30 pages).

    Attributes:
        gui: uuid -> :class:`GuiElement`.
        scene: node name -> message type -> its fields (``Set*`` messages), and
            ``"SceneNodeUpdateMessage"`` -> the node's properties updated so far.
        notifications: (title, body) of every notification shown.
        downloads: filename -> bytes of every completed file download.
        camera: the camera the server last set: "position", "look_at", "up" (3-tuples).
        local_storage: key -> value the server stored in this page's localStorage.
        bytes_received, frames_received: traffic counters.
        counts: message type -> how many.
    """

    def __init__(self, url: str, *, on_message: Callable[[dict, float], None] | None = None,
                 headers: dict[str, str] | None = None,
                 loop: asyncio.AbstractEventLoop | None = None) -> None:
        self.url = url
        self.headers = dict(headers or {})
        self._on_message = on_message
        self.gui: dict[str, GuiElement] = {}
        self.scene: dict[str, dict[str, Any]] = defaultdict(dict)
        self.notifications: list[tuple[str, str]] = []
        self.downloads: dict[str, bytes] = {}
        self.theme: dict[str, Any] | None = None  #: the last ThemeConfigurationMessage
        self.camera: dict[str, tuple[float, ...]] = {}
        self.local_storage: dict[str, str] = {}
        self.camera_sets = 0  #: camera messages received (a move sets position and look_at)
        self._parts: dict[str, dict[str, Any]] = {}
        self.bytes_received = 0
        self.frames_received = 0
        self.counts: Counter[str] = Counter()
        self._lock = threading.RLock()  # wait_for predicates call find()
        self._own_loop = loop is None
        self._loop = asyncio.new_event_loop() if loop is None else loop
        self._started = False
        self._open_timeout = 30.0
        self._ws: websockets.asyncio.client.ClientConnection | None = None
        self._connected = threading.Event()
        self._closed = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="headless-client", daemon=True)

    # -- lifetime -----------------------------------------------------------------

    @property
    def closed(self) -> bool:
        """The connection has ended (closed here, by the server, or lost)."""
        return self._closed.is_set()

    @property
    def error(self) -> BaseException | None:
        """Why the connection failed or ended with an error (None: it did not)."""
        return self._error

    def connect(self, timeout: float = 30.0) -> HeadlessClient:
        """Connect and introduce itself with a camera message; returns self."""
        self._started = True
        self._open_timeout = timeout  # the handshake's too (websockets' own default: 10 s)
        if self._own_loop:
            self._thread.start()
        else:  # a loop already running in another thread (:class:`SharedLoop`)
            asyncio.run_coroutine_threadsafe(self._main(), self._loop)
        if not self._connected.wait(timeout):
            raise TimeoutError(f"no connection to {self.url} in {timeout} s: {self._error}")
        if self._error is not None:
            raise ConnectionError(str(self._error))
        self.report_view()
        return self

    def report_view(self, *, width: int = 1280, height: int = 720, fov: float = 1.0,
                    position: tuple[float, float, float] = (0.5, -0.7, 1.0),
                    look_at: tuple[float, float, float] = (0.0, 0.0, 0.6)) -> None:
        """Tell the server this page's camera and the size of its 3D view, as a browser
        does after every orbit or resize (the first report comes with :meth:`connect`)."""
        self.send({"type": "ViewerCameraMessage", "wxyz": (1.0, 0.0, 0.0, 0.0),
                   "position": position, "fov": fov, "near": 0.01, "far": 100.0,
                   "image_height": height, "image_width": width, "look_at": look_at,
                   "up_direction": (0.0, 0.0, 1.0)})

    def close(self) -> None:
        """Drop the connection abruptly (like a closed tab)."""
        if self._ws is not None and not self._closed.is_set():
            asyncio.run_coroutine_threadsafe(self._ws.close(), self._loop)
        self._closed.wait(5.0)

    def __enter__(self) -> HeadlessClient:
        return self if self._started else self.connect()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(self._main())

    async def _main(self) -> None:
        zstd = zstandard.ZstdDecompressor()
        try:
            async with websockets.asyncio.client.connect(
                self.url, subprotocols=[f"viser-v{viser.__version__}"], max_size=None,  # type: ignore[list-item]  # websockets' Subprotocol: a NewType of str
                compression=None, additional_headers=self.headers or None,
                open_timeout=self._open_timeout,
            ) as ws:
                self._ws = ws
                self._connected.set()
                async for raw in ws:
                    now = time.perf_counter()
                    assert isinstance(raw, bytes)
                    messages, _ = decode_frame(raw, zstd)
                    with self._lock:
                        self.bytes_received += len(raw)
                        self.frames_received += 1
                        answers = [a for m in messages if (a := self._absorb(m)) is not None]
                    for answer in answers:
                        await ws.send(msgspec.msgpack.encode(answer))
                    if self._on_message is not None:
                        for m in messages:
                            self._on_message(m, now)
        except (OSError, websockets.exceptions.WebSocketException) as exc:
            self._error = exc
        finally:
            self._connected.set()
            self._closed.set()

    # -- state --------------------------------------------------------------------

    def _absorb(self, m: dict[str, Any]) -> dict[str, Any] | None:
        """Take in one server message; returns the page's answer to it, if it has one."""
        kind = m.get("type", "")
        self.counts[kind] += 1
        uuid = m.get("uuid")
        if kind.startswith("Gui") and kind.endswith("Message") and isinstance(uuid, str) \
                and "props" in m and kind != "GuiUpdateMessage":
            props = m.get("props") or {}
            self.gui[uuid] = GuiElement(uuid, kind, props.get("label"), m.get("value"),
                                        dict(props))
        elif kind == "GuiUpdateMessage" and uuid in self.gui:
            el = self.gui[uuid]
            for k, v in m["updates"].items():
                if k == "value":
                    el.value = v
                else:
                    el.props[k] = v
                    if k == "label":  # a relabelled control is found by its new label
                        el.label = v
        elif kind == "GuiRemoveMessage" and uuid in self.gui:
            del self.gui[uuid]
        elif kind in ("NotificationShowMessage", "NotificationUpdateMessage"):
            props = m.get("props") or {}
            self.notifications.append((props.get("title", ""), props.get("body", "")))
        elif kind == "FileTransferStartDownload":
            self._parts[m["transfer_uuid"]] = {"name": m["filename"], "count": m["part_count"],
                                               "parts": {}}
        elif kind == "FileTransferPart" and m.get("transfer_uuid") in self._parts:
            t = self._parts[m["transfer_uuid"]]
            t["parts"][m["part_index"]] = bytes(m["content"])
            if len(t["parts"]) == t["count"]:
                self.downloads[t["name"]] = b"".join(t["parts"][i] for i in range(t["count"]))
        elif kind == "ThemeConfigurationMessage":
            self.theme = m
        elif kind in CAMERA_MESSAGES:
            field, key = CAMERA_MESSAGES[kind]
            self.camera[key] = tuple(m[field])
            self.camera_sets += 1
        elif kind == "SceneNodeUpdateMessage":
            self.scene[m["name"]].setdefault(kind, {}).update(m["updates"])
        elif "name" in m and kind.startswith("Set"):
            self.scene[m["name"]][kind] = {k: v for k, v in m.items() if k != "type"}
        elif kind == "LocalStorageSetItemMessage":
            self.local_storage[m["key"]] = m["value"]
        elif kind == "LocalStorageRemoveItemMessage":
            self.local_storage.pop(m["key"], None)
        elif kind == "LocalStorageClearMessage":
            self.local_storage.clear()
        elif kind == "LocalStorageGetItemRequestMessage":
            return {"type": "LocalStorageGetItemResponseMessage", "error": None,
                    "value": self.local_storage.get(m["key"]),
                    "request_uuid": m["request_uuid"]}
        return None

    # -- queries and actions ------------------------------------------------------------

    def find(self, label: str, kind: str | None = None) -> GuiElement:
        """The GUI element labelled ``label`` (and of message type ``kind``, if given);
        KeyError when the page has none (yet: wait with :meth:`shows`)."""
        with self._lock:
            for el in self.gui.values():
                if el.label == label and (kind is None or el.kind == kind):
                    return el
        raise KeyError(f"no GUI element labelled {label!r}")

    def shows(self, label: str, kind: str | None = None) -> bool:
        """Whether the page has a GUI element labelled ``label`` (of type ``kind``)."""
        with self._lock:
            return any(el.label == label and (kind is None or el.kind == kind)
                       for el in self.gui.values())

    def send(self, message: dict[str, Any]) -> None:
        """Send one client->server message (a dict with its ``type``)."""
        if self._ws is None:
            raise ConnectionError("not connected")
        data = msgspec.msgpack.encode(message)
        asyncio.run_coroutine_threadsafe(self._ws.send(data), self._loop).result(5.0)

    def _uuid(self, target: str | Any, kind: str | None = None) -> str:
        """The uuid of a GUI element given by its label (waited for up to
        :data:`ACTION_WAIT_S`, as a person waits for a control to appear) or by the
        server's handle of it."""
        if isinstance(target, str):
            # a panel's fields may arrive one by one
            self.wait_for(lambda: self.shows(target, kind), ACTION_WAIT_S,
                          f"a GUI element labelled {target!r}")
            return self.find(target, kind).uuid
        return uuid_of(target)  # a viser GUI handle (a test holding the server side)

    def set_value(self, target: str | Any, value: Any) -> None:
        """Type ``value`` into the input labelled ``target`` (or whose server handle it is),
        as the page would send it."""
        self.send({"type": "GuiUpdateMessage", "uuid": self._uuid(target),
                   "updates": {"value": value}})

    def click(self, target: str | Any) -> None:
        """Click the button labelled ``target`` (or whose server handle it is)."""
        self.send({"type": "GuiUpdateMessage", "uuid": self._uuid(target, "GuiButtonMessage"),
                   "updates": {"value": True}})

    def upload(self, target: str | Any, name: str, content: bytes, *,
               part_bytes: int = 512 * 1024, declared: int | None = None,
               only: Sequence[int] | None = None) -> str:
        """Upload ``content`` as file ``name`` through the upload button labelled ``target``
        (or whose server handle it is), in parts of ``part_bytes`` as the page sends them;
        ``declared`` claims another size than the content's, ``only`` sends those part
        indices alone, in that order (a hostile page, or one that leaves mid-upload).
        Returns the transfer's id."""
        uuid = self._uuid(target, "GuiUploadButtonMessage")
        transfer = uuid4().hex
        parts = [content[i:i + part_bytes] for i in range(0, len(content), part_bytes)]
        self.send({"type": "FileTransferStartUpload", "source_component_uuid": uuid,
                   "transfer_uuid": transfer, "filename": name,
                   "mime_type": "application/zip", "part_count": len(parts),
                   "size_bytes": len(content) if declared is None else declared})
        for i in range(len(parts)) if only is None else only:
            self.send({"type": "FileTransferPart", "source_component_uuid": uuid,
                       "transfer_uuid": transfer, "part_index": i,
                       "content": parts[i % len(parts)]})
        return transfer

    def drag(self, name: str, phase: str, *, start: tuple[float, float, float],
             end: tuple[float, float, float]) -> None:
        """Send one drag event on scene node ``name`` (world coordinates)."""
        self.send({"type": "SceneNodeDragMessage", "phase": phase, "name": name,
                   "instance_index": None, "start_position": tuple(map(float, start)),
                   "start_screen_pos": (0.5, 0.5), "end_position": tuple(map(float, end)),
                   "end_screen_pos": (0.5, 0.5), "button": "left", "modifier": None})

    def move_gizmo(self, name: str, positions: list[tuple[float, float, float]]) -> None:
        """Drag the transform-controls gizmo ``name`` through ``positions`` (its parent
        frame, m): drag start, one update per position, drag end."""
        self.send({"type": "TransformControlsDragStartMessage", "name": name, "owner": ""})
        for p in positions:
            self.send({"type": "TransformControlsUpdateMessage", "name": name,
                       "wxyz": (1.0, 0.0, 0.0, 0.0), "position": tuple(map(float, p)),
                       "owner": ""})
        self.send({"type": "TransformControlsDragEndMessage", "name": name, "owner": ""})

    def wait_notification(self, title: str, timeout: float = 30.0) -> str:
        """Body of the first notification titled ``title`` (waits for it; TimeoutError
        listing the notifications seen otherwise)."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                for t, body in self.notifications:
                    if t == title:
                        return body
                if time.monotonic() > deadline:
                    raise TimeoutError(f"no notification {title!r} in {timeout} s; got "
                                       f"{self.notifications}")
            time.sleep(0.02)

    def wait_for(self, predicate: Callable[[], bool], timeout: float = 60.0,
                 what: str = "condition") -> None:
        """Poll ``predicate`` until true (TimeoutError naming ``what`` otherwise). A
        :meth:`find` of an element the page does not have yet (KeyError) counts as not yet
        true: on a busy machine the page's controls may arrive after the first poll."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                try:
                    ok = predicate()
                except KeyError:
                    ok = False
            if ok:
                return
            time.sleep(0.02)
        raise TimeoutError(f"timed out after {timeout} s waiting for {what}")
