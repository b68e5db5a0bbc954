"""How far the control loop fell behind lately, for the status line."""

from __future__ import annotations

from collections import deque

#: s: the window the status line counts late periods over.
LATE_WINDOW = 10.0


class LateWindow:
    """Counts the loop's late periods (``LoopStatus.overruns``) over the last ``window`` s.

    Feed it each status snapshot with :meth:`add`; :meth:`text` is the status-line
    note ("late: N periods skipped in the last 10 s"), empty when none were.
    """

    def __init__(self, window: float = LATE_WINDOW) -> None:
        self.window = float(window)
        self._seen: deque[tuple[float, int]] = deque()

    def add(self, now: float, overruns: int) -> int:
        """Note the loop's total ``overruns`` at wall time ``now``; returns the count in window."""
        self._seen.append((now, int(overruns)))
        while len(self._seen) > 1 and self._seen[1][0] <= now - self.window:
            self._seen.popleft()
        return self.late

    @property
    def late(self) -> int:
        """Late periods within the window (0 before two snapshots)."""
        if len(self._seen) < 2:
            return 0
        return max(0, self._seen[-1][1] - self._seen[0][1])

    def text(self) -> str:
        n = self.late
        return f"late: {n} periods skipped in the last {self.window:.0f} s" if n else ""
