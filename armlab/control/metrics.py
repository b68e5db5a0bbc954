"""Second-order design formulas (thesis eq. 2.11–2.19) and the same metrics measured.

The thesis designs the PD loop and the virtual environment with the classic
second-order formulas. Two cautions a student should see side by side:

* eq. 2.17 lost its minus sign: %OS = exp(−ζπ/√(1−ζ²))·100;
* the PD reference model (2.3) has a zero, (Kv s + Kp)/(s² + Kv s + Kp), so its
  step overshoots more and peaks earlier than the pure second-order part
  Kp/(s² + Kv s + Kp) the formulas describe (a step of θ_cmd with θ̇_cmd = 0
  on the sampled loop gives the pure part).

Eq. 2.19 (Tr = 1.8/ωn) is the usual 10–90 % rise-time fit near ζ = 0.5; the
measured 10–90 % rise differs for other damping ratios.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # scipy.signal is imported where it is used: it costs every start 0.3 s
    from scipy import signal


def pd_natural_frequency(kp: float) -> float:
    """Thesis eq. 2.11: ωp = √Kp, rad/s."""
    return math.sqrt(kp)


def pd_damping(kp: float, kv: float) -> float:
    """Thesis eq. 2.12: ζp = Kv / (2√Kp)."""
    return kv / (2.0 * math.sqrt(kp))


def env_natural_frequency(m_env: float, k_env: float) -> float:
    """Thesis eq. 2.13 (its "W_env" is M_env): ωf = √(K_env / M_env), rad/s."""
    return math.sqrt(k_env / m_env)


def env_damping(m_env: float, d_env: float, k_env: float) -> float:
    """Thesis eq. 2.14: ζf = D_env / (2√(M_env K_env))."""
    return d_env / (2.0 * math.sqrt(m_env * k_env))


def static_gain(k_f: float, k_env: float) -> float:
    """Thesis eq. 2.15 (garbled in print): C_f = K_f / K_env, rad per N·m (law 2.6)."""
    return k_f / k_env


def peak_time(omega_n: float, zeta: float) -> float:
    """Thesis eq. 2.16: Tp = π / (ωn √(1 − ζ²)), s; inf when ζ >= 1 (no peak)."""
    if zeta >= 1.0:
        return math.inf
    return math.pi / (omega_n * math.sqrt(1.0 - zeta * zeta))


def overshoot_pct(zeta: float) -> float:
    """Thesis eq. 2.17 with its sign fixed: %OS = exp(−ζπ/√(1 − ζ²)) · 100; 0 when ζ >= 1."""
    if zeta >= 1.0:
        return 0.0
    return 100.0 * math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta))


def zeta_from_overshoot(os_pct: float) -> float | None:
    """ζ from %OS (inverse of eq. 2.17): ζ = −ln(OS) / √(π² + ln²(OS)); None without overshoot."""
    if not (os_pct > 0.0 and math.isfinite(os_pct)):
        return None
    ln = math.log(os_pct / 100.0)
    return -ln / math.sqrt(math.pi**2 + ln * ln)


def omega_from_peak(tp: float | None, zeta: float | None) -> float | None:
    """ωn from Tp and ζ (inverse of eq. 2.16): ωn = π / (Tp √(1 − ζ²))."""
    if tp is None or zeta is None or tp <= 0.0 or zeta >= 1.0:
        return None
    return math.pi / (tp * math.sqrt(1.0 - zeta * zeta))


def settling_time(omega_n: float, zeta: float) -> float:
    """Thesis eq. 2.18: Ts = 4 / (ζ ωn), s (2 % envelope); inf when ζ = 0."""
    return math.inf if zeta <= 0.0 else 4.0 / (zeta * omega_n)


def rise_time(omega_n: float) -> float:
    """Thesis eq. 2.19: Tr = 1.8 / ωn, s."""
    return 1.8 / omega_n


@dataclass(frozen=True)
class StepMetrics:
    """Step-response figures (None where undefined: no peak, never settles)."""

    overshoot_pct: float
    peak_time_s: float | None
    rise_time_s: float | None
    settling_time_s: float | None

    def as_dict(self) -> dict[str, float | None]:
        return asdict(self)


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def formula_metrics(omega_n: float, zeta: float) -> StepMetrics:
    """Eq. 2.16–2.19 for a second-order system of ωn (rad/s) and ζ."""
    return StepMetrics(overshoot_pct(zeta), _finite(peak_time(omega_n, zeta)),
                       _finite(rise_time(omega_n)), _finite(settling_time(omega_n, zeta)))


def measure_step(t: np.ndarray, y: np.ndarray, *, final: float = 1.0,
                 initial: float = 0.0, band: float = 0.02) -> StepMetrics:
    """Overshoot, peak time, 10–90 % rise time and 2 % settling time of a step response.

    Args:
        t: (N,) times, s, starting at the step.
        y: (N,) response.
        final, initial: the values the step goes to and from.
        band: settling band as a fraction of the step (0.02 = 2 %).
    """
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    span = final - initial
    x = (y - initial) / span
    k = int(np.argmax(x))
    os_pct = max(0.0, (x[k] - 1.0) * 100.0)
    peak = float(t[k]) if x[k] > 1.0 and k < len(x) - 1 else None
    i10 = np.flatnonzero(x >= 0.1)
    i90 = np.flatnonzero(x >= 0.9)
    rise = _crossing(t, x, i10[0], 0.1) if len(i10) and len(i90) else None
    if rise is not None:
        rise = _crossing(t, x, i90[0], 0.9) - rise
    outside = np.flatnonzero(np.abs(x - 1.0) > band)
    if len(outside) == 0:
        settle: float | None = float(t[0])
    elif outside[-1] >= len(x) - 1:
        settle = None
    else:
        settle = float(t[outside[-1] + 1])
    return StepMetrics(os_pct, peak, rise, settle)


def _crossing(t: np.ndarray, x: np.ndarray, i: int, level: float) -> float:
    """Time at which x crosses ``level`` between samples i−1 and i (linear interpolation)."""
    if i == 0 or x[i] == x[i - 1]:
        return float(t[i])
    f = (level - x[i - 1]) / (x[i] - x[i - 1])
    return float(t[i - 1] + f * (t[i] - t[i - 1]))


def pd_reference_model(kp: float, kv: float) -> signal.TransferFunction:
    """Thesis eq. 2.3: (Kv s + Kp) / (s² + Kv s + Kp), with its zero."""
    from scipy import signal

    return signal.TransferFunction([kv, kp], [1.0, kv, kp])


def pure_second_order(kp: float, kv: float) -> signal.TransferFunction:
    """The pure second-order part of 2.3: Kp / (s² + Kv s + Kp) (what 2.16–2.19 describe)."""
    from scipy import signal

    return signal.TransferFunction([kp], [1.0, kv, kp])


def environment_model(m_env: float, d_env: float, k_env: float,
                      k_f: float) -> signal.TransferFunction:
    """Thesis eq. 2.7: θ_env / τ_ext = K_f / (M_env s² + D_env s + K_env)."""
    from scipy import signal

    return signal.TransferFunction([k_f], [m_env, d_env, k_env])


def step_duration(kp: float, kv: float) -> float:
    """A simulation length that covers settling: 3 × Ts (or 10 periods), 5..600 s."""
    wn, z = pd_natural_frequency(kp), pd_damping(kp, kv)
    ts = settling_time(wn, z)
    guess = 3.0 * ts if math.isfinite(ts) else 600.0
    return float(min(600.0, max(5.0, guess, 10.0 * 2.0 * math.pi / wn)))
