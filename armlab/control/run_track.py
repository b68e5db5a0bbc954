"""One run's record, kept whole while the recorder's window moves on (docs/runs.md).

A :class:`RunTrack` begins when a run's first command is posted: it takes the
recorder's last :data:`LEAD_S` s (the pose the run started from) and from then on
follows the recorder by its count of rows ever written (:meth:`Recorder.since
<armlab.control.recorder.Recorder.since>`), copying only the rows new since the last
:meth:`RunTrack.pull` into chunks of its own. Nothing is copied per save but the run
itself. Once the lesson says the run is over (:meth:`RunTrack.finish`, when it
measures it) a settling tail of :data:`TAIL_S` s is kept, then no more.

The bound: a run keeps at most :data:`MAX_RUN_S` s and :data:`MAX_RUN_ROWS` rows
(lead and tail included), whichever comes first: 120 s at the thesis's 16 ms (7 500
rows, 1.9 MB for three joints), 30 s at 1 ms (the longest run the lab saved before,
whose file's reading cost docs/runs.md states). A run past it is cut there and says so.
A pull must come within the recorder's window (30 s) of the rows it copies; rows the
recorder dropped before a pull are counted in :attr:`RunTrack.lost`.

What a track follows is a :class:`RowSource`: a servo arm's
:class:`~armlab.control.recorder.Recorder`, or the record of a loop of its own
(:class:`armlab.control.loop_record.LoopRecord`: the hand's 1 ms grip loop, whose
bound is then 30 s, and the quadruped's gait loop, 120 s at 20 ms).
"""

from __future__ import annotations

import math
import threading
from typing import Protocol

import numpy as np

#: s of record kept before the run's first command (the pose it started from).
LEAD_S = 0.5
#: s of record kept after the run is over (the arm settling).
TAIL_S = 2.0
#: The longest run kept, s of loop time, and the most rows (lead and tail included).
MAX_RUN_S = 120.0
MAX_RUN_ROWS = 30_000

__all__ = ["LEAD_S", "MAX_RUN_ROWS", "MAX_RUN_S", "TAIL_S", "RowSource", "RunTrack"]


class RowSource(Protocol):
    """A record of fixed-width rows, column 0 the loop time in s, that one loop writes
    and a track reads (:class:`~armlab.control.recorder.Recorder`,
    :class:`~armlab.control.loop_record.LoopRecord`)."""

    @property
    def width(self) -> int:
        """Floats in a row."""
        ...

    def recent(self, rows: int) -> tuple[np.ndarray, int]:
        """The newest ``rows`` rows (a copy, oldest first) and the count ever written."""
        ...

    def since(self, written: int) -> tuple[np.ndarray, int]:
        """The rows written after the first ``written`` (those still kept) and the count."""
        ...

    def unpack(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Rows (m, width) as the record's snapshot gives them: {"t": (m,), name: ...}."""
        ...


class RunTrack:
    """The rows of one run, followed from ``recorder`` since loop time ``t0``.

    Args:
        recorder: the loop's record (one writer, the loop; this reads it): a
            :class:`RowSource`.
        t0: loop time the run's first command was posted, s.
        period: the loop's period, s, or less (how many rows the lead may be: the lead is
            then cut to :data:`LEAD_S` by time).
        max_s, max_rows: the bound (defaults :data:`MAX_RUN_S`, :data:`MAX_RUN_ROWS`).

    Attributes:
        t0: as given. finished_at: loop time the lesson said the run was over (None: it
        goes on). cut: the run reached its bound and was cut there. lost: rows the
        recorder dropped before they were pulled (0 for a run pulled in time).
    """

    def __init__(self, recorder: RowSource, *, t0: float, period: float,
                 max_s: float = MAX_RUN_S, max_rows: int = MAX_RUN_ROWS) -> None:
        self.recorder = recorder
        self.t0 = float(t0)
        self.max_s = float(max_s)
        self.max_rows = int(max_rows)
        self.finished_at: float | None = None
        self.cut = False
        self.lost = 0
        self._lock = threading.Lock()
        lead, self._written = recorder.recent(math.ceil(LEAD_S / max(period, 1e-6)) + 1)
        lead = lead[lead[:, 0] >= self.t0 - LEAD_S - 1e-9] if len(lead) else lead
        self._chunks: list[np.ndarray] = [lead] if len(lead) else []
        self._rows = len(lead)
        self._last_t = float(lead[-1, 0]) if len(lead) else -math.inf
        self._closed = False

    @property
    def closed(self) -> bool:
        """No more rows will be kept (the tail is in, or the run was cut)."""
        return self._closed

    @property
    def finished(self) -> bool:
        """The lesson said the run is over (or it was cut at its bound)."""
        return self.finished_at is not None or self.cut

    @property
    def rows(self) -> int:
        """Rows kept so far."""
        return self._rows

    def finish(self, t: float) -> None:
        """The run is over at loop time ``t`` s: keep :data:`TAIL_S` s more, then stop."""
        self.pull()
        with self._lock:
            if self.finished_at is None:
                self.finished_at = float(t)

    def pull(self) -> None:
        """Copy the rows the recorder gained since the last pull (only those)."""
        if self._closed:
            return
        rows, written = self.recorder.since(self._written)
        with self._lock:
            if self._closed:
                return
            self.lost += max(0, written - self._written - len(rows))
            self._written = written
            if not len(rows):
                return
            rows = rows[rows[:, 0] > self._last_t]  # a recorder cleared meanwhile: only newer
            bound = self.t0 + self.max_s
            tail_end = None if self.finished_at is None else self.finished_at + TAIL_S
            end = bound if tail_end is None else min(bound, tail_end)
            within = rows[rows[:, 0] <= end + 1e-9]
            keep = within[: self.max_rows - self._rows]
            if len(keep) < len(within) or (len(within) < len(rows)
                                           and (tail_end is None or tail_end > bound)):
                self._closed = self.cut = True  # at the bound before the run was over
            elif len(within) < len(rows):
                self._closed = True  # the tail is in
            if len(keep):
                self._chunks.append(keep)
                self._rows += len(keep)
                self._last_t = float(keep[-1, 0])

    def span(self) -> tuple[float, float] | None:
        """(first, last) loop time kept, s (None: no row yet)."""
        with self._lock:
            if not self._chunks:
                return None
            return float(self._chunks[0][0, 0]), self._last_t

    def snapshot(self) -> dict[str, np.ndarray]:
        """What is kept, pulled up to now, in :meth:`Recorder.snapshot`'s layout (one copy
        of the run, made here)."""
        self.pull()
        with self._lock:
            chunks = list(self._chunks)
        data = (np.concatenate(chunks) if chunks
                else np.empty((0, self.recorder.width)))
        return self.recorder.unpack(data)
