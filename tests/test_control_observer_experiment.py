"""``armlab experiment observers``: both observers follow the truth; feeding back helps."""

import json

import pytest

from armlab.app.commands.cli import main
from armlab.control.experiments.observers import observers


@pytest.mark.parametrize("g", [100.0, 400.0])
def test_reaction_torque_observer_picks_up_a_step_in_about_one_over_g(g):
    fig, _ = observers(step=0.004, g_dis=g, g_reac=g)
    assert fig["rtob_rise_s"] == pytest.approx(1.0 / g, rel=0.15)
    # after five time constants both estimates sit on the truth (step is 4 mN·m)
    assert fig["dob_error_max_nm"] < 0.01 * 0.004
    assert fig["rtob_error_max_nm"] < 0.01 * 0.004


def test_feeding_the_disturbance_estimate_back_holds_the_joint():
    fig, _ = observers(step=0.004, model_error=0.3)  # nominal inertia 30 % off
    assert fig["offset_compensated_rad"] < fig["final_offset_rad"] / 10


def test_cli_prints_figures_and_series(capsys):
    assert main(["experiment", "observers", "--g-dis", "200", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["g_dis"] == 200.0 and len(out["series"]["t"]) > 50


@pytest.mark.parametrize("kw,name", [({"g_dis": 0.0}, "g_dis"), ({"step": float("nan")}, "step"),
                                     ({"at": 5.0}, "at")])
def test_bad_input_names_the_argument(kw, name):
    with pytest.raises(ValueError, match=name):
        observers(**kw)
