"""What a lesson uses of a loop that takes commands and records rows, in any thread.

The hand's :class:`armlab.control.grip_loop.GripLoop` and the quadruped's
:class:`armlab.control.gait_loop.GaitLoop`, and the server's proxies of such loops running in a
worker process (``armlab.app.workers.remote_hand``, ``armlab.app.workers.remote_gait``), share
this surface; their records are :class:`armlab.control.ring_buffer.RingBuffer` rows.
"""

from __future__ import annotations

import numpy as np

from armlab.control.ring_buffer import RingBuffer


class LoopRecord:
    """Commands in, record rows out.

    A subclass names the commands it takes (:attr:`COMMANDS`, what they are called in a
    refusal: :attr:`WHAT`) and hands a checked one on (:meth:`_send`).
    """

    COMMANDS: tuple[type, ...] = ()
    WHAT = "loop"
    _ring: RingBuffer

    def post(self, command: object) -> None:
        """Apply ``command`` before the loop's next period.

        Raises:
            ValueError: not one of :attr:`COMMANDS` (or the loop refuses it).
        """
        if not isinstance(command, self.COMMANDS):
            raise ValueError(f"not a {self.WHAT} command: {type(command).__name__}")
        self._send(command)

    def _send(self, command: object) -> None:
        """Hand a checked command to whatever runs the loop."""
        raise NotImplementedError

    @property
    def capacity(self) -> int:
        """Rows the record keeps."""
        return self._ring.capacity

    def rows_since(self, written: int) -> tuple[np.ndarray, int]:
        """The record's rows after the first ``written`` ever written, and the number
        written now (:meth:`armlab.control.ring_buffer.RingBuffer.since`: a mirror's bookmark)."""
        return self._ring.since(written)

    # --- a run's track follows the record (armlab.control.run_track.RowSource) ---------

    @property
    def width(self) -> int:
        """Floats in a record row."""
        return self._ring.width

    def recent(self, rows: int) -> tuple[np.ndarray, int]:
        """The newest ``rows`` rows and the number ever written, read together."""
        return self._ring.recent(rows)

    def since(self, written: int) -> tuple[np.ndarray, int]:
        """:meth:`rows_since` (a :class:`~armlab.control.run_track.RunTrack` follows it)."""
        return self._ring.since(written)

    def unpack(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Raw rows (m, :attr:`width`) as the loop's ``snapshot`` gives them."""
        raise NotImplementedError
