"""Seed 002's gradient projection on any arm whose task is its hand's position in space.

At the kinematics layer: the criteria's gradients against finite differences on
non-planar URDF chains, and the null-space motion not moving the hand to first order.
At the control layer (headless loops, run as fast as possible): the hand follows its
target with the spare joints aiming away from the limits, and ends farther from them
than without; an arm without spare joints says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from armlab.app.arm.backends import make_backend
from armlab.control.commands import MAX_NULL_SPACE_GAIN, SetTarget, UseSpareJoints
from armlab.control.loop import SPARE_MAX_SPEED, ControlLoop
from armlab.kinematics import load_robot
from armlab.kinematics.redundancy import (
    AIMS,
    POSITION_ROWS,
    aim_gradient,
    joint_limit_criterion,
    joint_limit_gradient,
    log_manipulability_gradient,
    manipulability,
    null_space_rate,
    task_jacobian,
)

DATA = Path(__file__).with_name("data")
ARMS = {"open_manipulator_x": {}, "five_joint_arm": {"robot": DATA / "five_joint_arm.urdf"},
        "panda_style": {"robot": DATA / "panda_style.urdf"},
        "mobile_manipulator": {"robot": DATA / "mobile_manipulator.urdf",
                               "tip_link": "tcp_link"}}


def _arm(name: str):  # noqa: ANN202
    kw = dict(ARMS[name])
    return load_robot(kw.pop("robot", name), **kw)


def _poses(model, count: int, seed: int) -> np.ndarray:  # noqa: ANN001
    """Random poses inside the limits, away from them by a tenth of each range."""
    rng = np.random.default_rng(seed)
    span = model.upper - model.lower
    return rng.uniform(model.lower + 0.1 * span, model.upper - 0.1 * span, (count, model.n))


@pytest.mark.parametrize("name", ARMS)
def test_gradients_match_finite_differences_on_a_3d_chain(name):
    model = _arm(name)
    h = 1e-6
    for q in _poses(model, 6, seed=14):
        def ln_w(x: np.ndarray) -> float:
            return float(np.log(manipulability(task_jacobian(model, x, POSITION_ROWS))))

        def limits(x: np.ndarray) -> float:
            return joint_limit_criterion(x, model.lower, model.upper)

        for f, grad in ((ln_w, log_manipulability_gradient(model, q)),
                        (limits, joint_limit_gradient(q, model.lower, model.upper))):
            fd = [(f(q + e) - f(q - e)) / (2 * h) for e in np.eye(model.n) * h]
            np.testing.assert_allclose(grad, fd, atol=1e-6, rtol=1e-5)


@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("aim", AIMS[1:])
def test_null_space_motion_does_not_move_the_hand_to_first_order(name, aim):
    """θ̇_NS = (I − J⁺J) k_a ∇H: J θ̇_NS = 0, so a step ε along it moves the hand by O(ε²)
    (a tenth of the step, a hundredth of the motion), while the criterion grows."""
    model = _arm(name)
    for q in _poses(model, 5, seed=2):
        grad = aim_gradient(model, q, aim, lower=model.lower, upper=model.upper)
        J = task_jacobian(model, q, POSITION_ROWS)
        rate = null_space_rate(J, grad, 1.0)
        if name == "mobile_manipulator" and aim == "manipulability":
            # its spare joint (the wrist) turns the TCP about its own axis: it changes
            # neither the hand's place nor w, so nothing moves
            assert np.linalg.norm(rate) < 1e-9
            continue
        assert np.linalg.norm(rate) > 1e-6  # the spare joints do move
        np.testing.assert_allclose(J @ rate, 0.0, atol=1e-10)
        x0 = model.fk(q)[:3, 3]
        step = 1e-2 / np.abs(rate).max()  # 0.01 rad on the fastest joint
        moved = [np.linalg.norm(model.fk(q + s * rate)[:3, 3] - x0) for s in (step, step / 10)]
        assert moved[1] < moved[0] / 50 + 1e-12
        assert float(grad @ rate) > 0.0  # eq. 2: along the gradient, projected


def test_joint_limit_criterion_is_zero_mid_range_and_minus_half_per_joint_at_a_limit():
    lower, upper = np.array([-1.0, 0.0, -2.0]), np.array([1.0, 2.0, 0.5])
    mid = (lower + upper) / 2
    assert joint_limit_criterion(mid, lower, upper) == 0.0
    assert joint_limit_criterion(upper, lower, upper) == pytest.approx(-1.5)
    np.testing.assert_allclose(joint_limit_gradient(mid, lower, upper), 0.0)
    with pytest.raises(ValueError, match="upper limit must be above"):
        joint_limit_criterion(mid, upper, lower)


@pytest.mark.parametrize("aim,gain,words", [
    ("elsewhere", 1.0, "aim must be one of off, limits, manipulability, both"),
    ("limits", float("nan"), "null-space gain k_a (1/s) must be finite"),
    ("limits", -1.0, "must be >= 0"),
    ("limits", MAX_NULL_SPACE_GAIN * 2, f"must be at most {MAX_NULL_SPACE_GAIN:g}"),
])
def test_a_bad_spare_joints_command_names_the_field(aim, gain, words):
    with pytest.raises(ValueError) as info:
        UseSpareJoints(aim, gain)
    assert words in str(info.value)


def _loop(model, q0: np.ndarray) -> ControlLoop:  # noqa: ANN001
    loop = ControlLoop(model, make_backend("sim", model, q0=q0), realtime=False)
    loop.run_for(0.5)
    return loop


def _follow(model, q0: np.ndarray, goal: np.ndarray, aim: str) -> tuple[np.ndarray, float]:  # noqa: ANN001
    """The commanded pose and the largest |hand − goal| over the last 2 s of 8 s of
    following ``goal`` with the spare joints aiming for ``aim``."""
    loop = _loop(model, q0)
    loop.post(UseSpareJoints(aim, 2.0))
    loop.post(SetTarget(goal))
    status = loop.run_for(8.0)
    assert status.fault is None, status.fault
    snap = loop.recorder.snapshot(2.0)
    off = max(np.linalg.norm(model.fk(q)[:3, 3] - goal) for q in snap["q_cmd"])
    return snap["q_cmd"][-1], float(off)


@pytest.mark.parametrize("name,q0", [
    ("open_manipulator_x", [0.3, -1.2, 0.6, 1.6]),
    ("five_joint_arm", [0.2, 0.5, 1.5, 2.2, 0.4]),
])
@pytest.mark.slow
def test_the_hand_follows_its_target_while_the_spare_joints_leave_the_limits(name, q0):
    model = _arm(name)
    q0 = np.array(q0)
    goal = model.fk(q0)[:3, 3] + np.array([0.03, -0.03, 0.02])
    q_off, off_plain = _follow(model, q0, goal, "off")
    q_on, off_spare = _follow(model, q0, goal, "limits")
    assert off_plain < 5e-4 and off_spare < 5e-4  # the commanded hand on the target
    h_off = joint_limit_criterion(q_off, model.lower, model.upper)
    h_on = joint_limit_criterion(q_on, model.lower, model.upper)
    assert h_on > h_off + 0.05, (h_off, h_on)


@pytest.mark.slow
def test_turning_the_spare_joints_on_while_holding_keeps_the_hand_and_moves_the_arm():
    model = _arm("five_joint_arm")
    q0 = np.array([0.2, 0.5, 1.5, 2.2, 0.4])
    loop = _loop(model, q0)
    hand = model.fk(loop.recorder.snapshot(0.1)["q_cmd"][-1])[:3, 3]
    loop.post(UseSpareJoints("manipulability", 1.0))
    loop.run_for(4.0)
    assert loop.spare_joints == UseSpareJoints("manipulability", 1.0)
    snap = loop.recorder.snapshot(4.0)
    q = snap["q_cmd"]
    assert np.abs(q[-1] - q[0]).max() > 0.2  # the arm moved ...
    assert max(np.linalg.norm(model.fk(x)[:3, 3] - hand) for x in q) < 5e-4  # ... not its hand
    speeds = np.abs(np.diff(q, axis=0)) / np.diff(snap["t"])[:, None]
    assert speeds.max() <= SPARE_MAX_SPEED + 0.05  # plus the RMRC's second-order corrections
    w = [manipulability(task_jacobian(model, x, POSITION_ROWS)) for x in (q[0], q[-1])]
    assert w[1] > w[0]


def test_an_arm_without_spare_joints_says_so():
    model = load_robot(DATA / "two_joint_arm.urdf")
    loop = _loop(model, model.neutral())
    loop.post(UseSpareJoints("limits", 1.0))
    loop.run_for(0.1)
    assert loop.spare_joints.aim == "off"
    assert "2 joints have no spare joint" in loop.status.message
