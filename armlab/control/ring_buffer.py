""":class:`RingBuffer` keeps the newest rows of a fixed width, column 0 the time in s: one
writer appends in place (no allocation per period), any thread takes a copy of the last
seconds (found by bisection on time), thinned if asked; a mirror in another process
follows it by the count of rows ever written.

(``armlab.control.recorder.Recorder`` is a RingBuffer with a named column per signal.)
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

import numpy as np


class RingBuffer:
    """The newest ``capacity`` rows of ``width`` floats; column 0 is time, s (increasing).

    Args:
        width: floats per row.
        capacity: rows kept (>= 2); e.g. ``rows_for(seconds, period)``.
    """

    def __init__(self, width: int, capacity: int) -> None:
        if capacity < 2:
            raise ValueError(f"capacity must be >= 2 rows, got {capacity}")
        self.width = int(width)
        self._lock = threading.Lock()
        self._data = np.full((capacity, self.width), np.nan)
        self._head = 0  # next row to write
        self._count = 0  # rows kept (<= capacity)
        self._written = 0  # rows ever written (a mirror's bookmark; :meth:`since`)

    @staticmethod
    def rows_for(seconds: float, period: float) -> int:
        """Rows that hold ``seconds`` of one row per ``period``."""
        return max(2, math.ceil(seconds / period))

    @property
    def capacity(self) -> int:
        return self._data.shape[0]

    def __len__(self) -> int:
        return self._count

    def append(self, row: np.ndarray | Sequence[float]) -> None:
        """Write ``row`` (width,) over the oldest one."""
        with self._lock:
            self._data[self._head] = row
            self._head = (self._head + 1) % self.capacity
            self._count = min(self._count + 1, self.capacity)
            self._written += 1

    def extend(self, rows: np.ndarray) -> None:
        """Write ``rows`` (m, width), oldest first, over the oldest ones (a mirror taking
        what :meth:`since` gave)."""
        rows = np.asarray(rows, dtype=float).reshape(-1, self.width)[-self.capacity:]
        with self._lock:
            for row in rows:
                self._data[self._head] = row
                self._head = (self._head + 1) % self.capacity
            self._count = min(self._count + len(rows), self.capacity)
            self._written += len(rows)

    def since(self, written: int) -> tuple[np.ndarray, int]:
        """The rows written after the first ``written`` ever written (those still kept),
        oldest first, as a copy, and the number written now (the next call's
        ``written``): a mirror follows the buffer by what it was last given."""
        with self._lock:
            return self._last(max(0, min(self._written - written, self._count))), self._written

    def recent(self, rows: int) -> tuple[np.ndarray, int]:
        """The newest ``rows`` rows kept, oldest first (a copy), and the number ever written,
        read together: where a follower of the buffer (:meth:`since`) starts, with a lead."""
        with self._lock:
            return self._last(max(0, min(int(rows), self._count))), self._written

    def clear(self) -> None:
        with self._lock:
            self._head = self._count = 0

    def resize(self, capacity: int) -> None:
        """Change the number of rows kept, keeping the newest ones."""
        if capacity < 2:
            raise ValueError(f"capacity must be >= 2 rows, got {capacity}")
        with self._lock:
            keep = self._ordered()[-capacity:]
            self._data = np.full((capacity, self.width), np.nan)
            self._data[: len(keep)] = keep
            self._count = len(keep)
            self._head = len(keep) % capacity

    def rows(self, window_s: float | None = None, *, max_points: int | None = None
             ) -> np.ndarray:
        """(m, width) copy, oldest first: the last ``window_s`` s (None: all kept), thinned
        evenly to about ``max_points`` rows (the newest kept) when given."""
        with self._lock:
            if window_s is None or self._count == 0:
                data = self._ordered()
            else:
                newest = self._data[(self._head - 1) % self.capacity, 0]
                lo, hi = 1, self._count  # rows newer than newest - window_s: bisect on time
                while lo < hi:
                    mid = (lo + hi + 1) // 2
                    if self._data[(self._head - mid) % self.capacity, 0] >= newest - window_s:
                        lo = mid
                    else:
                        hi = mid - 1
                data = self._last(lo)
        if max_points is not None and len(data) > max_points > 0:
            step = math.ceil(len(data) / max_points)
            data = data[(len(data) - 1) % step:: step]
        return data

    def _ordered(self) -> np.ndarray:
        """Rows oldest first (caller holds the lock); a copy."""
        if self._count < self.capacity:
            return self._data[: self._count].copy()
        return np.concatenate([self._data[self._head:], self._data[: self._head]])

    def _last(self, rows: int) -> np.ndarray:
        """The newest ``rows`` rows, oldest first (caller holds the lock); a copy."""
        rows = min(rows, self._count)
        start = self._head - rows
        if start >= 0:
            return self._data[start: self._head].copy()
        return np.concatenate([self._data[start:], self._data[: self._head]])
