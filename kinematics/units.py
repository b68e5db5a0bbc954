"""Unit conversions: SI inside, degrees / cm / kgf·cm at the edges (UI, tables)."""

from __future__ import annotations

import numpy as np

G0 = 9.80665  #: standard gravity, m/s^2 (1 kgf = G0 N)
KGF_CM_PER_NM = 100.0 / G0  #: 1 N·m = 10.197 kgf·cm


def deg(rad: float | np.ndarray) -> float | np.ndarray:
    """rad -> degrees."""
    return np.degrees(rad)


def rad(degrees: float | np.ndarray) -> float | np.ndarray:
    """degrees -> rad."""
    return np.radians(degrees)


def cm(m: float | np.ndarray) -> float | np.ndarray:
    """m -> cm."""
    return np.asarray(m) * 100.0


def m_from_cm(c: float | np.ndarray) -> float | np.ndarray:
    """cm -> m."""
    return np.asarray(c) / 100.0


def kgf_cm(nm: float | np.ndarray) -> float | np.ndarray:
    """N·m -> kgf·cm (the thesis's torque unit; RX-24F stall 26 kgf·cm ≈ 2.55 N·m)."""
    return np.asarray(nm) * KGF_CM_PER_NM


def nm_from_kgf_cm(t: float | np.ndarray) -> float | np.ndarray:
    """kgf·cm -> N·m."""
    return np.asarray(t) / KGF_CM_PER_NM
