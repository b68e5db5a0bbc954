"""Seed 002: redundant planar 3R arm on the paper's circle, joint limits, manipulability."""

import io
import itertools
import json
from contextlib import redirect_stdout

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.control.experiments.seed002 import circle
from armlab.kinematics import load_robot
from armlab.kinematics.redundancy import (
    MODES,
    CircleTask,
    bounded_rate,
    circle_target,
    decomposition,
    decomposition_rate,
    limit_inequality,
    manipulability,
    manipulability_gradient,
    simulate_circle,
    task_jacobian,
    velocity_bounds,
)

LIMITS = 1e-6  # rad

# ---------------------------------------------------------------- the paper's runs by hand
# An independent implementation of seed 002 §5 (the figures the tests expect come from it,
# not from the lab's earlier output): the 3 x 0.5 m planar arm's FK and Jacobian in closed
# form, w = √det(J Jᵀ) with its gradient by central differences, Euler steps of Δt.
L_M, DT, GAIN, K_A = 0.5, 0.004, 400.0, 200.0
LO = np.array([np.pi / 2, -np.pi / 2, -np.pi])
HI = np.array([np.pi, 0.0, -np.pi / 2])


def _planar(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of the hand and the 2 x 3 Jacobian, θ relative angles."""
    a = np.cumsum(q)
    x = L_M * np.array([np.cos(a).sum(), np.sin(a).sum()])
    J = L_M * np.array([[-np.sin(a[i:]).sum() for i in range(3)],
                        [np.cos(a[i:]).sum() for i in range(3)]])
    return x, J


def _w(q: np.ndarray) -> float:
    J = _planar(q)[1]
    return float(np.sqrt(np.linalg.det(J @ J.T)))


def _box_lsq(J, r, lo, hi, pref, w=1e-6):
    """min ‖J v − r‖² + w ‖v − pref‖² over lo ≤ v ≤ hi, exactly: every face of the box
    (each joint free, at lo or at hi), the best feasible minimiser of each."""
    best, best_v = np.inf, None
    for faces in itertools.product((None, 0, 1), repeat=3):
        v = np.array([np.nan if f is None else (lo, hi)[f][i] for i, f in enumerate(faces)])
        free = np.isnan(v)
        Jf = J[:, free]
        v[free] = np.linalg.solve(Jf.T @ Jf + w * np.eye(free.sum()),
                                  Jf.T @ (r - J[:, ~free] @ v[~free]) + w * pref[free])
        cost = np.sum((J @ v - r) ** 2) + w * np.sum((v - pref) ** 2)
        if np.all(v >= lo - 1e-12) and np.all(v <= hi + 1e-12) and cost < best:
            best, best_v = cost, v
    return best_v


def _circle_by_hand(mode: str) -> dict[str, object]:
    """Mode 1 θ̇ = J⁺ẋ; 2 plus the null-space projection of the middle of the velocity
    bounds (eq. 18's least squares with A = [I; −I]); 3 plus (I − J⁺J) k_a ∇w (eq. 4);
    "bounded": eq. 4's rate as the preference of the box-bounded least squares."""
    q = np.array([np.pi, -np.pi / 2, -np.pi / 2])
    qs, ws, speed = [], [], 0.0
    for k in range(int(round(2.0 / DT)) + 1):
        t = k * DT
        x, J = _planar(q)
        qs.append(q.copy())
        ws.append(_w(q))
        xd = 0.25 * np.array([1 - np.cos(np.pi * t), 2 + np.sin(np.pi * t)])
        xdot = 0.25 * np.pi * np.array([np.sin(np.pi * t), np.cos(np.pi * t)])
        xdot = xdot + GAIN * (xd - x)
        Jp = np.linalg.pinv(J)
        null = np.eye(3) - Jp @ J
        qdot = Jp @ xdot
        if mode in ("3", "bounded"):
            grad = np.array([(_w(q + e) - _w(q - e)) / 2e-6 for e in np.eye(3) * 1e-6])
            qdot = qdot + null @ (K_A * grad)
        if mode == "2":
            qdot = qdot + null @ ((LO - q) + (HI - q)) / (2 * DT)
        if mode == "bounded":
            qdot = _box_lsq(J, xdot, (LO - q) / DT, (HI - q) / DT, qdot)
        speed = max(speed, float(np.abs(qdot).max()))
        q = q + DT * qdot
    qs = np.array(qs)
    violation = np.max(np.maximum(np.maximum(qs - HI, 0), np.maximum(LO - qs, 0)), axis=0)
    return {"max_violation_rad": violation, "mean_manipulability": float(np.mean(ws)),
            "min_manipulability": float(np.min(ws)), "max_joint_speed_rad_s": speed}


@pytest.fixture(scope="module")
def by_hand():
    return {mode: _circle_by_hand(mode) for mode in ("1", "2", "3", "bounded")}


@pytest.fixture(scope="module")
def model():
    return load_robot("redundant_planar")


@pytest.fixture(scope="module")
def results():
    return {mode: circle(mode) for mode in MODES}


def test_model_has_the_papers_links_limits_and_start_pose(model):
    np.testing.assert_allclose(model.lower, [np.pi / 2, -np.pi / 2, -np.pi])
    np.testing.assert_allclose(model.upper, [np.pi, 0.0, -np.pi / 2])
    # θ(0) = [π, −π/2, −π/2] puts the end effector at x_d(0) = (0, 0.5) m.
    np.testing.assert_allclose(model.fk([np.pi, -np.pi / 2, -np.pi / 2])[:2, 3],
                               circle_target(0.0)[0], atol=1e-12)
    assert np.linalg.norm(model.fk([0.0, 0.0, 0.0])[:3, 3]) == pytest.approx(1.5)


def test_manipulability_gradient_matches_finite_differences(model):
    rng = np.random.default_rng(2)
    for _ in range(10):
        q = rng.uniform(-np.pi, np.pi, 3)
        h = 1e-6
        fd = [(manipulability(task_jacobian(model, q + e)) -
               manipulability(task_jacobian(model, q - e))) / (2 * h) for e in np.eye(3) * h]
        np.testing.assert_allclose(manipulability_gradient(model, q), fd, atol=1e-7)
    # Planar 3R with equal links: w = l1 l2 |sin θ2| + ... does not depend on θ1.
    assert manipulability_gradient(model, [0.3, 1.0, -0.7])[0] == pytest.approx(0, abs=1e-12)


def test_decomposition_parts_and_eq_20_inverse(model):
    q = np.array([2.5, -0.6, -2.0])
    J = task_jacobian(model, q)
    J_c, N = decomposition(J)
    np.testing.assert_allclose(J @ N, 0, atol=1e-12)  # N spans the null space (eq. 17)
    np.testing.assert_allclose(J @ J_c, np.eye(2), atol=1e-12)
    xdot = np.array([0.3, -0.2])
    lo, hi = velocity_bounds(q, model.lower, model.upper, 0.004)
    A, B = limit_inequality(lo, hi)
    qdot = decomposition_rate(J, xdot, A, B)
    np.testing.assert_allclose(J @ qdot, xdot, atol=1e-10)  # eq. 19 tracks ẋ exactly
    # With A = [I; −I] the least-squares choice (eq. 18) is the minimum-norm J⁺ẋ plus the
    # null-space projection of the middle of the velocity bounds (docs/redundancy.md).
    P = N @ np.linalg.pinv(N)
    np.testing.assert_allclose(qdot, np.linalg.pinv(J) @ xdot + P @ (lo + hi) / 2, atol=1e-9)
    with pytest.raises(ValueError, match="J_nr"):
        decomposition(task_jacobian(model, [2.5, -0.6, -np.pi]))


def test_bounded_rate_never_leaves_the_bounds():
    rng = np.random.default_rng(3)
    for _ in range(50):
        J = rng.normal(size=(2, 3))
        lo = -rng.uniform(0, 1, 3)
        hi = rng.uniform(0, 1, 3)
        qdot = bounded_rate(J, rng.normal(size=2) * 3, lo, hi, rng.normal(size=3))
        assert np.all(qdot >= lo) and np.all(qdot <= hi)


@pytest.mark.slow
def test_modes_1_and_3_leave_the_limits_mode_1_on_joints_2_and_3(results, by_hand):
    v1 = results["1"]["max_violation_rad"]
    assert v1[0] <= LIMITS and by_hand["1"]["max_violation_rad"][0] <= LIMITS
    assert v1[1:] == pytest.approx(by_hand["1"]["max_violation_rad"][1:], abs=1e-4)
    assert min(v1[1:]) > 0.2  # 0.2600 and 0.5530 rad
    assert results["3"]["max_violation_rad"] == pytest.approx(
        by_hand["3"]["max_violation_rad"], abs=1e-4)  # 0.0912, 0.2179, 0.2231
    assert min(results["3"]["max_violation_rad"]) > 0.05


@pytest.mark.slow
def test_mode_1_leaves_joint_2_below_and_joint_3_above_their_limits(model, by_hand):
    """The paper: without redundancy or limits joints 2 and 3 leave their ranges. Joint 2
    ([-90°, 0°]) bends past -90° and joint 3 ([-180°, -90°]) opens past -90°."""
    run = simulate_circle(model, "1")
    below = model.lower - run.q.min(axis=0)  # > 0: under the lower limit
    above = run.q.max(axis=0) - model.upper  # > 0: over the upper limit
    hand = by_hand["1"]["max_violation_rad"]
    assert below[1] == pytest.approx(hand[1], abs=1e-4) and above[1] < -1.0  # 0.2600
    assert above[2] == pytest.approx(hand[2], abs=1e-4) and below[2] < -1.0  # 0.5530
    assert below[0] < -0.7 and above[0] <= LIMITS  # joint 1 touches π, never past it


@pytest.mark.parametrize("mode", ["2", "4", "bounded"])
@pytest.mark.slow
def test_limited_modes_never_leave_the_limits(results, mode):
    assert max(results[mode]["max_violation_rad"]) <= LIMITS


@pytest.mark.parametrize("mode", list(MODES))
@pytest.mark.slow
def test_tracking_error_after_0_2_s_is_below_1_mm(results, mode):
    assert results[mode]["max_error_m"] < 1e-3


@pytest.mark.slow
def test_printed_method_gives_mode_4_the_motion_of_mode_2_and_bounded_beats_it(model, results,
                                                                              by_hand):
    # The paper claims w(mode 4) > w(mode 2). With its eq. 7-19 the manipulability
    # gradient cancels exactly (docs/redundancy.md): the two runs are the same motion.
    run2, run4 = simulate_circle(model, "2"), simulate_circle(model, "4")
    np.testing.assert_allclose(run4.q, run2.q, atol=1e-9)
    assert results["4"]["mean_manipulability"] == pytest.approx(
        results["2"]["mean_manipulability"], abs=1e-12)
    assert results["2"]["mean_manipulability"] == pytest.approx(
        by_hand["2"]["mean_manipulability"], abs=1e-4)  # 0.4141
    # The guaranteed method does use the gradient inside the limits.
    assert results["bounded"]["mean_manipulability"] == pytest.approx(
        by_hand["bounded"]["mean_manipulability"], abs=1e-4)  # 0.4740
    assert max(by_hand["bounded"]["max_violation_rad"]) <= LIMITS
    assert by_hand["bounded"]["mean_manipulability"] > by_hand["2"]["mean_manipulability"]
    assert results["bounded"]["min_manipulability"] > results["2"]["min_manipulability"]
    # Using redundancy without limits raises w most of all (the paper's Fig. 10).
    assert results["3"]["mean_manipulability"] > results["bounded"]["mean_manipulability"]


@pytest.mark.slow
def test_decomposition_jumps_the_self_motion_to_mid_range_in_one_sample(model, results):
    run = simulate_circle(model, "2")
    mid = (model.lower + model.upper) / 2
    # First step: the null-space part of (mid − θ) is removed at once (gain 1/Δt).
    assert np.abs(run.q[1] - run.q[0]).max() > 0.5
    assert results["2"]["max_joint_speed_rad_s"] > 100
    assert results["bounded"]["max_joint_speed_rad_s"] < 10
    assert np.linalg.norm(run.q[1] - mid) < np.linalg.norm(run.q[0] - mid)


def test_unstable_gain_and_unknown_mode_are_refused(model):
    with pytest.raises(ValueError, match="unstable"):
        simulate_circle(model, "1", CircleTask(gain=600.0))
    with pytest.raises(ValueError, match="mode"):
        simulate_circle(model, "5")


def test_cli_prints_the_issue_schema():
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["experiment", "seed002-circle", "--mode", "1", "--json"]) == 0
    r = json.loads(out.getvalue())
    assert r["mode"] == 1
    assert set(r) >= {"mode", "max_error_m", "max_violation_rad", "mean_manipulability",
                      "min_manipulability"}
    assert len(r["max_violation_rad"]) == 3 and r["max_violation_rad"][2] > 0.1
