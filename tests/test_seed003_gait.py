"""Seed 003 gaits: sine pattern (Table 1.1), trot, crawl, walking, static stability."""

import io
import json
from contextlib import redirect_stdout

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.kinematics.gait import (
    TROT_PHASE,
    SineParams,
    crawl,
    cycle_angles,
    cycle_margins,
    in_swing,
    sine_pattern,
    trot,
    walk,
)
from armlab.kinematics.quadruped import LEGS
from armlab.kinematics.stability import nearest_on_polygon, stability_margin, support_polygon

P = SineParams(A=0.05, B=0.11, C=0.025, D=0.085)


@pytest.mark.parametrize("phase", [0, 1])
def test_stance_feet_at_minus_d_and_swing_peaks_c_above(phase):
    omegas = np.arange(0, 360, 0.5)
    feet = np.array([sine_pattern(w, P, phase=phase) for w in omegas])
    swing = np.array([in_swing(w, phase) for w in omegas])
    assert swing.mean() == pytest.approx(0.5)
    np.testing.assert_allclose(feet[~swing, 2], -P.D)
    assert np.all(feet[swing, 2] >= -P.D - 1e-12)
    assert feet[:, 2].max() == pytest.approx(P.C - P.D)
    peak = omegas[np.argmax(feet[:, 2])]
    assert peak == (180.0 if phase == 0 else 0.0)  # mid-swing
    # Straight ahead (α = 90°): the step is along x only, ±A/2, foot B out.
    np.testing.assert_allclose(feet[:, 1], P.B, atol=1e-15)
    assert feet[:, 0].max() == pytest.approx(P.A / 2)
    assert feet[:, 0].min() == pytest.approx(-P.A / 2)
    # Both phases swing forward (+x) and push back in stance.
    lift = int(np.argmax(swing & ~np.roll(swing, 1)))
    land = int(np.argmax(~swing & np.roll(swing, 1)))
    assert feet[lift, 0] == pytest.approx(-P.A / 2) and feet[land, 0] == pytest.approx(P.A / 2)


def test_heading_and_direction_index():
    side = sine_pattern(180.0, SineParams(alpha_deg=0.0), phase=0)
    assert side[0] == pytest.approx(0.0) and side[1] == pytest.approx(0.10)
    w = 45.0  # phase 0 in stance
    fwd = sine_pattern(w, P, phase=0, direction=0)
    back = sine_pattern(w, P, phase=0, direction=1)
    assert back[0] == pytest.approx(-fwd[0]) and back[2] == fwd[2]
    with pytest.raises(ValueError, match="phase"):
        sine_pattern(0.0, P, phase=2)
    with pytest.raises(ValueError, match="D"):
        SineParams(D=0.0)


def test_trot_moves_diagonal_legs_together():
    cyc = trot(P, samples=72)
    i = {leg: LEGS.index(leg) for leg in LEGS}
    np.testing.assert_allclose(cyc.feet[:, i["RF"]], cyc.feet[:, i["LH"]])
    np.testing.assert_allclose(cyc.feet[:, i["LF"]], cyc.feet[:, i["RH"]])
    assert TROT_PHASE["RF"] == TROT_PHASE["LH"] != TROT_PHASE["LF"] == TROT_PHASE["RH"]
    assert np.all(cyc.stance.sum(axis=1) == 2)
    assert np.all(cyc.stance[:, i["RF"]] != cyc.stance[:, i["LF"]])


@pytest.mark.parametrize("make", [lambda: trot(P, samples=72), lambda: crawl(P, samples=72)])
def test_stance_feet_stay_put_while_the_body_walks(make):
    cyc = make()
    moved = walk(cyc, cycles=3)
    assert moved.slip.max() < 1e-3
    T = len(cyc.omega_deg)
    # Check independently of walk()'s own slip figure: a foot standing in two
    # consecutive samples has the same world position.
    both = np.tile(cyc.stance, (3, 1))
    still = both[1:] & both[:-1]
    jumps = np.linalg.norm(np.diff(moved.feet_world, axis=0), axis=2)[still]
    assert jumps.max() < 1e-3
    np.testing.assert_allclose(moved.feet_world[both][:, 2], 0.0, atol=1e-12)  # on the floor
    advance = moved.body[T, :2] - moved.body[0, :2]
    # Trot: each diagonal pair pushes the body A per half cycle; crawl: A per cycle.
    expected = 2 * P.A if cyc.name == "trot" else P.A
    np.testing.assert_allclose(advance, [expected, 0.0], atol=1e-9)
    assert moved.body[:, 2] == pytest.approx(P.D)


