"""``armlab experiment contact-sweep``: the run into a wall at each wall stiffness and
control period, where its contact chatters, and one clear line for bad options."""

from __future__ import annotations

import re

import numpy as np
import pytest

from armlab.control.experiments.contact_sweep import (
    MAX_CELLS,
    SweepOptions,
    chatter_figures,
    numbers,
    run_sweep,
)
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend


def factory(model, q0):
    return SimBackend(model, q0=q0)


def test_a_hand_resting_on_the_wall_is_calm_and_one_striking_it_again_chatters():
    t = np.arange(0.0, 3.0, 0.016)
    rest = np.full_like(t, 2.0)
    assert chatter_figures(t, rest) == {"rests": True, "losses": 0, "ripple_n": 0.0}
    tapping = np.where((t * 10).astype(int) % 2 == 0, 3.0, 0.0)  # on, off, every 0.1 s
    found = chatter_figures(t, tapping)
    assert not found["rests"] and found["losses"] >= 4 and found["ripple_n"] == 3.0
    # before the last second it may bounce: only the last second counts
    settled = np.where(t < 1.5, tapping, 2.0)
    assert chatter_figures(t, settled)["rests"]


@pytest.mark.parametrize(("options", "message"), [
    (SweepOptions(stiffness="2e3,x"), "--stiffness: comma-separated numbers in N/m"),
    (SweepOptions(stiffness="2e3,2e3"), "--stiffness: each value once"),
    (SweepOptions(stiffness="nan"), "--stiffness: finite numbers"),
    (SweepOptions(stiffness="10"), "--stiffness must be in 100..1e+06"),
    (SweepOptions(periods_ms="0.1"), "--periods-ms must be in 1..50"),
    (SweepOptions(stiffness=",".join(str(1e3 + i) for i in range(MAX_CELLS)),
                  periods_ms="4,8"), f"at most {MAX_CELLS} runs"),
])
def test_a_bad_grid_is_refused_in_one_line_before_any_run(options, message):
    with pytest.raises(ValueError, match=re.escape(message)) as caught:
        run_sweep(options, backend_factory=factory)
    assert "\n" not in str(caught.value)


def test_numbers_reads_a_comma_list():
    assert numbers(" 2e3, 20000 ", name="--stiffness", unit="N/m") == (2000.0, 20000.0)


@pytest.mark.slow
def test_the_sweep_runs_each_cell_as_the_contact_experiment_and_names_the_calm_periods():
    from armlab.control.experiments.contact import run_contact
    from armlab.control.params import DEFAULT
    from armlab.kinematics.catalog import load_robot

    options = SweepOptions(stiffness="2e3,2e5", periods_ms="16")
    first = run_sweep(options, backend_factory=factory)
    again = run_sweep(options, backend_factory=factory)
    assert first == again  # the same grid, the same figures
    cells = first["rows"]
    assert [(c["stiffness_n_per_m"], c["period_ms"]) for c in cells] == [(2e3, 16.0),
                                                                         (2e5, 16.0)]
    # a cell is the contact experiment's run at that stiffness (its peak and steady force)
    one = run_contact(load_robot("receptionist_arm"), factory, DEFAULT, controller="compliance",
                      wall=0.04, depth=0.02, stiffness=2e5, damping=50.0)
    assert cells[1]["peak_force_n"] == one["peak_force_n"]
    assert cells[1]["steady_force_n"] == one["steady_force_n"]
    # a stiffer wall strikes harder
    assert cells[1]["peak_force_n"] > cells[0]["peak_force_n"]
    for c in cells:
        assert c["chatters"] == (c["stopped"] or not c["rests"])
    calm = dict((k, v) for k, v in first["longest_calm_period_ms"])
    for c in cells:
        assert (calm[c["stiffness_n_per_m"]] is None) == c["chatters"]
