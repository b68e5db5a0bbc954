"""Argument checks shared by the kinematics functions (and the layers above).

Every public function that takes arrays from a caller runs them through
:func:`vector` or :func:`matrix`, and every parameter set its numbers through
:func:`scalar`, so a wrongly shaped, non-finite or out-of-sign input raises
``ValueError`` naming the argument instead of producing NaN further down.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from armlab.kinematics.smallarrays import finite


def vector(name: str, value: object, size: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite float64 vector of ``size`` elements.

    Raises:
        ValueError: naming ``name`` when the shape is wrong or an entry is NaN/inf.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of numbers ({exc})") from None
    if arr.ndim != 1 or (size is not None and arr.shape[0] != size):
        want = f"({size},)" if size is not None else "a 1-D array"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def floats(name: str, value: object, size: int) -> list[float]:
    """:func:`vector` for the hot paths: ``value`` as a list of ``size`` finite floats,
    without building an array (a generated-code call takes lists).

    Raises:
        ValueError: as :func:`vector` does, naming ``name``.
    """
    try:
        if isinstance(value, np.ndarray) and value.dtype == np.float64 and value.ndim == 1:
            vals = value.tolist()  # Python floats at once (iterating makes numpy scalars)
        else:
            vals = [float(v) for v in value]  # type: ignore[attr-defined]  # any object: a TypeError is caught and said
    except (TypeError, ValueError):
        vals = []
    if len(vals) != size or not finite(vals):
        vector(name, value, size)  # raises with the clear message
        raise ValueError(f"{name} must be {size} finite numbers")
    return vals


def matrix(name: str, value: object, shape: tuple[int, int]) -> np.ndarray:
    """Return ``value`` as a finite float64 matrix of ``shape``; ValueError otherwise."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of numbers ({exc})") from None
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def scalar(name: str, value: object, *, positive: bool = False,
           nonnegative: bool = False) -> float:
    """Return ``value`` as a finite float (> 0 or >= 0 if asked); ValueError otherwise."""
    try:
        x = float(value)  # type: ignore[arg-type]  # any object: a TypeError is caught and said
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x}")
    if positive and x <= 0.0:
        raise ValueError(f"{name} must be > 0, got {x}")
    if nonnegative and x < 0.0:
        raise ValueError(f"{name} must be >= 0, got {x}")
    return x


def index(name: str, value: object, size: int) -> int:
    """Return ``value`` as an index 0..size-1 (an int, not a bool); ValueError otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not (
            0 <= int(value) < size):
        raise ValueError(f"{name} must be an index 0..{size - 1}, got {value!r}")
    return int(value)


def joint_index(value: object, names: Sequence[str]) -> int:
    """A joint named by its index (0..n-1, also as text: "1") or by its name ("joint2") ->
    its index; ValueError listing both forms otherwise."""
    text = str(value).strip()
    if text in names:
        return list(names).index(text)
    try:
        k = int(text)
    except ValueError:
        k = -1
    if 0 <= k < len(names) and not isinstance(value, bool):
        return k
    shown = repr(value) if len(text) <= 40 else repr(text[:40]) + "…"  # not a page of it
    raise ValueError(f"joint must be an index 0..{len(names) - 1} or one of "
                     f"{', '.join(names)}; got {shown}")


def check_number(value: object, *, name: str, lo: float, hi: float) -> float:
    """``value`` as a float in [lo, hi] (what a person typed, a file held).

    Raises:
        ValueError: naming ``name`` when ``value`` is not a finite number in range.
    """
    try:
        v = float(value)  # type: ignore[arg-type]  # any object: a TypeError is caught and said
    except (TypeError, ValueError):
        raise ValueError(f"{name}: {value!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: {value!r} is not a finite number")
    if not lo <= v <= hi:
        raise ValueError(f"{name}: {v:g} is outside [{lo:g}, {hi:g}]")
    return v
