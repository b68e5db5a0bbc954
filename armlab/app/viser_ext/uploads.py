"""Limits on the files pages upload (the lab's **Open run**).

viser keeps an upload's parts in memory as they arrive, up to the size and the number of
parts the page declares, with no limit of its own (its websocket takes messages of up to
50 MiB, and a page splits a file into parts of 512 KiB). :func:`limit_uploads` puts a
screen in front of a GUI's two upload handlers:

- an upload declared larger than the limit is refused before a byte of it is kept;
- a page may have at most :data:`MAX_PAGE_UPLOADS` unfinished uploads declaring at most
  :data:`MAX_PAGE_UPLOAD_BYTES` together, and all pages' unfinished uploads (every
  screened GUI of the process) at most :data:`MAX_TOTAL_UPLOAD_BYTES`: an upload past
  either is refused before a byte of it is kept (what is kept of an upload never exceeds
  what it declared, so these bound the memory uploads hold);
- a page's unfinished uploads are dropped when it leaves (viser drops them too, where it
  does; here, at the next upload of any page, those of pages no longer connected);
- an upload whose parts add up to more or less than it declared, whose part is out of
  range or repeated, or that another page sends parts into, is dropped at that part.

Every upload refused or dropped is told, once, to the page that sent it (``on_refused``);
an error in the screen itself is told the same way, never left silent.

relies on: ``GuiApi._websock_interface`` (``register_handler``, ``unregister_handler``),
``GuiApi._handle_file_transfer_start``, ``GuiApi._handle_file_transfer_part``,
``GuiApi._current_file_upload_states`` (transfer uuid -> {"client_id", "filename",
"part_count", "parts" (index -> bytes), "total_bytes", "transferred_bytes", ...}),
``viser._messages.FileTransferStartUpload``, ``FileTransferPart`` and
``FileTransferPartAck``; seen in viser 1.1.1
"""

from __future__ import annotations

import logging
import threading
import weakref
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
#: () -> the ids of the pages connected now
Connected = Callable[[], set[Any]]

#: The most unfinished uploads one page may have at once, and the most bytes they may
#: declare together (a whole run file of 64 MiB and a small one).
MAX_PAGE_UPLOADS = 2
MAX_PAGE_UPLOAD_BYTES = 80 * 2**20
#: The most bytes all pages' unfinished uploads may declare together (four run files of
#: 64 MiB at once), over every GUI screened in this process.
MAX_TOTAL_UPLOAD_BYTES = 256 * 2**20

log = logging.getLogger(__name__)
#: Every screen alive (the lab's GUI and each private page's): the total spans them all.
_SCREENS: weakref.WeakSet[UploadLimit] = weakref.WeakSet()
_BUDGET_LOCK = threading.Lock()


