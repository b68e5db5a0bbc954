"""Controller parameters: presets from the thesis, validation, the stability check."""

import dataclasses
import math

import pytest

from armlab.control.params import (
    PARAM_SPECS,
    PRESETS,
    Params,
    check_gains,
    loop_stability,
    preset,
)


def warning_of(p: Params) -> str | None:
    """What the rule on gains says of ``p`` on a simulated arm (which takes any gains)."""
    return check_gains(p, servos=False).warning


def test_thesis_presets_carry_the_thesis_numbers():
    t41 = preset("thesis Table 4.1")
    assert (t41.kp, t41.kv, t41.k_f, t41.k_env, t41.d_env, t41.m_env) == (3.8, 0.2, 0.3, 12, 5, 1)
    con = preset("thesis conclusion")
    assert (con.kp, con.kv, con.k_f, con.k_env, con.d_env, con.m_env) == (3.8, 0.02, 0.2, 9, 5, 9)
    assert t41.alpha == 0.05 and t41.period == 0.016


def test_every_preset_fits_the_slider_ranges_and_is_stable():
    for name, p in PRESETS.items():
        for field, spec in PARAM_SPECS.items():
            assert spec.min <= getattr(p, field) <= spec.max, (name, field)
        assert not loop_stability(p).unstable, name


def test_default_is_well_damped_and_thesis_table_is_not():
    assert warning_of(preset("well-damped default")) is None
    warn = warning_of(preset("thesis Table 4.1"))
    assert warn is not None and "badly damped" in warn and "0.05" in warn  # ζp = 0.2/(2√3.8)


@pytest.mark.parametrize("field,value,words", [
    ("kp", math.nan, "kp must be finite"),
    ("kv", math.inf, "kv must be finite"),
    ("m_env", 0.0, "m_env must be > 0"),
    ("m_env", -1.0, "m_env must be > 0"),
    ("period", 0.1, "period must be in"),
    ("period", 0.0005, "period must be in"),
    ("alpha", 0.0, "alpha must be in"),
    ("law", "2.7", "law must be one of"),
])
def test_bad_values_are_refused_naming_the_field(field, value, words):
    with pytest.raises(ValueError, match=words):
        Params(**{field: value})


def test_params_are_frozen_and_replace_validates():
    p = Params()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.kp = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="kv"):
        dataclasses.replace(p, kv=-1.0)


def test_gains_that_diverge_at_the_period_are_reported_unstable():
    # Kv·T > 2 makes the sampled loop diverge (semi-implicit Euler): 50 · 0.05 = 2.5
    p = Params(kp=10.0, kv=50.0, period=0.05)
    assert loop_stability(p).unstable
    assert "diverges" in warning_of(p)
    # the same gains at 16 ms converge
    assert not loop_stability(Params(kp=10.0, kv=50.0, period=0.016)).unstable


def test_the_rule_refuses_unstable_gains_on_servos_only_and_says_why():
    p = Params(kp=10.0, kv=50.0, period=0.05)  # Kv·T = 2.5: diverges
    with pytest.raises(ValueError, match=r"^unstable gains are refused on real servos: "
                                         r"the PD loop diverges at T = 50 ms"):
        check_gains(p, servos=True)
    taken = check_gains(p, servos=False)  # a simulated arm takes them, to be seen failing
    assert taken.unstable and taken.params is p
    assert taken.warning.startswith("the PD loop diverges")
    # badly damped but convergent gains are taken on servos too, with their warning
    t41 = check_gains(preset("thesis Table 4.1"), servos=True)
    assert not t41.unstable and "badly damped" in t41.warning
    with pytest.raises(ValueError, match="params must be a armlab.control.params.Params"):
        check_gains({"kp": 1.0}, servos=False)  # type: ignore[arg-type]


def test_too_fast_for_the_period_is_flagged():
    p = Params(kp=200.0, kv=20.0, period=0.05)
    warn = warning_of(p)
    # the sampled loop converges (pole radius 0.5) but gets under 10 samples per period
    assert not loop_stability(p).unstable
    assert warn is not None and warn.startswith("too fast for the period: ωp·T = 0.69")
    # and closed through the servos' own lag it grows (ζ = -0.46 at 15.9 rad/s)
    assert "likely unstable on the servos" in warn and "15.9 rad/s" in warn


def test_a_diverging_loop_is_told_its_cause_and_a_fix_that_settles():
    """Kp 200, Kv 0 at 16 ms: nothing damps the loop (pole radius 1, not "lower Kv"); the
    fix named is one that settles, through the servos' lag too; Kv·T too large is told to
    lower Kv."""
    import re

    from armlab.control.params import _settles

    said = warning_of(Params(kp=200.0, kv=0.0, period=0.016))
    assert said.startswith("the PD loop diverges at T = 16 ms (Kv = 0: nothing damps it")
    assert "unstable" not in said and "lower Kp or Kv" not in said
    kp, kv = map(float, re.search(r"lower Kp to about ([\d.]+) with Kv about ([\d.]+)",
                                  said).groups())
    assert _settles(kp, kv, 0.016) and check_gains(Params(kp=kp, kv=kv, period=0.016),
                                                   servos=True).warning is None
    said = warning_of(Params(kp=10.0, kv=50.0, period=0.05))
    kv = float(re.search(r"lower Kv to about ([\d.]+)", said).group(1))
    assert _settles(10.0, kv, 0.05)
