"""The compliance controller: static gain of eq. 2.7, release, and PD for comparison."""

import dataclasses
import functools

import numpy as np
import pytest

from armlab.control.backend import JointState
from armlab.control.commands import Push
from armlab.control.compliance import ComplianceController, ControllerState, environment_step, lpf
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics import load_robot

ARM = load_robot("receptionist_arm")
POSE = np.array([0.6, 0.3, 1.2])  # arm raised and bent: every joint carries the push
FORCE = np.array([0.0, -4.0, 2.0])  # N at the hand, base frame


def ideal_joint_offset(params: Params, tau_hand: float, seconds: float = 20.0) -> float:
    """One ideal joint (it reaches every goal), no gravity, a hand torque ``tau_hand``:
    the servo's load is then the motor torque, −tau_hand at rest."""
    ctl = ComplianceController(np.array([-3.0]), np.array([3.0]), 10.0)
    st = ControllerState.at_rest(np.zeros(1))
    q, qd = np.zeros(1), np.zeros(1)
    for k in range(int(seconds / params.period)):
        load = np.array([-tau_hand]) if k * params.period > 1.0 else np.zeros(1)
        meas = JointState(k * params.period, q, qd, load, (0,), (True,))
        q, qd = ctl.step(params, st, np.zeros(1), np.zeros(1), np.zeros(1), meas, np.zeros(1))
    return float(q[0])


@pytest.mark.parametrize("law,gain", [("2.6", lambda p: p.k_f / p.k_env),
                                      ("2.26", lambda p: p.k_f)])
def test_ideal_joint_static_gain_of_each_law(law, gain):
    p = Params(law=law, k_f=0.3, k_env=12.0, d_env=5.0, m_env=1.0)
    assert ideal_joint_offset(p, 0.5) == pytest.approx(gain(p) * 0.5, rel=1e-3)


@pytest.mark.parametrize("law", ["2.6", "2.26"])
def test_each_registered_law_states_the_stiffness_its_controller_settles_at(law):
    """The registry's joint stiffness (what the contact experiment predicts with) is what
    the controller running that very law holds: τ / offset, on an ideal joint."""
    from armlab.control.laws import LAWS

    p = Params(law=law, k_f=0.3, k_env=12.0, d_env=5.0, m_env=1.0)
    assert LAWS[law].key == law
    assert 0.5 / ideal_joint_offset(p, 0.5) == pytest.approx(LAWS[law].joint_stiffness(p),
                                                             rel=1e-3)


def test_a_student_s_law_takes_eq_2_6_s_place_and_the_literal_law_stays_the_lab_s():
    """``with_student``: the controller calls the student's function where eq. 2.6 runs
    (their numbers, here the lab's own halved), and eq. 2.26 is still the lab's."""
    from armlab.control.compliance import Laws
    from armlab.control.laws import EQ_2_26, LAWS, compliance_accel, with_student

    calls = []

    def halved(*args):
        calls.append(len(args))
        return 0.5 * compliance_accel(*args)

    laws = Laws(compliance=with_student(halved))
    assert laws.compliance["2.26"] is EQ_2_26
    assert laws.compliance["2.6"].title == "Compliance, your law 2.6"
    assert laws.compliance["2.6"].label == LAWS["2.6"].label  # the same choice on the page
    p = Params()
    ctl_theirs = ComplianceController(np.array([-3.0]), np.array([3.0]), 10.0, laws=laws)
    ctl_ours = ComplianceController(np.array([-3.0]), np.array([3.0]), 10.0)
    meas = JointState(0.0, np.zeros(1), np.zeros(1), np.zeros(1), (0,), (True,))
    q_cmd = np.array([0.2])
    ours = ctl_ours.step(p, ControllerState.at_rest(np.zeros(1)), q_cmd, np.zeros(1),
                         np.zeros(1), meas, np.zeros(1))
    theirs = ctl_theirs.step(p, ControllerState.at_rest(np.zeros(1)), q_cmd, np.zeros(1),
                             np.zeros(1), meas, np.zeros(1))
    assert calls == [9]  # kp, kv and the seven arrays of the exercise's signature
    np.testing.assert_allclose(theirs[1], 0.5 * ours[1])  # θ̇_ref = T θ̈_ref from rest
    calls.clear()
    ctl_theirs.step(Params(law="2.26"), ControllerState.at_rest(np.zeros(1)), q_cmd,
                    np.zeros(1), np.zeros(1), meas, np.zeros(1))
    assert calls == []