def test_trot_static_margin_is_never_positive_while_two_legs_swing():
    cyc = trot(P, samples=72)
    angles, ok = cycle_angles(cyc)
    assert ok
    margins = cycle_margins(cyc, walk(cyc), angles)
    two = cyc.stance.sum(axis=1) == 2
    assert two.all()
    assert np.all(margins[two] <= 1e-12)
    assert margins.min() < -0.005  # away from mid-stance the COM is off the diagonal


def test_crawl_margin_is_positive_over_a_whole_cycle_with_defaults():
    cyc = crawl(samples=144)
    angles, ok = cycle_angles(cyc)
    assert ok
    margins = cycle_margins(cyc, walk(cyc), angles)
    assert margins.min() > 0.01
    swinging = cyc.stance.sum(axis=1)
    assert set(swinging.tolist()) == {3, 4}  # one leg at a time
    for leg in range(4):  # every leg swings once per cycle
        up = ~cyc.stance[:, leg]
        assert (up & ~np.roll(up, 1)).sum() == 1


def test_body_shift_is_what_keeps_other_crawl_sequences_standing():
    # margin=-1 m: the body never moves sideways. The classic sequence LH, LF, RH, RF then
    # barely stays up (a few mm); the others tip over. With the shift all of them stand.
    for seq, tips in ((("LH", "LF", "RH", "RF"), False), (("LF", "LH", "RF", "RH"), True),
                      (("LF", "RF", "LH", "RH"), True)):
        margins = {}
        for target in (-1.0, 0.02):
            cyc = crawl(samples=72, sequence=seq, margin=target)
            angles, _ = cycle_angles(cyc)
            margins[target] = cycle_margins(cyc, walk(cyc), angles).min()
        assert (margins[-1.0] < 0.0) == tips and margins[-1.0] < 0.005, seq
        assert margins[0.02] > 0.015, seq


def test_seed_formula_with_other_headings_makes_the_feet_slip():
    # The right legs' frame is mirrored, so α ≠ 90° steps the two sides in mirrored
    # directions: no rigid body motion keeps both stance feet put.
    moved = walk(trot(SineParams(alpha_deg=60.0), samples=72))
    assert moved.slip.max() > 5e-3


def test_direction_one_on_the_right_legs_turns_right():
    cyc = trot(P, samples=72, directions={"RF": 1, "RH": 1})
    moved = walk(cyc, cycles=2)
    T = len(cyc.omega_deg)
    assert moved.body[T, 3] - moved.body[0, 3] < -0.05  # clockwise seen from above


def test_support_polygon_and_margin_signs():
    feet = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    hull = support_polygon(feet)
    assert len(hull) == 4
    assert stability_margin([0.5, 0.4], feet) == pytest.approx(0.4)
    assert stability_margin([1.5, 0.5], feet) == pytest.approx(-0.5)
    line = feet[:2]
    assert stability_margin([0.5, 0.0], line) == 0.0
    assert stability_margin([0.5, 0.2], line) == pytest.approx(-0.2)


@pytest.mark.slow
def test_cli_prints_one_cycle():
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["experiment", "seed003-gait", "--gait", "crawl", "--samples", "24",
                     "--json"]) == 0
    r = json.loads(out.getvalue())
    assert r["gait"] == "crawl" and len(r["rows"]) == 24 and r["reachable"]
    assert r["min_margin_m"] > 0 and r["max_slip_m"] < 1e-3
    assert r["warnings"] == []
    s = r["rows"][0]
    assert set(s["angles_deg"]) == set(LEGS) and len(s["feet_m"]["RF"]) == 3


@pytest.mark.parametrize("hull", [
    [[0.1, 0.2]],
    [[0.0, 0.0], [0.2, 0.1]],
    [[0.0, 0.0], [0.2, 0.0], [0.1, 0.15]],
    [[0.0, 0.0], [0.2, 0.0], [0.2, 0.2], [0.0, 0.2]],
])
def test_the_margin_ends_on_the_support_polygons_nearest_boundary_point(hull):
    hull = np.array(hull)
    closed = len(hull) > 2
    ends = list(zip(hull, np.roll(hull, -1, axis=0) if closed else hull[1:], strict=False))
    s = np.linspace(0.0, 1.0, 2001)[:, None]
    boundary = (np.concatenate([a + s * (b - a) for a, b in ends]) if ends else hull)
    rng = np.random.default_rng(3)
    for p in rng.uniform(-0.1, 0.3, (50, 2)):
        near = nearest_on_polygon(p, hull)
        best = np.linalg.norm(boundary - p, axis=1).min()
        assert np.linalg.norm(near - p) == pytest.approx(best, abs=2e-4)
        assert np.linalg.norm(boundary - near, axis=1).min() < 2e-4  # on the boundary
