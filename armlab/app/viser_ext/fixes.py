"""Work-arounds for viser (seen in 1.1.1), applied once when the lab's server module loads.

**The waiter race.** viser's message buffer wakes its sender by setting an
``asyncio.Event`` twice: through the event loop (thread-safe) and directly from the
calling thread, so that synchronous code can read it at once. The direct ``set()`` walks
the event's waiters while the loop thread may be adding one; on a busy machine this now
and then raises ``RuntimeError: deque mutated during iteration`` inside a GUI call made
from a callback thread (a classroom page's welcome, one run in a few under load), and
the page never got the rest of its controls. The message itself is already buffered when
this happens; :func:`install` wraps the buffer's ``push`` so that this one error wakes
the sender the thread-safe way instead of escaping into the lab's code.

**Two property writes made cheap.** A classroom sends every page its own arm 25 times a
second, so what one property write costs is paid some thousand times a second. In viser
1.1.1 a node's ``position`` / ``wxyz`` compared the new value with ``np.allclose``
(about 15 µs of numpy's per-call overhead for 3 or 4 numbers), and every property write
cast its value by comparing the type hint with ``npt.NDArray[...]`` aliases built anew
at each call. :func:`install` replaces both with the same rules at a fraction of the
cost: the pose comparison in plain floats (``|a − b| ≤ 1e-8 + 1e-5·|b|``; an infinity is
close only to itself, a NaN to nothing), the cast by looking the hint up in a table made
once. What reaches the page is unchanged (``tests/test_viser_fixes.py`` compares the
messages).

relies on: ``viser.infra._async_message_buffer.AsyncMessageBuffer.push`` (its
``event_loop``, ``message_event``), ``viser._scene_handles._set_pose_vector``,
``viser._assignable_props_api.AssignablePropsBase._cast_value_recursive`` and
``colors_to_uint8``, ``viser._scene_api.cast_vector``; seen in viser 1.1.1
"""

from __future__ import annotations

import contextlib
import functools
import math
from typing import Any

import numpy as np
import numpy.typing as npt

# Private modules of viser: another release may move them (then that fix is not made).
try:
    from viser.infra._async_message_buffer import AsyncMessageBuffer
except ImportError:  # pragma: no cover - not this viser
    AsyncMessageBuffer = None  # type: ignore[assignment,misc]  # a viser without the class: the fix is skipped
try:
    from viser import _scene_handles
    from viser._assignable_props_api import AssignablePropsBase, colors_to_uint8
    from viser._scene_api import cast_vector

    #: viser's own two functions, kept to compare against (tests/test_viser_fixes.py)
    VISER_SET_POSE_VECTOR: Any = _scene_handles._set_pose_vector
    VISER_CAST_VALUE_RECURSIVE: Any = AssignablePropsBase._cast_value_recursive
except (ImportError, AttributeError):  # pragma: no cover - not this viser
    VISER_SET_POSE_VECTOR = VISER_CAST_VALUE_RECURSIVE = None

#: The words of the race's error (CPython's asyncio.Event.set over a changing deque).
RACE = "mutated during iteration"


def missing() -> list[str]:
    """What of the above this viser lacks (that fix is then not made)."""
    out = []
    if AsyncMessageBuffer is None or not hasattr(AsyncMessageBuffer, "push"):
        out.append("viser.infra._async_message_buffer.AsyncMessageBuffer.push")
    if VISER_SET_POSE_VECTOR is None:
        out.append("viser._scene_handles._set_pose_vector, "
                   "AssignablePropsBase._cast_value_recursive")
    return out


def install() -> None:
    """Make ``AsyncMessageBuffer.push`` survive the waiter race, and pose and property
    writes cheap (idempotent; nothing on a viser without these private modules)."""
    _install_fast_writes()
    if AsyncMessageBuffer is None:
        return
    push = AsyncMessageBuffer.push
    if getattr(push, "armlab_fixed", False):
        return

    @functools.wraps(push)
    def fixed_push(self: AsyncMessageBuffer, message: Any) -> None:
        try:
            push(self, message)
        except RuntimeError as exc:
            if RACE not in str(exc):
                raise
            with contextlib.suppress(RuntimeError):  # a closed loop has no sender to wake
                self.event_loop.call_soon_threadsafe(self.message_event.set)

    fixed_push.armlab_fixed = True  # type: ignore[attr-defined]  # marks the patched function (the fix is applied once)
    AsyncMessageBuffer.push = fixed_push  # type: ignore[method-assign]  # patches viser's push (see the fix's docstring)


#: viser's array type hints -> the dtype a value is cast to (viser 1.1.1's
#: ``_cast_value_recursive``: NDArray[float16 | float32 | float64])
_ARRAY_HINTS = {npt.NDArray[np.float16]: np.float16, npt.NDArray[np.float32]: np.float32,
                npt.NDArray[np.float64]: np.float64}
_COLOR_HINT = npt.NDArray[np.uint8]


def _close(new: tuple[float, ...], current: list[float]) -> bool:
    """``np.allclose(new, current)`` for a few floats, without numpy's call overhead."""
    for a, b in zip(new, current, strict=True):
        if not (a == b or (abs(b) != math.inf and abs(a - b) <= 1e-8 + 1e-5 * abs(b))):
            return False
    return True


def _set_pose_vector(current: np.ndarray, value: Any, length: int, queue: Any,
                     make_message: Any) -> None:
    """viser's pose write (cast, skip an unchanged value, store in place, queue), its
    comparison in plain floats."""
    value_cast = cast_vector(value, length)
    if _close(value_cast, current.tolist()):
        return
    current[:] = value_cast
    queue(make_message(value_cast))


def _cast_value_recursive(self: Any, hint: Any, value: Any, prop_name: str) -> Any:
    """viser's property cast (arrays to the hinted dtype, colours to uint8, tuples item by
    item), the hint found in a table instead of compared with aliases built per call."""
    try:
        dtype = _ARRAY_HINTS.get(hint)
    except TypeError:  # an unhashable hint is no array hint
        dtype = None
    if dtype is not None:
        return np.asarray(value).astype(dtype)
    if "color" in prop_name and hint == _COLOR_HINT:
        return colors_to_uint8(value)
    if isinstance(value, tuple):
        args = getattr(hint, "__args__", None)
        if getattr(hint, "__origin__", None) is tuple and args is not None \
                and len(args) == 2 and args[1] is ...:
            return tuple(_cast_value_recursive(self, args[0], item, prop_name)
                         for item in value)
    return value


def _install_fast_writes() -> None:
    if VISER_SET_POSE_VECTOR is None or getattr(_scene_handles._set_pose_vector,
                                                "armlab_fixed", False):
        return
    _set_pose_vector.armlab_fixed = True  # type: ignore[attr-defined]  # marks the patched function (the fix is applied once)
    _scene_handles._set_pose_vector = _set_pose_vector
    AssignablePropsBase._cast_value_recursive = _cast_value_recursive  # type: ignore[method-assign]  # patches viser's method (see the fix's docstring)
