"""Number inputs with one rule for what a person types (:func:`typed_value`).

A browser can send anything (a typed "1e999", NaN from a hand-made message, a
value outside the slider's range). The rule, the same for every number on the page:

- a finite number inside the input's range is applied as it is;
- a finite number outside it is applied as the nearest end of the range (the value
  the browser's own field clamps to when it loses focus), and the page that sent it
  is told so: "Kp: 999999 is above the largest value, 200; set to 200.";
- anything else (NaN, inf, text, a bool) is refused and the input keeps its value:
  "Kp: nan is not a finite number; kept 20.".

So the value applied is always the value the message names. :class:`GuardedNumber`
wraps a viser slider or number handle and applies the rule with its own range (and
its ``apply`` may refuse a value, e.g. a gain the loop cannot take);
:class:`UpdateScreen` applies it to every input before viser sees the value.
"""

from __future__ import annotations

import asyncio
import math
import sys
import threading
import time
import weakref
from collections.abc import Callable
from typing import Any

import viser

from armlab.app.viser_ext.clients import connected, queue
from armlab.app.viser_ext.dispatch import screen_gui_updates
from armlab.app.viser_ext.handles import gui_inputs, is_removed, uuid_of
from armlab.app.viser_ext.messages import GuiUpdateMessage
from armlab.kinematics.validate import check_number

#: s a value typed past the range stays in the typer's field before it shows the value
#: applied: once the typing pauses that long (the field itself clamps when it loses focus;
#: sooner, the next digit would land after the shown end: "999" shown as 200, then "20099").
SHOW_APPLIED_S = 1.0
_show_timers: dict[tuple[int, int], threading.Timer] = {}
#: The title of the message that a typed value was set to the end of its range.
LIMIT_TITLE = "Value set to its limit"


def typed_value(raw: object, *, name: str, lo: float, hi: float) -> tuple[float, str | None]:
    """What a typed number ``raw`` is applied as, under the page's one rule (module
    docstring): ``(value, None)`` inside [lo, hi]; ``(the nearest end, the message that
    says so)`` outside it.

    Raises:
        ValueError: ``raw`` is not a finite number (the message names ``name``).
    """
    if isinstance(raw, bool):
        raise ValueError(f"{name}: {raw!r} is not a number")
    v = check_number(raw, name=name, lo=-math.inf, hi=math.inf)
    if lo <= v <= hi:
        return v, None
    end, side = (lo, "below the smallest") if v < lo else (hi, "above the largest")
    return end, f"{name}: {v:g} is {side} value, {end:g}; set to {end:g}."


#: s a page's message that a control's value was set to its limit stays open; a further
#: value of that control past its range within it updates that message (typing "999999"
#: sends six values: one message, naming the last).
LIMIT_SECONDS = 6.0
#: page -> control -> (its open message, when it opened); a page's entries go with it
_limit_notes: weakref.WeakKeyDictionary[Any, dict[str, tuple[Any, float]]] = \
    weakref.WeakKeyDictionary()
_limit_lock = threading.Lock()


def tell_limit(client: viser.ClientHandle | None, control: str, body: str) -> None:
    """Tell ``client`` that ``control``'s value was set to the end of its range (``body``,
    from :func:`typed_value`): one message per control and page, updated while open."""
    if client is None:
        return
    now = time.monotonic()
    with _limit_lock:
        notes = _limit_notes.setdefault(client, {})
        shown = notes.get(control)
        if shown is not None and now - shown[1] < LIMIT_SECONDS:
            shown[0].body = body  # (it closes when it was to close)
            return
        notes[control] = (client.add_notification(LIMIT_TITLE, body, color="yellow",
                                                  auto_close_seconds=LIMIT_SECONDS), now)


def show_applied_soon(client: viser.ClientHandle | None, handle: Any, value: Any) -> None:
    """Once ``client``'s person has paused typing into ``handle`` for :data:`SHOW_APPLIED_S`,
    its field shows ``value``, the value applied: every page's, when the input itself does
    not hold it yet, else the typer's page's alone (the others were sent it already)."""
    if client is None:
        return
    key = (id(client), id(handle))

    def show() -> None:
        with _limit_lock:
            if _show_timers.get(key) is not timer:
                return
            del _show_timers[key]
        if handle.value != value:
            try:
                handle.value = value
            except RuntimeError:  # removed meanwhile (its lesson or page went): no field
                if not is_removed(handle):
                    raise
        elif connected(client) and GuiUpdateMessage is not None:
            queue(client, GuiUpdateMessage(uuid_of(handle), {"value": handle.value}))

    timer = threading.Timer(SHOW_APPLIED_S, show)
    timer.daemon = True
    with _limit_lock:
        old = _show_timers.pop(key, None)
        if old is not None:
            old.cancel()
        _show_timers[key] = timer
    timer.start()


