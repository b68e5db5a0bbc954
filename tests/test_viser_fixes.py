"""armlab.app.viser_ext.fixes: a GUI call from a callback thread that meets viser's waiter race
(``deque mutated during iteration`` from the direct ``asyncio.Event.set``) still reaches
the page, and the lab's code never sees the error. The race itself needs a busy machine;
here the buffer's event raises it on demand, once."""

from __future__ import annotations

import viser
from _helpers import client_of

from armlab.app.viser_ext import fixes as viser_fixes


def test_a_gui_call_that_meets_the_race_reaches_the_page():
    viser_fixes.install()
    viser_fixes.install()  # twice is once
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with client_of(server) as page:
            (client,) = server.get_clients().values()
            event = client._websock_connection.get_message_buffer().message_event
            calls: list[str] = []
            set_event = event.set

            def racing_set() -> None:  # the first set (the direct one) meets the race
                calls.append("set")
                if len(calls) == 1:
                    raise RuntimeError("deque mutated during iteration")
                set_event()

            event.set = racing_set  # the sender waits on this very event
            handle = client.gui.add_markdown("after the race")  # must not raise
            page.wait_for(lambda: any(e.props.get("_markdown") == "after the race"
                                      for e in list(page.gui.values())),
                          what="the markdown that met the race")
            assert len(calls) >= 2  # raced, then woke the sender through the loop
            handle.remove()
    finally:
        server.stop()


# ---------------------------------------------------------------- the cheap writes

import dataclasses  # noqa: E402
import math  # noqa: E402
import typing  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from viser import _messages  # noqa: E402

needs_fast_writes = pytest.mark.skipif(
    viser_fixes.VISER_SET_POSE_VECTOR is None,
    reason="this viser has not the private functions the fast writes replace")

POSES = [
    (3, (1.0, 2.0, 3.0)), (3, (1.0, 2.0, 3.0 + 1e-9)), (3, (1.0, 2.0, 3.0001)),
    (3, np.array([0.0, 0.0, 0.0])), (3, [1e-9, 0.0, 0.0]), (3, (math.nan, 0.0, 0.0)),
    (3, (math.inf, 0.0, 0.0)), (3, (-math.inf, 0.0, 0.0)), (3, np.float32([1, 2, 3])),
    (4, (1.0, 0.0, 0.0, 0.0)), (4, np.array([0.7071, 0.7071, 0.0, 0.0])),
    (3, (1, 2)), (3, np.zeros(4)), (4, "abcd"),
]


def _pose_write(fn, current, length, value):
    sent: list = []
    try:
        fn(current, value, length, sent.append, lambda v: ("message", v))
    except (ValueError, TypeError) as exc:
        return type(exc), current
    return sent, current


@needs_fast_writes
@pytest.mark.parametrize("start", [(1.0, 2.0, 3.0, 0.0), (math.inf, 0.0, 0.0, 1.0),
                                   (math.nan, 0.0, 0.0, 1.0)])
def test_a_pose_write_sends_and_stores_what_visers_own_does(start):
    viser_fixes.install()
    for length, value in POSES:
        mine = _pose_write(viser_fixes._set_pose_vector, np.array(start[:length]), length, value)
        theirs = _pose_write(viser_fixes.VISER_SET_POSE_VECTOR, np.array(start[:length]),
                             length, value)
        assert mine[0] == theirs[0], (start, value)
        np.testing.assert_array_equal(mine[1], theirs[1])


class _Viser:  # viser's own cast, recursing into itself
    _cast_value_recursive = viser_fixes.VISER_CAST_VALUE_RECURSIVE


def _hints() -> list[tuple[str, typing.Any]]:
    """(name, hint) of every property of viser's messages' props."""
    out = {}
    for obj in vars(_messages).values():
        if isinstance(obj, type) and dataclasses.is_dataclass(obj) \
                and obj.__name__.endswith("Props"):
            for name, hint in typing.get_type_hints(obj).items():
                out[(name, repr(hint))] = (name, hint)
    return list(out.values())


VALUES = [np.zeros(3), np.arange(6, dtype=np.int64).reshape(2, 3), np.float32([1.5, 2.5]),
          (np.zeros(2), np.ones(2)), (1.0, 2.0), [0.1, 0.2, 0.3], (255, 0, 0), "text", 3.0,
          None, True, {"a": 1}]


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (type(a) is type(b) and a.dtype == b.dtype and a.shape == b.shape
                and np.array_equal(a, b, equal_nan=True))
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


@needs_fast_writes
def test_a_property_cast_is_visers_own_for_every_hint_of_its_messages():
    hints = _hints()
    assert len(hints) > 50  # the props of viser's messages, every kind of hint among them
    for name, hint in hints:
        for value in VALUES:
            try:
                theirs = viser_fixes.VISER_CAST_VALUE_RECURSIVE(_Viser(), hint, value, name)
            except Exception as exc:  # noqa: BLE001 - whatever viser's raises, ours must
                with pytest.raises(type(exc)):
                    viser_fixes._cast_value_recursive(None, hint, value, name)
                continue
            mine = viser_fixes._cast_value_recursive(None, hint, value, name)
            assert _same(mine, theirs), (name, hint, value, mine, theirs)


@needs_fast_writes
def test_the_cheap_writes_are_the_ones_a_served_page_gets():
    viser_fixes.install()
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with client_of(server) as page:
            frame = server.scene.add_frame("/probe", show_axes=False)
            frame.position = (0.25, -0.5, 1.0)
            frame.wxyz = np.array([0.0, 1.0, 0.0, 0.0])
            frame.position = (0.25, -0.5, 1.0 + 1e-12)  # unchanged: nothing stored or sent
            assert tuple(frame.position) == (0.25, -0.5, 1.0)
            frame.position = np.array([0.5, 0.0, 0.0])

            def pose(kind: str, field: str) -> tuple[float, ...] | None:
                got = page.scene["/probe"].get(kind)
                return None if got is None else tuple(got[field])

            page.wait_for(lambda: pose("SetPositionMessage", "position") == (0.5, 0.0, 0.0),
                          what="the probe frame's last position")
            assert pose("SetOrientationMessage", "wxyz") == (0.0, 1.0, 0.0, 0.0)
    finally:
        server.stop()
