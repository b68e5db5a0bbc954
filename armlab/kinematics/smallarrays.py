"""numpy on arrays of a few joints, for code that runs every period of every arm.

On an (n,) array of 3 joints numpy's cost is its per-call overhead: ``np.clip`` and
the reductions (``.all()``, ``.any()``, ``.max()``) cost 1–2 µs a call, an elementwise
ufunc a third of that, Python arithmetic on ``tolist()`` floats less still. These helpers
give the same results as the numpy spelling named in each docstring, for less: a class
of a hundred private arms runs them in every period of every arm (``armlab bench``:
``sandboxes_realtime_per_core``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def clamp(x: np.ndarray, lower: np.ndarray | float, upper: np.ndarray | float) -> np.ndarray:
    """``np.clip(x, lower, upper)`` (a new array; NaN stays NaN) with two ufunc calls
    instead of clip's slower wrapper."""
    return np.minimum(np.maximum(x, lower), upper)


def all_finite(*arrays: np.ndarray) -> bool:
    """``all(np.isfinite(a).all() for a in arrays)`` for 1-D float arrays: True when no entry
    is NaN or ±inf (:func:`finite` of their entries)."""
    return finite([v for a in arrays for v in a.tolist()])


def finite(values: list[float]) -> bool:
    """True when no float of ``values`` is NaN or ±inf (``all(map(math.isfinite, values))``):
    one sum decides when it is finite (a NaN or inf entry makes it NaN or inf); only a sum
    that overflowed is checked entry by entry."""
    return math.isfinite(sum(values)) or all(map(math.isfinite, values))


def cross3(a: Sequence[float], b: Sequence[float]) -> list[float]:
    """``np.cross(a, b)`` of two 3-vectors, on floats: the same three differences of
    products as numpy's (so equal to the last bit), without its per-call overhead."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return [a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0]