def notify(client: viser.ClientHandle | None, title: str, body: str, *,
           color: str = "red", seconds: float = 6.0) -> None:
    """Show a notification to ``client`` (nothing when the change came from Python)."""
    if client is None:
        return
    client.add_notification(title, body, color=color, auto_close_seconds=seconds)  # type: ignore[call-overload]  # color: one of viser's colour names (the callers')


#: The inputs a :class:`GuardedNumber` applies the rule to, by their uuid: the guard knows
#: whether its ``apply`` takes the end of the range, so :class:`UpdateScreen` hands it the
#: value typed (:meth:`GuardedNumber.typed`) and leaves the message to it rather than
#: announce a value that may then be refused.
_GUARDED: weakref.WeakValueDictionary[str, GuardedNumber] = weakref.WeakValueDictionary()


class GuardedNumber:
    """A slider/number input under the page's one rule (module docstring): a value outside
    its range applied as the nearest end and the page told, a bad value refused and the
    input put back.

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
        self._typed: Any = None  #: the value typed, when the screen put it in range
        handle.on_update(self._on_update)
        _GUARDED[uuid_of(handle)] = self

    def typed(self, raw: object) -> None:
        """The page typed ``raw``, which :class:`UpdateScreen` put in the input's range
        before viser took it (the handle never holds a value outside it): the message
        names ``raw``."""
        with self._lock:
            self._typed = raw

    def _on_update(self, event: viser.GuiEvent) -> None:
        with self._lock:
            raw = self.handle.value
            typed, self._typed = self._typed, None
            try:
                v, clamped = typed_value(raw, name=self.name, lo=self.lo, hi=self.hi)
                if clamped is None and typed is not None:  # (the screen clamped it)
                    end, clamped = typed_value(typed, name=self.name, lo=self.lo, hi=self.hi)
                    clamped = clamped if end == v else None
            except ValueError as exc:
                self._refuse(event.client, str(exc))
                return
            if v != self.value:
                try:
                    self._apply(v)
                except ValueError as exc:
                    self._refuse(event.client, str(exc))
                    return
                self.value = v
            if clamped is not None:
                tell_limit(event.client, self.name, clamped)
                show_applied_soon(event.client, self.handle, v)

    def tell(self, client: viser.ClientHandle | None, raw: object) -> None:
        """The page typed ``raw`` past the range while the input already held its end
        (viser then calls no one): say so in the guard's words, if that end is applied."""
        try:
            end, note = typed_value(raw, name=self.name, lo=self.lo, hi=self.hi)
        except ValueError:
            return
        if note is not None and end == self.value:
            tell_limit(client, self.name, note)
            show_applied_soon(client, self.handle, self.value)

    def _refuse(self, client: viser.ClientHandle | None, message: str) -> None:
        self.refused += 1
        notify(client, "Value refused", f"{message}; kept {self.value:g}.")
        # Put the input back; the synchronous callback this fires sees the good
        # value and returns without applying anything.
        self.handle.value = self.value

    def set(self, value: float) -> None:
        """Set from Python (a preset): shown on every page and applied."""
        self.handle.value = float(value)


def inward_range(lo: float, hi: float, *, step: float) -> tuple[float, float]:
    """[lo, hi] with its ends rounded inwards to multiples of ``step`` (> 0): a slider's
    ends print as round numbers ("179.5", not "179.912109") and every value it offers
    stays inside [lo, hi]. A range holding no multiple of ``step`` is returned as it is."""
    places = max(0, -math.floor(math.log10(step))) + 1  # digits the multiples need
    a = round(math.ceil(lo / step) * step, places)
    b = round(math.floor(hi / step) * step, places)
    a = a if a >= lo else a + step  # (rounding to places never crosses an end: kept in)
    b = b if b <= hi else b - step
    return (a, b) if a <= b else (lo, hi)


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


