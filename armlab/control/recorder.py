"""Fixed-size ring buffers of every signal the lab plots, written by the loop, read by the UI.

One writer (the control loop) appends a row per period; readers (the UI at
30 Hz, a CSV export) take a :meth:`Recorder.snapshot`, a copy made under a lock
that is held only for one array copy, so neither side waits on the other.

Signals (SI, joint order of the model), each (m,) for ``t`` and (m, n) otherwise:

=========  ==================================================================
t          loop time, s (periods × period: skipped periods leave no gap here)
wall       wall-clock time of the period, s since the epoch (NaN headless; a gap
           here beside a regular ``t`` shows periods the machine skipped)
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

The contact signals (:data:`CONTACT_SIGNALS`) are one value a period, not one a joint,
each (m,) as ``t`` is: the ground truth of a simulated wall the hand touches
(:class:`armlab.control.backend.Touchable`), which no servo measures. They are NaN when
the backend has no wall in its world (real servos never report one):

==============  ============================================================
f_contact       N, the wall's normal force on the hand at the period (≥ 0)
f_contact_peak  N, the largest wall force at any plant step since the period
                before (an impact between two periods is kept)
==============  ============================================================
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence

import numpy as np

from armlab.control.params import Params
from armlab.control.ring_buffer import RingBuffer

SIGNALS: tuple[str, ...] = ("q_cmd", "q_ref", "q", "error", "qd_ref", "load", "tau_load",
                            "tau_dyn", "tau_ext", "q_env")
UNITS = {"q_cmd": "rad", "q_ref": "rad", "q": "rad", "error": "rad", "qd_ref": "rad/s",
         "load": "N·m", "tau_load": "N·m", "tau_dyn": "N·m", "tau_ext": "N·m", "q_env": "rad",
         "f_contact": "N", "f_contact_peak": "N"}
#: The signals of one value a period (not one a joint): the hand's contact with a wall
CONTACT_SIGNALS: tuple[str, ...] = ("f_contact", "f_contact_peak")


class Recorder:
    """The last ``capacity`` periods of every signal: a
    :class:`~armlab.control.ring_buffer.RingBuffer` with one named column per joint and
    signal.

    Args:
        n: number of joints.
        capacity: rows kept (e.g. history seconds / period).
        joint_names: names for CSV columns (default j0, j1, ...).
    """

    def __init__(self, n: int, capacity: int, joint_names: Sequence[str] | None = None) -> None:
        self.n = n
        self.joint_names = tuple(joint_names) if joint_names else tuple(f"j{i}" for i in range(n))
        self._cols = {"t": slice(0, 1), "wall": slice(1, 2)}
        c = 2
        for name in SIGNALS:
            self._cols[name] = slice(c, c + n)
            c += n
        for name in CONTACT_SIGNALS:  # after the joints' (one column each)
            self._cols[name] = slice(c, c + 1)
            c += 1
        self._ring = RingBuffer(c, capacity)
        self._no_joints = [math.nan] * n  #: a joint signal not given this period

    @property
    def capacity(self) -> int:
        return self._ring.capacity

    def __len__(self) -> int:
        return len(self._ring)

    def append(self, t: float, signals: Mapping[str, np.ndarray | float], *,
               wall: float = math.nan) -> None:
        """Add one row: loop time ``t`` s, the wall clock ``wall`` s (epoch) and each signal
        (n,), or a float for a contact signal (missing ones are NaN)."""
        if not signals.keys() <= self._cols.keys():
            raise KeyError(f"not a recorded signal: {sorted(signals.keys() - self._cols.keys())}")
        n = self.n
        row = [t, wall]  # the row as Python floats, written at once (every period of every arm)
        for name in SIGNALS:
            value = signals.get(name)
            if value is None:
                row.extend(self._no_joints)
            elif type(value) is np.ndarray and value.shape == (n,):  # the loop's own
                row.extend(value.tolist())
            else:
                row.extend(np.broadcast_to(np.asarray(value, dtype=float), (n,)).tolist())
        for name in CONTACT_SIGNALS:
            row.append(float(signals.get(name, math.nan)))  # a contact signal: one float
        self._ring.append(row)

    def clear(self) -> None:
        self._ring.clear()

    def since(self, written: int) -> tuple[np.ndarray, int]:
        """The raw rows (t, wall, each signal's n columns in :data:`SIGNALS` order, then one
        column per :data:`CONTACT_SIGNALS`)
        appended after the first ``written`` ever appended, and the count now: what a
        mirror of this recorder in another process is sent (:meth:`extend`)."""
        return self._ring.since(written)

    def extend(self, rows: np.ndarray) -> None:
        """Append raw rows (m, :attr:`width`) as :meth:`since` gave them."""
        self._ring.extend(rows)

    def resize(self, capacity: int) -> None:
        """Change the number of rows kept, keeping the newest ones."""
        self._ring.resize(capacity)

    def snapshot(self, window_s: float | None = None, *,
                 max_points: int | None = None) -> dict[str, np.ndarray]:
        """Copy of the newest ``window_s`` seconds (all kept rows when None).

        Args:
            window_s: how much history, s.
            max_points: keep at most about this many rows (evenly thinned, newest kept).

        Returns:
            {"t": (m,), "wall": (m,), signal: (m, n), ..., contact signal: (m,)}, oldest
            first; safe to keep and modify.
        """
        return self.unpack(self._ring.rows(window_s, max_points=max_points))

    def recent(self, rows: int) -> tuple[np.ndarray, int]:
        """The newest ``rows`` raw rows and the count ever appended, read together (a
        follower's start: :meth:`since` from that count on)."""
        return self._ring.recent(rows)

    @property
    def width(self) -> int:
        """Floats in a raw row (:meth:`since`): t, wall, n per signal, one per contact
        signal."""
        return self._ring.width

    def unpack(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Raw rows (m, :attr:`width`) as :meth:`snapshot` gives them: {"t": (m,), "wall":
        (m,), signal: (m, n), contact signal: (m,)} (views of ``data``)."""
        out = {"t": data[:, 0], "wall": data[:, 1]}
        for name in SIGNALS:
            out[name] = data[:, self._cols[name]]
        for name in CONTACT_SIGNALS:
            out[name] = data[:, self._cols[name].start]
        return out

    def to_csv(self, params: Params | None = None, window_s: float | None = None) -> str:
        """The recording as CSV text, parameters in ``#`` header lines, SI units in the
        column names (one column per joint and signal)."""
        return snapshot_csv(self.snapshot(window_s), self.joint_names,
                            None if params is None else params.as_dict())


def snapshot_csv(snap: Mapping[str, np.ndarray], joint_names: Sequence[str],
                 params: Mapping[str, object] | None = None) -> str:
    """Rows in :meth:`Recorder.snapshot`'s layout (a window, or a run's rows kept apart:
    :class:`armlab.control.run_track.RunTrack`) as CSV text: parameters in a ``#`` header
    line, SI units in the column names (one column per joint and signal, then one per
    contact signal the rows hold: ``f_contact_N``, ``f_contact_peak_N``, empty cells where
    NaN); times to 10 significant digits (a period of 1 ms stays apart for 10⁶ s of loop
    time)."""
    buf = io.StringIO()
    buf.write("# armlab recording (SI units)\n")
    if params is not None:
        buf.write("# " + ", ".join(f"{k}={v}" for k, v in params.items()) + "\n")
    contact = [s for s in CONTACT_SIGNALS if s in snap]
    cols = ["t_s", "wall_time_s"] + [f"{s}_{j}_{UNITS[s].replace('·', '')}"
                                     for s in SIGNALS for j in joint_names] + [
                                         f"{s}_{UNITS[s]}" for s in contact]
    buf.write(",".join(cols) + "\n")
    signals: np.ndarray | list[np.ndarray] = (
        np.column_stack([snap[s] for s in SIGNALS] + [snap[s] for s in contact])
        if len(snap["t"]) else [])
    for t, wall, row in zip(snap["t"], snap["wall"], signals, strict=True):
        buf.write(",".join([f"{t:.10g}", "" if np.isnan(wall) else f"{wall:.4f}"]
                           + ["" if np.isnan(v) else f"{v:.6g}" for v in row]) + "\n")
    return buf.getvalue()
