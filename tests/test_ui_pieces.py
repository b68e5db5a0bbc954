"""The lab's pure pieces: chart decimation, input checks, the teaching panel's numbers."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from armlab.app.lessons.compliance_servos import ServoHealth, advice
from armlab.app.lessons.compliance_teach import (
    STALE,
    Chapter4,
    LiveValues,
    chapter4_markdown,
    design_table,
    equations_markdown,
    people,
    thesis_preset_note,
)
from armlab.app.page.inputs import check_number
from armlab.app.page.plots import decimate, fill_gaps
from armlab.control import metrics
from armlab.control.metrics import omega_from_peak, zeta_from_overshoot
from armlab.control.params import PRESETS, Params
from armlab.control.response import Measured, measure_response
from armlab.hardware.families.dynamixel1.packets import error_names


def test_decimate_keeps_the_window_and_a_few_hundred_points():
    t = np.arange(0.0, 30.0, 0.016)
    y = np.sin(t)
    tt, (yy,) = decimate(t, [y], window_s=10.0, points=128)
    assert len(tt) <= 130
    assert tt[-1] == t[-1] and tt[0] == pytest.approx(t[-1] - 10.0)  # exactly the window
    assert np.allclose(yy[1:], np.sin(tt[1:])) and yy[0] == yy[1]  # samples, not averages
    # Bins are aligned to t = 0: one more sample picks the same earlier points.
    tt2, _ = decimate(t[:-1], [y[:-1]], window_s=10.0, points=128)
    shared = np.intersect1d(tt, tt2)
    assert len(shared) >= len(tt) - 3


def test_decimate_pads_a_short_record_to_the_full_window():
    t = np.arange(0.0, 1.4, 0.016)
    tt, (yy,) = decimate(t, [t * 2], window_s=10.0, points=128)
    assert tt[-1] - tt[0] == pytest.approx(10.0)
    assert yy[0] == yy[1] and tt[1] < 0.1  # the pad repeats the oldest kept value


def test_fill_gaps_leaves_no_nan_for_the_chart():
    a = np.array([np.nan, 1.0, np.nan, 3.0])
    b = np.full(4, np.nan)
    c = np.array([5.0, 6.0, 7.0, 8.0])
    fa, fb, fc = fill_gaps([a, b, c])
    assert fa.tolist() == [1.0, 1.0, 1.0, 3.0]
    assert np.all(np.isfinite(fb)) and fc.tolist() == c.tolist()


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -1e-9, 200.0001, "x", None])
def test_check_number_refuses_bad_values_naming_the_input(value):
    with pytest.raises(ValueError, match="Kp"):
        check_number(value, name="Kp", lo=0.0, hi=200.0)


def test_check_number_accepts_the_range_ends():
    assert check_number("3.8", name="Kp", lo=0.0, hi=200.0) == 3.8
    assert check_number(200, name="Kp", lo=0.0, hi=200.0) == 200.0


@pytest.mark.parametrize("zeta", [0.05, 0.3, 0.59, 0.83])
def test_zeta_and_omega_read_back_from_overshoot_and_peak(zeta):
    wn = 4.47
    os_pct = metrics.overshoot_pct(zeta)
    tp = metrics.peak_time(wn, zeta)
    assert zeta_from_overshoot(os_pct) == pytest.approx(zeta, rel=1e-9)
    assert omega_from_peak(tp, zeta) == pytest.approx(wn, rel=1e-9)


def test_measure_response_of_an_exact_second_order_step():
    wn, zeta = 3.0, 0.4
    t = np.arange(0.0, 12.0, 0.001)
    wd = wn * math.sqrt(1 - zeta**2)
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2)
                                      * np.sin(wd * t))
    m = measure_response(t, 2.0 + 10.0 * y, initial=2.0, final=12.0, what="test")
    assert m.zeta == pytest.approx(zeta, rel=0.01)
    assert m.omega_n == pytest.approx(wn, rel=0.01)
    assert m.overshoot_pct == pytest.approx(metrics.overshoot_pct(zeta), rel=0.01)
    with pytest.raises(ValueError, match="did not move"):
        measure_response(t, np.zeros_like(t), initial=1.0, final=1.0, what="flat")


def test_design_table_shows_the_thesis_table_4_1_figures():
    text = design_table(PRESETS["thesis Table 4.1"], None, None)
    # ωp = √3.8 = 1.95 rad/s, ζp = 0.2/(2√3.8) = 0.0513, %OS = 85 %;
    # ωf = √(12/1) = 3.46, ζf = 5/(2√12) = 0.722, C_f = 0.3/12 = 0.025.
    for figure in ("1.95 rad/s", "0.0513", "85 %", "3.46 rad/s", "0.722", "0.025 rad/N·m"):
        assert figure in text, figure
    assert "Press **Step**" in text


def test_equations_show_live_numbers_in_degrees_and_the_law_in_use():
    live = LiveValues("θ2", q_cmd=math.radians(30.0), q=math.radians(28.0),
                      q_env=math.radians(-1.0), tau_load=0.5, tau_dyn=0.6, tau_ext=-0.1)
    p = Params()
    md = equations_markdown(p, live, torque_unit="kgf·cm")
    assert "law 2.6" in md and "30.00°" in md and "28.00°" in md and "− (−1.00°)" in md
    assert "− -" not in md and "− +" not in md  # (a negative subtrahend in brackets)
    assert "-1.02 kgf·cm" in md  # τ_ext = −0.1 N·m
    pd = equations_markdown(Params(compliance=False), live)
    assert "PD reference loop (2.20)" in pd and "θ_env" not in pd.split("External")[0]
    literal = equations_markdown(PRESETS["thesis Table 4.1"], live)
    assert "2.26 (thesis literal)" in literal and "K_env θ_env" in literal
    # the default's feed-forward is written into the law; the thesis preset has none
    assert "+ θ̈_cmd  (feed-forward: not in the thesis)" in md
    assert "feed-forward" not in literal


def test_servo_advice_names_the_fault_and_what_to_do():
    h = ServoHealth(5, "theta2", 8.1, 72.0, (1 << 5) | (1 << 2), True)
    assert error_names(h.error) == "overheating, overload"
    tips = " ".join(advice(h))
    assert "free it, then press Reset" in tips and "8.1 V" in tips and "72 °C" in tips
    assert advice(ServoHealth(1, "theta1", 12.0, 35.0, 0, True)) == []


def test_chapter4_panel_names_each_figure_for_what_it_is():
    ch4 = Chapter4(free=np.array([1.0, 0.0, 2.7]), pushed=np.array([4.7, 0.0, 16.2]),
                   yield_deg=np.array([7.3, 0.0, 11.4]))
    text = chapter4_markdown(ch4, ("θ1", "θ0", "θ2"))
    lines = text.splitlines()
    assert "free: θ1 1.0°, θ0 0.0°, θ2 2.7°" in lines[1]
    assert "θ2 16.2°" in lines[2] and "over 15° on servo 3" in lines[2]
    assert "θ2 11.4°" in lines[3] and "different quantity" in lines[3]
    assert chapter4_markdown(Chapter4(), ("a", "b", "c")).count("—") == 3


def test_a_thesis_preset_says_chapter_4_does_not_reproduce():
    for name, lag in (("thesis Table 4.1", "Kv 0.2 make the PD loop lag 19.5°"),
                      ("thesis conclusion", "Kv 0.02 make the PD loop lag 21.1°")):
        note = thesis_preset_note(PRESETS[name])
        assert note.startswith(f"**{name}: chapter 4 does not reproduce here.**")
        assert lag in note and "thesis-readings" in note
    assert thesis_preset_note(PRESETS["well-damped default"]) == ""
    assert thesis_preset_note(Params(kp=3.8, kv=0.2)) == ""  # custom gains: no note


def _decimate_by_masks(t, ys, window_s, points):
    """decimate spelled as masks over every series (how it was first written)."""
    start = t[-1] - window_s
    keep = t > start
    t, ys = t[keep], [y[keep] for y in ys]
    bins = np.floor(t / (window_s / points))
    last = np.append(bins[1:] != bins[:-1], True)
    t, ys = t[last], [y[last] for y in ys]
    return np.concatenate([[start], t]), [np.concatenate([y[:1], y]) for y in ys]


def test_a_shared_decimation_keeps_what_masks_over_each_series_keep():
    """Charts of one record share one decimation (armlab.app.lessons.compliance_plots): its
    samples are those of masks over each series, for windows that start before, at and
    inside the record."""
    from armlab.app.page.plots import decimation

    rng = np.random.default_rng(4)
    for n, window in ((1, 10.0), (2, 10.0), (400, 3.0), (657, 10.0), (2000, 10.0)):
        t = np.cumsum(rng.uniform(0.005, 0.03, n))
        ys = [rng.normal(size=n), rng.normal(size=n)]
        ref = _decimate_by_masks(t, ys, window, 100)
        for got in (decimate(t, ys, window_s=window, points=100),
                    decimate(t, ys, window_s=window, points=100,
                             index=decimation(t, window_s=window, points=100))):
            np.testing.assert_array_equal(got[0], ref[0])
            for a, b in zip(got[1], ref[1], strict=True):
                np.testing.assert_array_equal(a, b)


def test_numbers_are_written_for_people():
    assert [people(x, 2) for x in (100.0, 99.96, 85.08, 4.283, 0.25, 1e-5)] == [
        "100", "100", "85", "4.3", "0.25", "1.0e-05"]
    assert people(2.8601, 3) == "2.86" and people(-20.0, 3) == "-20" and people(0.0) == "0"


def _measured(params: Params, *, ts: float = 1.0, band: float = math.radians(0.2)) -> Measured:
    return Measured("step of θ2 by +10°", 2.0, 0.5, 99.96, 1.2, 0.5, ts, params=params,
                    band=band)


def test_a_measured_figure_is_marked_stale_when_its_gains_change():
    p = Params()
    fresh = design_table(p, _measured(p), None)
    assert STALE not in fresh and "%OS" in fresh and "| 100 % |" in fresh  # not "1e+02 %"
    later = replace(p, kp=30.0)
    stale = design_table(later, _measured(p), None)
    assert f"{STALE} old gains" in stale and f"| 100 % {STALE} |" in stale
    assert f"{STALE} Measured with Kp 20, not the gains in use: press **Step** again" in stale
    # the environment's gains do not make a PD step stale, nor the PD's a push
    assert STALE not in design_table(replace(p, k_env=30.0), _measured(p), None)
    env = design_table(replace(p, k_env=30.0), None, _measured(p))
    assert f"{STALE} Measured with K_env 16" in env and "press **Push** again" in env
    period = design_table(replace(p, period=0.008), _measured(p), None)
    assert "Measured with T 16 ms" in period


def test_a_long_measured_settling_time_names_its_band_and_the_servo_step():
    p = Params()
    design_ts = metrics.formula_metrics(metrics.pd_natural_frequency(p.kp),
                                        metrics.pd_damping(p.kp, p.kv)).settling_time_s
    long = design_table(p, _measured(p, ts=2.0 * design_ts), None, servo_step_deg=0.293)
    assert ("Ts is the time θ stays within 2 % of the step (±0.2°, less than the servo's "
            "0.29° position step") in long
    assert "Ts is the time" not in design_table(p, _measured(p, ts=design_ts), None,
                                                servo_step_deg=0.293)


def test_one_name_per_quantity_in_the_design_table():
    text = design_table(Params(), None, None)
    pd, env = text.split("**environment**")
    assert "ωn" not in text and "ζ²" not in text
    assert "ωp" in pd and "ωf" not in pd and "ωf" in env and "ωp" not in env