#: s: a client hears about (and the log tells of) refusals of one control at most this often.
REFUSAL_INTERVAL = 1.0
#: s: one control takes a client's value at most this often (about one control period);
#: values arriving faster are coalesced, the latest wins.
COALESCE_INTERVAL = 0.016
#: characters: longest text a text or dropdown input takes.
MAX_TEXT = 10_000
#: characters: longest log line the screen writes.
MAX_LOG_LINE = 200


def _brief(value: Any) -> str:
    """A short description of a client value, safe to log (a 10 MB string stays short)."""
    text = repr(value) if not isinstance(value, (str, list, dict, tuple)) or len(value) < 20 \
        else f"{type(value).__name__} of length {len(value)}"
    return text[:40]


def _is_number(v: Any) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    return abs(v) < 1e300 if isinstance(v, int) else math.isfinite(v)


def _check_scalar(v: Any, current: Any, lo: Any, hi: Any) -> str | None:
    """Why ``v`` cannot go where ``current`` is (None: it can). A number outside [lo, hi]
    can: :func:`clamp_to_range` puts it at the nearest end first."""
    if isinstance(current, bool):
        return None if isinstance(v, bool) else f"{_brief(v)} is not true/false"
    if isinstance(current, (int, float)):
        if not _is_number(v):
            return f"{_brief(v)} is not a finite number"
        if isinstance(current, int) and not isinstance(v, int) and not float(v).is_integer():
            return f"{_brief(v)} is not a whole number"
        return None
    if isinstance(current, str):
        if not isinstance(v, str) or len(v) > MAX_TEXT:
            return f"{_brief(v)} is not a text of at most {MAX_TEXT} characters"
        return None
    return f"{_brief(v)} is not accepted here"


def clamp_to_range(handle: Any, value: Any, *, name: str) -> tuple[Any, str | None]:
    """``value`` (one :func:`why_bad_value` accepts) for input ``handle``, a number outside
    the handle's range put at its nearest end (:func:`typed_value`), with the message
    that says so (None: nothing changed). A vector's items are each put in range."""
    current = handle.value
    lo, hi = getattr(handle, "min", None), getattr(handle, "max", None)

    def one(v: Any, c: Any, lo: Any, hi: Any) -> tuple[Any, str | None]:
        if isinstance(c, bool) or not isinstance(c, (int, float)) or isinstance(v, bool):
            return v, None
        got, note = typed_value(v, name=name, lo=-math.inf if lo is None else float(lo),
                                hi=math.inf if hi is None else float(hi))
        return (int(got) if isinstance(c, int) else got, note) if note else (v, None)

    if isinstance(current, tuple):
        out, notes = [], []
        for i, (v, c) in enumerate(zip(value, current, strict=True)):
            got, note = one(v, c, lo[i] if isinstance(lo, tuple) else lo,
                            hi[i] if isinstance(hi, tuple) else hi)
            out.append(got)
            if note:
                notes.append(f"item {i}: {note}")
        return (tuple(out), " ".join(notes)) if notes else (value, None)
    return one(value, current, lo, hi)


def why_bad_value(handle: Any, value: Any) -> str | None:
    """Why ``value`` from a client cannot go into input ``handle`` (None: it can).

    Checks the type as well as the range: a bool is not a number, a string is
    not a number, a list is not a vector of another length; a dropdown or button
    group takes only one of its options.
    """
    current = handle.value
    lo, hi = getattr(handle, "min", None), getattr(handle, "max", None)
    if isinstance(current, tuple):
        if not isinstance(value, (list, tuple)) or len(value) != len(current):
            return f"{_brief(value)} is not a list of {len(current)} values"
        for i, (v, c) in enumerate(zip(value, current, strict=True)):
            why = _check_scalar(v, c, lo[i] if isinstance(lo, tuple) else lo,
                                hi[i] if isinstance(hi, tuple) else hi)
            if why is not None:
                return f"item {i}: {why}"
        return None
    options = getattr(handle, "options", None)
    why = _check_scalar(value, current, lo, hi)
    if why is None and options is not None and value not in options:
        return f"{_brief(value)} is not one of the choices"
    return why


