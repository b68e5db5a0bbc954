"""Disturbance (eq. 2.36) and reaction-torque (eq. 2.37) observers vs the true torques."""

import numpy as np
import pytest

from control.observers import TorqueJoint, simulate_observers


def step_torque(t: float) -> float:
    return 0.02 if t >= 0.5 else 0.0  # a finger pressing on an object, N·m


def settled(run, t0: float) -> np.ndarray:
    return run.t >= t0


def test_disturbance_observer_follows_the_true_disturbance():
    joint = TorqueJoint()
    run = simulate_observers(joint, step_torque, duration=1.2, j_n=0.8 * joint.inertia,
                             kt_n=1.1 * joint.kt, g_dis=200.0)
    k = settled(run, 0.5 + 5 / 200.0)
    # after 5 time constants the estimate sits on the true (model-error-including) disturbance
    err = np.abs(run.tau_dis_hat[k] - run.tau_dis[k])
    assert err.max() < 0.03 * 0.02 + 1e-4
    # right after the step it lags: a first-order filter of cut-off g_dis
    i = np.searchsorted(run.t, 0.5 + 1 / 200.0)
    jump = run.tau_dis[i] - run.tau_dis_hat[np.searchsorted(run.t, 0.4999)]
    est = run.tau_dis_hat[i] - run.tau_dis_hat[np.searchsorted(run.t, 0.4999)]
    assert est / jump == pytest.approx(1 - np.exp(-1), abs=0.1)


def test_reaction_torque_observer_recovers_the_external_torque():
    joint = TorqueJoint()
    run = simulate_observers(joint, step_torque, duration=1.2, g_reac=200.0)
    before = (run.t > 0.3) & (run.t < 0.5)
    after = settled(run, 0.5 + 5 / 200.0)
    assert np.abs(run.tau_ext_hat[before]).max() < 5e-4  # gravity and friction removed
    assert run.tau_ext_hat[after] == pytest.approx(0.02, rel=0.02)
    # the plain disturbance observer sees gravity and friction too, so it is not τ_ext
    assert abs(run.tau_dis_hat[after][-1] - 0.02) > 1e-3


def test_feeding_back_the_disturbance_holds_the_joint():
    joint = TorqueJoint()
    plain = simulate_observers(joint, step_torque, duration=1.5)
    comp = simulate_observers(joint, step_torque, duration=1.5, compensate=True)
    assert abs(plain.q[-1] - 0.5) > 0.5  # the weak PD loop gives way to 0.02 N·m
    assert abs(comp.q[-1] - 0.5) < 0.01  # with the observer it stays on target
