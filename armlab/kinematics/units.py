"""Unit conversions: SI inside, degrees and kgf·cm at the edges (UI, tables)."""

from __future__ import annotations

from typing import overload

import numpy as np

G0 = 9.80665  #: standard gravity, m/s^2 (1 kgf = G0 N)
KGF_CM_PER_NM = 100.0 / G0  #: 1 N·m = 10.197 kgf·cm


@overload
def deg(rad: float) -> float: ...
@overload
def deg(rad: np.ndarray) -> np.ndarray: ...
def deg(rad: float | np.ndarray) -> float | np.ndarray:
    """rad -> degrees."""
    return np.degrees(rad)