class UpdateScreen:
    """Checks every GUI update a client sends before viser or the lab acts on it.

    Installed in front of viser's own handler of ``GuiUpdateMessage``. An update
    to an unknown control, or of a property other than ``value``, is dropped
    and counted; a value that fails :func:`why_bad_value` is refused: the client
    gets one notification per control per :data:`REFUSAL_INTERVAL`, the log one
    line of at most :data:`MAX_LOG_LINE` characters at the same rate.

    Args:
        server: the lab's server (notifications go to its pages).
        gui: a page's own GUI (``client.gui``, a private lesson's controls) to screen
            instead of the server's; updates of controls it does not hold are then left to
            the server's screen, neither dropped nor counted.

    Attributes:
        screened: updates seen so far. refused: values refused so far. dropped: updates
            dropped so far.
    """

    def __init__(self, server: viser.ViserServer, *, gui: viser.GuiApi | None = None,
                 log: Callable[[str], None] | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        self._server = server
        self._gui = server.gui if gui is None else gui
        self._own_only = gui is not None
        self._log = log or (lambda line: print(line, file=sys.stderr, flush=True))
        self._clock = clock or time.monotonic
        self._last: dict[tuple[Any, str], float] = {}
        self.screened = 0
        self.refused = 0
        self.dropped = 0
        self.coalesced = 0  #: values replaced by a later one before they were applied
        self._applied_at: dict[str, float] = {}
        self._pending: dict[str, tuple[Any, Any]] = {}
        self._inner = screen_gui_updates(self._gui, self._screen)

    def _due(self, key: tuple[Any, str]) -> bool:
        now = self._clock()
        if now - self._last.get(key, -math.inf) < REFUSAL_INTERVAL:
            return False
        self._last[key] = now
        return True

    def _say(self, line: str) -> None:
        self._log(line[:MAX_LOG_LINE])

    async def _screen(self, client_id: Any, message: Any) -> None:
        """Screen one update (counted in :attr:`screened` once it is dealt with)."""
        try:
            await self._screen_one(client_id, message)
        finally:
            self.screened += 1

    async def _screen_one(self, client_id: Any, message: Any) -> None:
        uuid = message.uuid if isinstance(message.uuid, str) else repr(message.uuid)[:40]
        handle = gui_inputs(self._gui).get(uuid)
        updates = message.updates
        if handle is None and (self._own_only or self._page_owns(client_id, uuid)):
            return  # the other screen (the server's, or the page's own) deals with it
        if handle is None or not isinstance(updates, dict) or set(updates) != {"value"}:
            self.dropped += 1
            if self._due((None, "dropped")):
                self._say(f"armlab: dropped {self.dropped} update(s) of unknown controls or "
                          f"properties so far (last: control {uuid[:40]!r})")
            return
        why = why_bad_value(handle, updates["value"])
        if why is None:
            label = str(handle.label)[:40]
            raw = updates["value"]
            value, clamped = clamp_to_range(handle, raw, name=label)
            if clamped is not None:  # applied as the end of the range, and the page told
                updates["value"] = value  # (so no handle ever holds a value past its range)
                guard = _GUARDED.get(uuid)
                client = self._server.get_clients().get(client_id)
                if guard is None:
                    tell_limit(client, uuid, clamped)
                    show_applied_soon(client, handle, value)
                elif value != handle.value:  # the guard tells, once its apply has taken it
                    guard.typed(raw)
                else:  # unchanged: viser calls no one
                    guard.tell(client, raw)
            await self._coalesce(uuid, client_id, message)  # (the field clamps on blur)
            return
        self.refused += 1
        label = str(handle.label)[:40]
        if self._due((client_id, uuid)):
            self._say(f"armlab: refused {label} from client {client_id}: {why} "
                      f"({self.refused} refused so far)")
            client = self._server.get_clients().get(client_id)
            notify(client, "Value refused", f"{label}: {why}; kept {_brief(handle.value)}.")

    def _page_owns(self, client_id: Any, uuid: str) -> bool:
        """Whether ``uuid`` is a control of the sending page's own GUI (``client.gui``)."""
        client = self._server.get_clients().get(client_id)
        gui = getattr(client, "gui", None)
        return gui is not None and uuid in gui_inputs(gui)

    async def _coalesce(self, uuid: str, client_id: Any, message: Any) -> None:
        """Apply now, or (within :data:`COALESCE_INTERVAL` of the last) keep only the latest."""
        if uuid in self._pending:
            self.coalesced += 1
            self._pending[uuid] = (client_id, message)
            return
        wait = self._applied_at.get(uuid, -math.inf) + COALESCE_INTERVAL - self._clock()
        if wait > 0:
            self._pending[uuid] = (client_id, message)
            await asyncio.sleep(wait)
            client_id, message = self._pending.pop(uuid)
        self._applied_at[uuid] = self._clock()
        await self._inner(client_id, message)
