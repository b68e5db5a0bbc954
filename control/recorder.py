"""Fixed-size ring buffers of every signal the lab plots, written by the loop, read by the UI.

One writer (the control loop) appends a row per period; readers (the UI at
30 Hz, a CSV export) take a :meth:`Recorder.snapshot`, a copy made under a lock
that is held only for one array copy, so neither side waits on the other.

Signals (SI, joint order of the model), each (m,) for ``t`` and (m, n) otherwise:

=========  ==================================================================
t          loop time, s (periods × period)
wall       wall-clock time of the row, s since the epoch (CSV wall_time_s)
q_cmd      θ_cmd, the commanded trajectory (RMRC), rad
q_ref      θ_ref, the goal sent to the servos (after clamping), rad
q          θ, the position the servos report, rad
error      θ_cmd − θ, rad
qd_ref     θ̇_ref, the signed speed behind the moving-speed goal, rad/s
load       τ_dist, the servo's Present Load, N·m
tau_load   LPF(τ_dist), N·m
tau_dyn    τ_dyn, Newton–Euler torque of the measured motion, N·m
tau_ext    τ_ext = LPF(τ_dist) − τ_dyn (eq. 2.23), N·m
q_env      θ_env, the environment state of eq. 2.7, rad
=========  ==================================================================
"""

from __future__ import annotations

import io
import math
import threading
import time
from collections.abc import Mapping, Sequence

import numpy as np

from control.params import Params

SIGNALS: tuple[str, ...] = ("q_cmd", "q_ref", "q", "error", "qd_ref", "load", "tau_load",
                            "tau_dyn", "tau_ext", "q_env")
UNITS = {"q_cmd": "rad", "q_ref": "rad", "q": "rad", "error": "rad", "qd_ref": "rad/s",
         "load": "N·m", "tau_load": "N·m", "tau_dyn": "N·m", "tau_ext": "N·m", "q_env": "rad"}


class Recorder:
    """Ring buffers holding the last ``capacity`` periods of every signal.

    Args:
        n: number of joints.
        capacity: rows kept (e.g. history seconds / period).
        joint_names: names for CSV columns (default j0, j1, ...).
    """

    def __init__(self, n: int, capacity: int, joint_names: Sequence[str] | None = None) -> None:
        if capacity < 2:
            raise ValueError(f"capacity must be >= 2 rows, got {capacity}")
        self.n = n
        self.joint_names = tuple(joint_names) if joint_names else tuple(f"j{i}" for i in range(n))
        self._cols = {"t": slice(0, 1), "wall": slice(1, 2)}
        c = 2
        for name in SIGNALS:
            self._cols[name] = slice(c, c + n)
            c += n
        self._width = c
        self._lock = threading.Lock()
        self._data = np.full((capacity, c), np.nan)
        self._head = 0  # next row to write
        self._count = 0

    @property
    def capacity(self) -> int:
        return self._data.shape[0]

    def __len__(self) -> int:
        return self._count

    def append(self, t: float, signals: Mapping[str, np.ndarray]) -> None:
        """Add one row: ``t`` s and each signal (n,) (missing ones are NaN)."""
        with self._lock:
            row = self._data[self._head]  # written in place: no allocation per period
            row.fill(np.nan)
            row[0] = t
            row[1] = time.time()  # wall clock beside the period count: skipped periods show
            for name, value in signals.items():
                row[self._cols[name]] = value
            self._head = (self._head + 1) % self.capacity
            self._count = min(self._count + 1, self.capacity)

    def clear(self) -> None:
        with self._lock:
            self._head = self._count = 0

    def resize(self, capacity: int) -> None:
        """Change the number of rows kept, keeping the newest ones."""
        if capacity < 2:
            raise ValueError(f"capacity must be >= 2 rows, got {capacity}")
        with self._lock:
            rows = self._ordered()
            keep = rows[-capacity:]
            self._data = np.full((capacity, self._width), np.nan)
            self._data[: len(keep)] = keep
            self._count = len(keep)
            self._head = len(keep) % capacity

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

    def snapshot(self, window_s: float | None = None, *,
                 max_points: int | None = None) -> dict[str, np.ndarray]:
        """Copy of the newest ``window_s`` seconds (all kept rows when None).

        Args:
            window_s: how much history, s.
            max_points: keep at most about this many rows (evenly thinned, newest kept).

        Returns:
            {"t": (m,), signal: (m, n), ...}, oldest first; safe to keep and modify.
        """
        with self._lock:
            if window_s is None or self._count == 0:
                data = self._ordered()
            else:
                newest = self._data[(self._head - 1) % self.capacity, 0]
                # rows are one period apart: find how many fall in the window
                lo, hi = 1, self._count
                while lo < hi:  # binary search on time, newest rows backwards
                    mid = (lo + hi + 1) // 2
                    if self._data[(self._head - mid) % self.capacity, 0] >= newest - window_s:
                        lo = mid
                    else:
                        hi = mid - 1
                data = self._last(lo)
        if max_points is not None and len(data) > max_points > 0:
            step = math.ceil(len(data) / max_points)
            data = data[(len(data) - 1) % step:: step]
        out = {"t": data[:, 0], "wall": data[:, 1]}
        for name in SIGNALS:
            out[name] = data[:, self._cols[name]]
        return out

    def to_csv(self, params: Params | None = None, window_s: float | None = None) -> str:
        """The recording as CSV text, parameters in ``#`` header lines, SI units in the
        column names (one column per joint and signal)."""
        snap = self.snapshot(window_s)
        buf = io.StringIO()
        buf.write("# armlab recording (SI units)\n")
        if params is not None:
            buf.write("# " + ", ".join(f"{k}={v}" for k, v in params.as_dict().items()) + "\n")
        cols = ["t_s", "wall_time_s"] + [f"{s}_{j}_{UNITS[s].replace('·', '')}"
                          for s in SIGNALS for j in self.joint_names]
        buf.write(",".join(cols) + "\n")
        table = np.column_stack([snap["t"], snap["wall"]] + [snap[s] for s in SIGNALS]) \
            if len(snap["t"]) else np.zeros((0, len(cols)))
        for row in table:
            buf.write(",".join("" if np.isnan(v) else (f"{v:.6f}" if k == 1 else f"{v:.6g}")
                               for k, v in enumerate(row)) + "\n")
        return buf.getvalue()
