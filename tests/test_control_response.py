"""Step and push responses measured on a recording (armlab.control.response), without a server."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from armlab.control import metrics
from armlab.control.commands import Push, RunTrajectory
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.response import (
    line_errors,
    measure_push,
    measure_step,
    plan_step,
    simulate_ideal_joint_step,
)
from armlab.control.trajectory import thesis_line
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics import load_robot

ARM = load_robot("receptionist_arm")
LOWER = np.array([-1.0, -1.0, -1.0])
UPPER = np.array([1.0, 1.0, 1.0])


def _snap(q_cmd_rows: list[list[float]]) -> dict[str, np.ndarray]:
    q = np.array(q_cmd_rows, dtype=float)
    return {"t": np.arange(len(q)) * 0.016, "q_cmd": q, "q": q.copy()}


def test_plan_step_steps_the_newest_command_and_turns_back_at_a_limit():
    snap = _snap([[0.0, 0.1, 0.2], [0.1, 0.2, 0.3], [np.nan, np.nan, np.nan]])
    p = Params()  # Kv 5: Ts = 8/Kv = 1.6 s, wait 1.5 Ts = 2.4 s -> at least 3 s
    plan = plan_step(snap, joint=2, step=math.radians(10), lower=LOWER, upper=UPPER,
                     params=p, label="θ2")
    assert (plan.joint, plan.q0) == (2, 0.3)  # the newest finite row
    assert plan.q1 == pytest.approx(0.3 + math.radians(10), abs=1e-15)
    np.testing.assert_array_equal(plan.trajectory.times, [0.0, p.period])
    np.testing.assert_allclose(plan.trajectory.q, [[0.1, 0.2, 0.3], [0.1, 0.2, plan.q1]])
    assert not plan.trajectory.qd.any() and plan.trajectory.name == "step θ2"
    assert plan.wait_s == 3.0
    assert plan_step(snap, joint=2, step=0.1, lower=LOWER, upper=UPPER,
                     params=Params(kv=0.2), label="θ2").wait_s == 12.0  # 60 s, capped
    near = plan_step(_snap([[0.0, 0.0, 0.95]]), joint=2, step=0.2, lower=LOWER, upper=UPPER,
                     params=p, label="θ2")
    assert near.q1 == pytest.approx(0.75)  # +0.2 would pass the 1.0 limit: stepped down


@pytest.mark.parametrize(("rows", "step", "upper", "message"), [
    ([[np.nan] * 3], 0.2, UPPER, "the controller is not running: press Reset first"),
    ([[0.0] * 3], math.radians(0.4), UPPER, "step: choose a step of at least 1°"),
    ([[0.0, 0.0, 0.0]], math.radians(30), np.array([1.0, 1.0, 0.1]),
     "θ2: no room for a 30° step between its limits"),
])
def test_plan_step_refusals_say_why(rows, step, upper, message):
    lower = np.array([-1.0, -1.0, -0.1])
    with pytest.raises(ValueError, match=f"^{message}$"):
        plan_step(_snap(rows), joint=2, step=step, lower=lower, upper=upper, params=Params(),
                  label="θ2")


def _recorded_step(kp: float, kv: float, *, q0: float, q1: float, t0: float,
                   lead: int = 50) -> dict[str, np.ndarray]:
    """A recording of joint 1 of 2: ``lead`` periods at q0, then the sampled ideal joint's
    step (eq. 2.20 integrated twice) from q0 to q1 posted at ``t0``."""
    t, y = simulate_ideal_joint_step(kp, kv, period=1e-3, duration=6.0)
    tt = np.concatenate([t0 - 1e-3 * np.arange(lead, 0, -1), t0 + t])
    q = np.concatenate([np.full(lead, q0), q0 + (q1 - q0) * y])
    q_cmd = np.concatenate([np.full(lead, q0), np.full(len(t), q1)])
    other = np.full(len(tt), 0.5)
    return {"t": tt, "q": np.column_stack([other, q]), "q_cmd": np.column_stack([other, q_cmd])}


def test_measure_step_reads_back_the_design_of_a_sampled_second_order_step():
    kp, kv = 20.0, 5.0
    snap = _recorded_step(kp, kv, q0=0.4, q1=0.1, t0=3.0)
    m = measure_step(snap, t0=3.0, joint=1, q0=0.4, q1=0.1, what="step of θ0 by -17°")
    # q̈ = Kp e + Kv ė: ωn² = Kp, 2ζωn = Kv; a second-order step's closed-form peak
    wn, zeta = math.sqrt(kp), kv / (2.0 * math.sqrt(kp))
    assert m.what == "step of θ0 by -17°" and m.static_gain is None
    overshoot = 100.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2))
    assert m.overshoot_pct == pytest.approx(overshoot, rel=0.02)  # 12.0 %
    assert m.peak_time_s == pytest.approx(math.pi / (wn * math.sqrt(1.0 - zeta**2)),
                                          rel=0.02)  # 0.85 s
    assert m.zeta == pytest.approx(zeta, rel=0.02)
    assert m.omega_n == pytest.approx(wn, rel=0.02)
    with pytest.raises(ValueError, match="never stepped"):
        measure_step(snap, t0=3.0, joint=0, q0=0.5, q1=0.8, what="joint 0")


def test_measure_push_gives_the_static_gain_C_f_on_the_joint_pushed_hardest():
    k_f, k_env, m_env, d_env = 4.0, 16.0, 1.0, 6.4  # the default: C_f 0.25, ζf 0.8, ωf 4
    t = np.arange(0.0, 4.0, 1e-3)
    tau = np.zeros((len(t), 3))
    tau[1:, 1], tau[1:, 2] = 0.05, 0.8  # a torque step at t = 1 ms; joint 2 feels most
    _, y = signal.step(metrics.environment_model(m_env, d_env, k_env, k_f), T=t)
    env = np.zeros((len(t), 3))
    env[:, 2] = 0.8 * y
    snap = {"t": 10.0 + t, "q_env": env, "tau_ext": tau}
    m = measure_push(snap, t0=10.0, t1=14.0, what="push of 4 N", joint_labels=("a", "b", "c"))
    assert m.what == "push of 4 N, joint c"
    assert m.static_gain == pytest.approx(k_f / k_env, rel=1e-3)
    assert m.zeta is not None and m.zeta == pytest.approx(0.8, rel=0.02)
    with pytest.raises(ValueError, match="too few samples"):
        measure_push(snap, t0=20.0, t1=21.0, what="push", joint_labels=("a", "b", "c"))


def test_line_errors_are_the_largest_per_joint_since_the_start():
    snap = {"t": np.array([0.0, 1.0, 2.0, 3.0]),
            "error": np.array([[9.0, 9.0], [0.1, -0.3], [np.nan, np.nan], [-0.2, 0.1]])}
    np.testing.assert_array_equal(line_errors(snap, t0=1.0), [0.2, 0.3])


def test_step_and_push_measured_on_the_simulated_arm_headless():
    """What the Teach tab shows, from the same ControlLoop run headless: the step of θ2
    against eq. 2.16–2.19 and the push's static gain against C_f = K_f/K_env (2.15)."""
    line = thesis_line(ARM)
    loop = ControlLoop(ARM, SimBackend(ARM, q0=line.q[0]), Params(), realtime=False,
                       history_s=30.0)
    loop.run_for(1.0)
    plan = plan_step(loop.recorder.snapshot(0.2), joint=2, step=math.radians(-20),
                     lower=loop.lower, upper=loop.upper, params=loop.params, label="θ2")
    t0 = loop.status.t
    loop.post(RunTrajectory(plan.trajectory, approach=False))
    loop.run_for(plan.wait_s)
    snap = loop.recorder.snapshot(loop.status.t - t0 + 0.2)
    m = measure_step(snap, t0=t0, joint=2, q0=plan.q0, q1=plan.q1, what="step")
    # Kp 20, Kv 5: Tr = 0.40 s, Tp = 0.85 s by the formulas; the servos' own lag and
    # feedforward change the figures, not their size (as the lesson's UI test says).
    assert 0.2 < m.rise_time_s < 0.8
    # ζ = 0.56 < 1 must overshoot (12 % by the formula; about 4 % through the servos' lag)
    assert m.peak_time_s is not None and 0.4 < m.peak_time_s < 1.6
    assert m.overshoot_pct is not None and 1.0 < m.overshoot_pct < 24.0, m
    assert m.settling_time_s is not None and m.settling_time_s < plan.wait_s
    t0 = loop.status.t
    loop.post(Push(np.array([0.0, -4.0, 0.0]), link=ARM.n - 1, point=ARM.tip[:3, 3],
                   duration=2.0))
    loop.run_for(2.2)
    snap = loop.recorder.snapshot(loop.status.t - t0 + 0.2)
    p = measure_push(snap, t0=t0, t1=t0 + 2.0, what="push", joint_labels=ARM.joint_names)
    assert p.static_gain == pytest.approx(4.0 / 16.0, rel=0.05)  # C_f = K_f / K_env
    assert p.what.startswith("push, joint ")
