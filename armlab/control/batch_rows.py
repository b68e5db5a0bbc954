"""Stable ids of the members of a batch and the rows they hold (the order they joined).

A batched simulation (:mod:`armlab.hardware.sim.batched_hand`,
:mod:`armlab.hardware.families.dynamixel1.batched_quadruped`)
and its batched controllers (:mod:`armlab.control.batched_grip`) keep their members' state in
arrays, one row each. A
member is named by an id that never changes; its row moves up when one before it
leaves.
"""

from __future__ import annotations


class BatchRows:
    """The ids of a batch's members in row order."""

    def __init__(self) -> None:
        self._ids: list[int] = []
        self._next = 0

    def __len__(self) -> int:
        return len(self._ids)

    @property
    def ids(self) -> tuple[int, ...]:
        """The members' ids in row order."""
        return tuple(self._ids)

    def row(self, member: int) -> int:
        """The row of ``member`` (ValueError: not in the batch)."""
        try:
            return self._ids.index(member)
        except ValueError:
            raise ValueError(f"no member {member!r} in this batch") from None

    def join(self) -> int:
        """A new member in the last row; returns its id."""
        member, self._next = self._next, self._next + 1
        self._ids.append(member)
        return member

    def leave(self, member: int) -> int:
        """Take ``member`` out; returns the row it held (ValueError: not in the batch)."""
        r = self.row(member)
        del self._ids[r]
        return r
