"""A size limit on the files pages upload (the lab's **Open run**).

viser keeps an upload's parts in memory as they arrive, up to the size and the number of
parts the page declares, with no limit of its own (its websocket takes messages of up to
50 MiB, and a page splits a file into parts of 512 KiB). :func:`limit_uploads` puts a
screen in front of a GUI's two upload handlers: an upload declared larger than the limit
is refused before a byte of it is kept, and one whose parts add up to more than it
declared (or that another page sends parts into) is dropped at the part that overflows.

relies on: ``GuiApi._websock_interface`` (``register_handler``, ``unregister_handler``),
``GuiApi._handle_file_transfer_start``, ``GuiApi._handle_file_transfer_part``,
``GuiApi._current_file_upload_states`` (transfer uuid -> {"client_id", "total_bytes",
"transferred_bytes", ...}), ``viser._messages.FileTransferStartUpload``, ``FileTransferPart`` and
``FileTransferPartAck``; seen in viser 1.1.1
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import viser
from viser import _messages

from armlab.app.viser_ext import HooksMissing
from armlab.app.viser_ext.probe import assigned_in

FileTransferStartUpload: Any = getattr(_messages, "FileTransferStartUpload", None)
FileTransferPart: Any = getattr(_messages, "FileTransferPart", None)
FileTransferPartAck: Any = getattr(_messages, "FileTransferPartAck", None)
#: where a GUI keeps its limit (one per GUI: a lesson opened again changes it in place)
_ATTR = "_armlab_upload_limit"

#: ``on_refused(client_id, file name, why)``
Refused = Callable[[Any, str, str], None]


def missing() -> list[str]:
    """What of the above this viser lacks."""
    from viser import _gui_api

    out = [f"viser._messages.{name}" for name, cls in
           (("FileTransferStartUpload", FileTransferStartUpload),
            ("FileTransferPart", FileTransferPart),
            ("FileTransferPartAck", FileTransferPartAck)) if cls is None]
    for name in ("_handle_file_transfer_start", "_handle_file_transfer_part",
                 "_current_file_upload_states", "_websock_interface"):
        if not assigned_in(_gui_api.GuiApi, name):
            out.append(f"GuiApi.{name}")
    return out


class UploadLimit:
    """The screen of one GUI's uploads (see the module docstring).

    Attributes:
        max_bytes: the largest file taken.
        on_refused: told of each refused upload.
        refused: uploads refused so far.
    """

    def __init__(self, gui: viser.GuiApi, *, max_bytes: int, on_refused: Refused) -> None:
        self.max_bytes = int(max_bytes)
        self.on_refused = on_refused
        self.refused = 0
        self._states: dict[str, dict[str, Any]] = gui._current_file_upload_states  # type: ignore[attr-defined]
        iface = self._iface = gui._websock_interface  # type: ignore[attr-defined]
        self._start = gui._handle_file_transfer_start  # type: ignore[attr-defined]
        self._part = gui._handle_file_transfer_part  # type: ignore[attr-defined]
        iface.unregister_handler(FileTransferStartUpload, self._start)
        iface.unregister_handler(FileTransferPart, self._part)
        iface.register_handler(FileTransferStartUpload, self._screen_start)
        iface.register_handler(FileTransferPart, self._screen_part)

    def _refuse(self, client_id: Any, name: Any, why: str) -> None:
        self.refused += 1
        self.on_refused(client_id, str(name)[:80], why)

    def _screen_start(self, client_id: Any, message: Any) -> None:
        size, parts = message.size_bytes, message.part_count
        if not isinstance(size, int) or not isinstance(parts, int) or size < 0 \
                or parts < 0 or parts > size:
            self._refuse(client_id, message.filename, "the page declared no usable size")
            return
        if size > self.max_bytes:
            # the page's progress bar ends (as viser acknowledges a last part); its parts
            # then find no transfer and are dropped unread
            self._iface.queue_message(FileTransferPartAck(
                source_component_uuid=message.source_component_uuid,
                transfer_uuid=message.transfer_uuid, transferred_bytes=size, total_bytes=size))
            self._refuse(client_id, message.filename,
                         f"{size / 2**20:.1f} MiB is more than the "
                         f"{self.max_bytes / 2**20:.0f} MiB a file may have here")
            return
        self._start(client_id, message)

    def _screen_part(self, client_id: Any, message: Any) -> None:
        state = self._states.get(message.transfer_uuid)
        if state is not None:
            content = message.content
            size = len(content) if isinstance(content, bytes | bytearray) else -1
            if state.get("client_id") != client_id:
                return  # another page's transfer: not this page's to fill
            if size < 0 or state["transferred_bytes"] + size > state["total_bytes"]:
                self._states.pop(message.transfer_uuid, None)
                self._refuse(client_id, state.get("filename", ""),
                             "its parts add up to more than the page declared")
                return
        self._part(client_id, message)


def limit_uploads(gui: viser.GuiApi, *, max_bytes: int, on_refused: Refused) -> UploadLimit:
    """Screen ``gui``'s uploads (a server's ``gui`` or a page's own): files larger than
    ``max_bytes`` are refused, ``on_refused`` told. Called again for the same GUI, the
    limit and the callback of its screen are replaced.

    Raises:
        HooksMissing: this viser lacks what the screen needs (:func:`missing`).
    """
    absent = missing()
    if absent:
        raise HooksMissing("upload size limit: " + "; ".join(absent))
    limit = getattr(gui, _ATTR, None)
    if isinstance(limit, UploadLimit):
        limit.max_bytes, limit.on_refused = int(max_bytes), on_refused
        return limit
    limit = UploadLimit(gui, max_bytes=max_bytes, on_refused=on_refused)
    setattr(gui, _ATTR, limit)
    return limit