def unfinished(client_id: Any = None) -> tuple[int, int]:
    """(uploads, bytes declared) unfinished in every screened GUI: of page ``client_id``,
    or of all pages when None."""
    count = total = 0
    for screen in list(_SCREENS):
        for state in list(screen._states.values()):
            if client_id is None or state.get("client_id") == client_id:
                count += 1
                total += int(state.get("total_bytes", 0) or 0)
    return count, total


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
        connected: () -> the pages connected now (None: only viser drops a page's
            unfinished uploads when it leaves).
        refused: uploads refused so far.
    """

    def __init__(self, gui: viser.GuiApi, *, max_bytes: int, on_refused: Refused,
                 connected: Connected | None = None) -> None:
        self.max_bytes = int(max_bytes)
        self.on_refused = on_refused
        self.connected = connected
        self.refused = 0
        # viser's own upload states by transfer id (popped with a message's, maybe None)
        self._states: dict[Any, Any] = gui._current_file_upload_states
        iface = self._iface = gui._websock_interface
        self._start = gui._handle_file_transfer_start
        self._part = gui._handle_file_transfer_part
        iface.unregister_handler(FileTransferStartUpload, self._start)
        iface.unregister_handler(FileTransferPart, self._part)
        iface.register_handler(FileTransferStartUpload, self._screen_start)
        iface.register_handler(FileTransferPart, self._screen_part)
        _SCREENS.add(self)

    def _refuse(self, client_id: Any, name: Any, why: str) -> None:
        self.refused += 1
        try:
            self.on_refused(client_id, str(name)[:80], why)
        except Exception:  # noqa: BLE001 - the page has gone; the lab goes on
            log.exception("telling page %s of a refused upload failed", client_id)

    def _end_progress(self, message: Any, size: int) -> None:
        """End the page's progress bar (as viser acknowledges a last part); the upload's
        further parts then find no transfer and are dropped unread."""
        self._iface.queue_message(FileTransferPartAck(
            source_component_uuid=message.source_component_uuid,
            transfer_uuid=message.transfer_uuid, transferred_bytes=size, total_bytes=size))

    def drop_client(self, client_id: Any) -> int:
        """Drop page ``client_id``'s unfinished uploads (it left); returns how many."""
        gone = [k for k, st in list(self._states.items()) if st.get("client_id") == client_id]
        for key in gone:
            self._states.pop(key, None)
        return len(gone)

    def _drop_departed(self) -> None:
        """Drop the unfinished uploads of pages no longer connected, in every screen that
        knows its pages."""
        for screen in list(_SCREENS):
            if screen.connected is None:
                continue
            here = screen.connected()
            for key, state in list(screen._states.items()):
                if state.get("client_id") not in here:
                    screen._states.pop(key, None)

    def _screen_start(self, client_id: Any, message: Any) -> None:
        try:
            self._check_start(client_id, message)
        except Exception as exc:  # noqa: BLE001 - never silent: the page is told
            log.exception("screening an upload failed")
            self._states.pop(getattr(message, "transfer_uuid", None), None)
            self._refuse(client_id, getattr(message, "filename", ""),
                         f"the lab could not take it ({type(exc).__name__})")

    def _check_start(self, client_id: Any, message: Any) -> None:
        size, parts = message.size_bytes, message.part_count
        if not isinstance(size, int) or not isinstance(parts, int) or size < 0 \
                or parts < 0 or parts > size:
            self._refuse(client_id, message.filename, "the page declared no usable size")
            return
        if size > self.max_bytes:
            self._end_progress(message, size)
            self._refuse(client_id, message.filename,
                         f"{size / 2**20:.1f} MiB is more than the "
                         f"{self.max_bytes / 2**20:.0f} MiB a file may have here")
            return
        with _BUDGET_LOCK:
            self._drop_departed()
            page_count, page_bytes = unfinished(client_id)
            _, all_bytes = unfinished()
            why = None
            if page_count >= MAX_PAGE_UPLOADS or page_bytes + size > MAX_PAGE_UPLOAD_BYTES:
                why = (f"this page is still sending {page_count} file(s) "
                       f"({page_bytes / 2**20:.0f} MiB; a page may send {MAX_PAGE_UPLOADS} "
                       f"at once, {MAX_PAGE_UPLOAD_BYTES // 2**20} MiB in all): wait for "
                       "them to arrive")
            elif all_bytes + size > MAX_TOTAL_UPLOAD_BYTES:
                why = (f"the lab is receiving {all_bytes / 2**20:.0f} MiB of files from its "
                       f"pages (at most {MAX_TOTAL_UPLOAD_BYTES // 2**20} MiB at once): "
                       "try again in a moment")
            if why is None:
                self._start(client_id, message)
        if why is not None:
            self._end_progress(message, size)
            self._refuse(client_id, message.filename, why)
        elif parts > 0 and message.transfer_uuid not in self._states:
            self._end_progress(message, size)
            self._refuse(client_id, message.filename, "the button it was sent to is gone "
                         "(the lesson changed): open it again")

    def _screen_part(self, client_id: Any, message: Any) -> None:
        try:
            if self._check_part(client_id, message):
                self._part(client_id, message)
        except Exception as exc:  # noqa: BLE001 - never silent: the page is told
            log.exception("screening an upload's part failed")
            state = self._states.pop(getattr(message, "transfer_uuid", None), None) or {}
            self._refuse(client_id, state.get("filename", ""),
                         f"the lab could not take it ({type(exc).__name__})")

    def _check_part(self, client_id: Any, message: Any) -> bool:
        """Whether the part goes on to viser; a part that breaks its upload drops it (the
        page told)."""
        state = self._states.get(message.transfer_uuid)
        if state is None:
            return True  # no such transfer (refused, or done): viser drops it unread
        content = message.content
        size = len(content) if isinstance(content, bytes | bytearray) else -1
        name = state.get("filename", "")
        if state.get("client_id") != client_id:
            self._refuse(client_id, name, "its part was sent into another page's upload")
            return False
        index, count = message.part_index, state["part_count"]
        why = None
        if size < 0 or state["transferred_bytes"] + size > state["total_bytes"]:
            why = "its parts add up to more than the page declared"
        elif not isinstance(index, int) or not 0 <= index < count or index in state["parts"]:
            why = f"its part {index!r} is out of order (of {count}) or sent twice"
        elif (len(state["parts"]) == count - 1
              and state["transferred_bytes"] + size != state["total_bytes"]):
            why = "its parts add up to less than the page declared"
        if why is None:
            return True
        self._states.pop(message.transfer_uuid, None)
        self._refuse(client_id, name, why)
        return False


def limit_uploads(gui: viser.GuiApi, *, max_bytes: int, on_refused: Refused,
                  connected: Connected | None = None) -> UploadLimit:
    """Screen ``gui``'s uploads (a server's ``gui`` or a page's own): files larger than
    ``max_bytes``, or past a page's or the lab's unfinished uploads, are refused,
    ``on_refused`` told; ``connected`` () -> the pages connected now, whose departed
    pages' unfinished uploads are dropped. Called again for the same GUI, the limit and
    the callbacks of its screen are replaced.

    Raises:
        HooksMissing: this viser lacks what the screen needs (:func:`missing`).
    """
    absent = missing()
    if absent:
        raise HooksMissing("upload size limit: " + "; ".join(absent))
    limit = getattr(gui, _ATTR, None)
    if isinstance(limit, UploadLimit):
        limit.max_bytes, limit.on_refused = int(max_bytes), on_refused
        limit.connected = connected
        return limit
    limit = UploadLimit(gui, max_bytes=max_bytes, on_refused=on_refused, connected=connected)
    setattr(gui, _ATTR, limit)
    return limit