def test_environment_step_settles_on_kf_tau_over_kenv():
    q = qd = 0.0
    for _ in range(5000):
        q, qd, _ = environment_step(1.0, 5.0, 12.0, 0.3, 2.0, q, qd, 0.016)
    assert q == pytest.approx(0.3 * 2.0 / 12.0, rel=1e-9)


def test_lpf_is_the_thesis_filter():
    y = 0.0
    for _ in range(20):  # 20 samples of a unit step with α = 0.05: 1 − 0.95^20
        y = lpf(y, 1.0, 0.05)
    assert y == pytest.approx(1 - 0.95**20)


@functools.cache
def hold_and_push(params: Params):
    """Hold POSE, push the hand with FORCE for 7 s, let go: (pushed window, true joint
    torque of the push at its end, released window)."""
    backend = SimBackend(ARM, q0=POSE)
    loop = ControlLoop(ARM, backend, params, realtime=False)
    loop.run_for(1.0)
    loop.post(Push(FORCE, 2, ARM.tip[:3, 3], 7.0))
    loop.run_for(6.9)  # the yield changes the push's lever arms: let it settle fully
    pushed = loop.recorder.snapshot(2.0)
    tau = backend.plant.truth().external_torque  # true J^T F on the joints, N·m
    loop.run_for(2.5)
    released = loop.recorder.snapshot(0.3)
    assert loop.status.fault is None
    return pushed, tau, released


@pytest.mark.slow
def test_steady_offset_is_kf_tau_over_kenv_and_release_returns():
    p = Params()
    pushed, tau, released = hold_and_push(p)
    offset = np.mean(pushed["q"] - pushed["q_cmd"], axis=0)
    expected = p.k_f / p.k_env * tau  # the arm gives way in the push's direction
    assert np.abs(expected).min() > 0.05  # every joint is pushed by 3° or more
    np.testing.assert_allclose(offset, expected, rtol=0.05)
    # the estimate behind it: τ_ext = LPF(load) − τ_dyn is the torque the motors spend
    np.testing.assert_allclose(np.mean(pushed["tau_ext"], axis=0), -tau, rtol=0.05)
    # let go: back on the commanded path within a degree
    assert np.degrees(np.abs(released["q"][-1] - released["q_cmd"][-1])).max() < 1.0


@pytest.mark.slow
def test_thesis_literal_law_moves_k_env_times_further():
    p = dataclasses.replace(Params(), law="2.26", k_f=0.25, k_env=16.0)
    pushed, tau, _ = hold_and_push(p)
    offset = np.mean(pushed["q"] - pushed["q_cmd"], axis=0)
    np.testing.assert_allclose(offset, p.k_f * tau, rtol=0.05)


@pytest.mark.slow
def test_without_compliance_the_arm_yields_many_times_less():
    comp, tau_c, _ = hold_and_push(Params())
    stiff, tau_s, _ = hold_and_push(Params(compliance=False))
    yield_c = np.abs(np.mean(comp["q"] - comp["q_cmd"], axis=0))
    yield_s = np.abs(np.mean(stiff["q"] - stiff["q_cmd"], axis=0))
    assert np.all(yield_c > 5 * np.maximum(yield_s, np.radians(0.3)))
    assert np.abs(tau_s).max() > 0.3  # the PD arm was pushed as hard, and held on
