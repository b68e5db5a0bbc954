"""Reads of many servos in one request through a bus (protocol 2.0's and Feetech's
SYNC_READ, protocol 2.0's BULK_READ): each servo answers in turn, after the one before it;
the ones whose answer was lost are asked again, up to the bus's retries.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from armlab.hardware.servos.family import ServoFamily, Status
from armlab.hardware.wire.errors import NoReply
from armlab.hardware.wire.port import reply_timeout

if TYPE_CHECKING:
    from armlab.hardware.servos.family import Codec
    from armlab.hardware.wire.bus import BusStats


class GroupReads:
    """A bus's group reads (mixed into :class:`~armlab.hardware.wire.bus.Bus`, whose
    port and receiver it uses)."""

    if TYPE_CHECKING:  # the bus's, for mypy only
        family: ServoFamily
        retries: int
        timeout_margin: float
        stats: BusStats
        return_delay: dict[int, int]
        _p: Codec
        _lock: threading.Lock
        _baud: float

        def status_length(self, data_bytes: int = 0) -> int: ...
        def _send(self, packet: bytes) -> float: ...
        def _receive(self, request: bytes, want: dict[int, int], *, timeout: float
                     ) -> dict[int, Status]: ...
        def _no_reply(self, ids: list[int], tries: int, what: str = "", *,
                      heard: int = 0) -> NoReply: ...

    def sync_read(self, address: int, length: int, ids: list[int] | tuple[int, ...]
                  ) -> dict[int, bytes]:
        """SYNC_READ (protocol 2.0, STS): ``length`` bytes at ``address`` from each of
        ``ids`` in one request; each servo answers in turn, after the one before it.

        Servos whose answer was lost are asked again (a SYNC_READ of those alone), up to
        the bus's retries; :class:`NoReply` names the ones that never answered.

        Returns:
            servo ID -> its bytes, in the order of ``ids``.
        """
        ids = list(ids)
        if not self.family.group_read:
            raise ValueError(f"SYNC_READ is a protocol 2.0 and STS instruction, not "
                             f"{self.family.title}'s: read each servo")
        codec = self._p
        return self._read_many(codec.sync_read(address, length, ids), {i: length for i in ids},
                               lambda missing: codec.sync_read(address, length, missing))

    def bulk_read(self, requests: list[tuple[int, int, int]]) -> dict[int, bytes]:
        """BULK_READ (protocol 2.0's): ``(servo ID, address, length)`` for each servo, each
        its own item, in one request; retries and errors as :meth:`sync_read`."""
        bulk = self.family.bulk_read_packet
        if bulk is None:
            raise ValueError(f"BULK_READ is a protocol 2.0 instruction, not "
                             f"{self.family.title}'s: open the bus with protocol=2")
        by_id = {servo_id: (address, length) for servo_id, address, length in requests}
        return self._read_many(bulk(requests), {i: n for i, (_, n) in by_id.items()},
                               lambda missing: bulk([(i, *by_id[i]) for i in missing]))

    def _read_many(self, packet: bytes, want: dict[int, int],
                   again: Callable[[list[int]], bytes]) -> dict[int, bytes]:
        """Send a SYNC_READ or BULK_READ ``packet`` and gather its answers (``want``: ID ->
        data bytes); ``again(missing IDs)`` is the packet that asks those once more."""
        got: dict[int, bytes] = {}
        tries = self.retries + 1
        with self._lock:
            for attempt in range(tries):
                missing = [i for i in want if i not in got]
                if attempt:
                    self.stats.retries += 1
                    packet = again(missing)
                backlog = self._send(packet)
                # every servo waits for the answer before its own, then its return delay
                replies = sum(self.status_length(want[i]) for i in missing)
                delays = sum(self.return_delay.get(i, 254) for i in missing)
                timeout = backlog + reply_timeout(len(packet), replies, self._baud, delays,
                                                  self.timeout_margin)
                answers = self._receive(packet, {i: want[i] for i in missing}, timeout=timeout)
                got.update({i: st.params for i, st in answers.items()})
                if len(got) == len(want):
                    return {i: got[i] for i in want}
            self.stats.failures += 1
        raise self._no_reply([i for i in want if i not in got], tries, " to a group read")
