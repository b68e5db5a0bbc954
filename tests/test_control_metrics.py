"""Design formulas 2.11–2.19 against steps measured on the sampled PD loop."""

import math

import numpy as np
import pytest
from scipy import signal

from armlab.control import metrics
from armlab.control.response import simulate_ideal_joint_step, step_report


def test_formulas_with_the_thesis_gains():
    wn, z = metrics.pd_natural_frequency(3.8), metrics.pd_damping(3.8, 0.2)
    assert wn == pytest.approx(1.9494, abs=1e-4)
    assert z == pytest.approx(0.05130, abs=1e-5)
    # eq. 2.17 with the sign fixed: a lightly damped loop overshoots by 85 %, not e^+0.16
    assert metrics.overshoot_pct(z) == pytest.approx(85.10, abs=0.01)
    assert metrics.peak_time(wn, z) == pytest.approx(math.pi / (wn * math.sqrt(1 - z * z)))
    assert metrics.settling_time(wn, z) == pytest.approx(40.0, rel=1e-9)
    assert metrics.rise_time(wn) == pytest.approx(1.8 / wn)
    # Table 4.1 environment: ωf = √12, ζf = 5/(2√12), C_f = 0.3/12
    assert metrics.env_natural_frequency(1.0, 12.0) == pytest.approx(3.4641, abs=1e-4)
    assert metrics.env_damping(1.0, 5.0, 12.0) == pytest.approx(0.7217, abs=1e-4)
    assert metrics.static_gain(0.3, 12.0) == pytest.approx(0.025)


@pytest.mark.parametrize("kp,kv", [(3.8, 0.2), (25.0, 5.0), (36.0, 3.0)])
def test_ideal_joint_step_matches_2_16_and_2_17_within_2_percent(kp, kv):
    t, y = simulate_ideal_joint_step(kp, kv, period=1e-3, duration=20.0)
    m = metrics.measure_step(t, y)
    f = metrics.formula_metrics(metrics.pd_natural_frequency(kp), metrics.pd_damping(kp, kv))
    assert m.peak_time_s == pytest.approx(f.peak_time_s, rel=0.02)
    assert m.overshoot_pct == pytest.approx(f.overshoot_pct, rel=0.02)


def test_the_zero_of_eq_2_3_adds_overshoot_and_peaks_earlier():
    rep = step_report(25.0, 5.0)
    assert rep["measured_eq_2_3"]["overshoot_pct"] > rep["measured"]["overshoot_pct"] + 5
    assert rep["measured_eq_2_3"]["peak_time_s"] < rep["measured"]["peak_time_s"]


def test_measure_step_on_a_known_response():
    # first-order 1 - e^{-t}: no overshoot, rise 10-90 % = ln 9, 2 % settling = ln 50
    t = np.linspace(0, 10, 100001)
    m = metrics.measure_step(t, 1 - np.exp(-t))
    assert m.overshoot_pct == 0 and m.peak_time_s is None
    assert m.rise_time_s == pytest.approx(math.log(9), abs=1e-3)
    assert m.settling_time_s == pytest.approx(math.log(50), abs=1e-3)


def test_measured_second_order_matches_scipy_step():
    t, y = simulate_ideal_joint_step(25.0, 5.0, period=1e-3, duration=4.0)
    _, ys = signal.step(metrics.pure_second_order(25.0, 5.0), T=t)
    assert np.max(np.abs(y - ys)) < 0.01


def test_step_report_refuses_kv_zero():
    with pytest.raises(ValueError, match="kv"):
        step_report(3.8, 0.0)
