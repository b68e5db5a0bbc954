"""Number inputs that refuse bad values: non-finite or outside their range.

A browser can send anything (a typed "1e999", NaN from a hand-made message, a
value outside the slider's range). :class:`GuardedNumber` wraps a viser slider
or number handle: a bad value is refused with a notification to the client that
sent it and the input is put back to its last good value, so the server state
and every page stay consistent and nothing downstream ever sees it.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import viser


def check_number(value: Any, *, name: str, lo: float, hi: float) -> float:
    """``value`` as a float in [lo, hi].

    Raises:
        ValueError: naming ``name`` when ``value`` is not a finite number in range.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: {value!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: {value!r} is not a finite number")
    if not lo <= v <= hi:
        raise ValueError(f"{name}: {v:g} is outside [{lo:g}, {hi:g}]")
    return v


def notify(client: viser.ClientHandle | None, title: str, body: str, *,
           color: str = "red", seconds: float = 6.0) -> None:
    """Show a notification to ``client`` (nothing when the change came from Python)."""
    if client is None:
        return
    client.add_notification(title, body, color=color, auto_close_seconds=seconds)


class GuardedNumber:
    """A slider/number input whose bad values are refused and reverted.

    Args:
        handle: viser slider or number handle (float-valued).
        name: what the message calls it ("Kp").
        lo, hi: accepted range (inclusive).
        apply: called with the new good value; may raise ValueError to refuse it
            (e.g. a combination of values the controller cannot take); its message
            is shown to the client.
        lock: a re-entrant lock to share with related inputs (one lock for a group
            avoids lock-order deadlocks when one input's change sets another).

    Attributes:
        value: the last accepted value.
    """

    def __init__(self, handle: Any, *, name: str, lo: float, hi: float,
                 apply: Callable[[float], None], lock: threading.RLock | None = None) -> None:
        self.handle = handle
        self.name = name
        self.lo = float(lo)
        self.hi = float(hi)
        self._apply = apply
        self._lock = lock if lock is not None else threading.RLock()  # reverting re-enters
        self.value = float(handle.value)
        self.refused = 0  #: how many values were refused (for tests and the status line)
        handle.on_update(self._on_update)

    def _on_update(self, event: viser.GuiEvent) -> None:
        with self._lock:
            raw = self.handle.value
            try:
                v = check_number(raw, name=self.name, lo=self.lo, hi=self.hi)
            except ValueError as exc:
                self._refuse(event.client, str(exc))
                return
            if v == self.value:
                return
            try:
                self._apply(v)
            except ValueError as exc:
                self._refuse(event.client, str(exc))
                return
            self.value = v

    def _refuse(self, client: viser.ClientHandle | None, message: str) -> None:
        self.refused += 1
        notify(client, "Value refused", f"{message}; kept {self.value:g}.")
        # Put the input back; the synchronous callback this fires sees the good
        # value and returns without applying anything.
        self.handle.value = self.value

    def set(self, value: float) -> None:
        """Set from Python (a preset): shown on every page and applied."""
        self.handle.value = float(value)


def guarded_slider(gui: viser.GuiApi, label: str, *, name: str, lo: float, hi: float,
                   step: float, initial: float, apply: Callable[[float], None],
                   hint: str | None = None, visible: bool = True,
                   lock: threading.RLock | None = None) -> GuardedNumber:
    """A slider over [lo, hi] whose values pass a :class:`GuardedNumber` over the same range.

    The range is stated once, so the slider and its guard cannot disagree. The
    slider handle is the result's ``handle``.
    """
    handle = gui.add_slider(label, min=lo, max=hi, step=step, initial_value=initial, hint=hint,
                            visible=visible)
    return GuardedNumber(handle, name=name, lo=lo, hi=hi, apply=apply, lock=lock)
