"""``armlab experiment thesis-line`` and ``step`` through the real command line."""

import dataclasses
import io
import json
from contextlib import redirect_stderr, redirect_stdout

import pytest

from app.cli import build_parser, main
from app.commands.experiment import options_of
from control.experiments import all_experiments


def run_json(capsys, *argv: str) -> dict:
    assert main(["experiment", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def line_runs():
    """One free and one pushed run per controller (the default preset), via the CLI."""
    out = {}
    for c in ("none", "pd", "compliance"):
        buf = io.StringIO()
        with redirect_stdout(buf):
            assert main(["experiment", "thesis-line", "--controller", c, "--push", "3",
                         "--json"]) == 0
        out[c] = json.loads(buf.getvalue())
    return out


def test_thesis_line_prints_the_public_keys(line_runs):
    r = line_runs["compliance"]
    assert list(r) == ["controller", "max_angle_error_deg", "torque_error_max_nm",
                       "max_yield_deg"]
    assert r["controller"] == "compliance"
    assert all(len(r[k]) == 3 for k in list(r)[1:])


def test_pd_tracks_the_line_better_than_no_controller(line_runs):
    none, pd = line_runs["none"], line_runs["pd"]
    assert max(pd["max_angle_error_deg"]) < max(none["max_angle_error_deg"])
    # the shoulder carries the gravity the servo alone droops under; PD removes it
    assert pd["max_angle_error_deg"][0] < 0.5 * none["max_angle_error_deg"][0]


def test_compliance_yields_more_under_the_same_push(line_runs):
    pd, comp = line_runs["pd"], line_runs["compliance"]
    assert max(comp["max_yield_deg"]) > 1.5 * max(pd["max_yield_deg"])
    for j in (0, 2):  # the joints the push turns
        assert comp["max_yield_deg"][j] > pd["max_yield_deg"][j]


def test_free_motion_torque_error_is_the_size_the_thesis_saw(line_runs):
    # thesis fig. 4.6: servo load after the LPF vs Newton–Euler, up to about 1.5 kgf·cm
    worst = max(line_runs["compliance"]["torque_error_max_nm"])
    assert 0.02 < worst < 0.5


def test_step_formula_and_measured_side_by_side(capsys):
    r = run_json(capsys, "step", "--kp", "3.8", "--kv", "0.2")
    for part in ("formula", "measured", "measured_eq_2_3"):
        assert set(r[part]) == {"overshoot_pct", "peak_time_s", "rise_time_s",
                                "settling_time_s"}
    assert r["measured"]["overshoot_pct"] == pytest.approx(r["formula"]["overshoot_pct"],
                                                           rel=0.02)
    assert r["measured"]["peak_time_s"] == pytest.approx(r["formula"]["peak_time_s"], rel=0.02)
    assert r["formula"]["overshoot_pct"] == pytest.approx(85.1, abs=0.1)


def test_bad_options_give_one_line(capsys):
    assert main(["experiment", "thesis-line", "--preset", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("armlab experiment: unknown preset 'nope'") and err.count("\n") == 1
    assert main(["experiment", "thesis-line", "--port", "/dev/null"]) == 2
    assert "--port and --baud are for --backend serial" in capsys.readouterr().err


@pytest.mark.parametrize("name", sorted(all_experiments()))
def test_each_experiments_typed_options_are_its_command_line(name):
    """The CLI's options are the experiment's dataclass fields: its defaults when none is
    given, and a typed value (kebab-case flag, converted by the field's type) when given."""
    exp = all_experiments()[name]
    parser = build_parser(["experiment", name])
    assert options_of(exp, parser.parse_args(["experiment", name])) == exp.options()
    for f in dataclasses.fields(exp.options):
        assert f.metadata["help"], f.name
    if name == "seed003-gait":
        args = parser.parse_args(["experiment", name, "--A", "3", "--right-direction", "1",
                                  "--gait", "crawl"])
        assert options_of(exp, args) == exp.options(A=3.0, right_direction=1, gait="crawl")
    if name == "thesis-line":
        args = parser.parse_args(["experiment", name, "--law", "2.26", "--push", "0"])
        assert options_of(exp, args) == exp.options(law="2.26", push=0.0)
        with pytest.raises(SystemExit), redirect_stderr(io.StringIO()):
            parser.parse_args(["experiment", name, "--controller", "fast"])
