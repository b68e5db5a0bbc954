"""Disturbance (eq. 2.36) and reaction-torque (eq. 2.37) observers vs the true torques."""

import numpy as np
import pytest

from armlab.control.observers import (
    TorqueJoint,
    friction_torque,
    gravity_torque,
    simulate_observers,
)
from armlab.kinematics.hand_statics import (
    GRIPPER_KT,
    OZ_IN,
    FingerGeometry,
    grip_force_from_tension,
    tension_for_grip_force,
)

STEP = 0.005  #: N·m at the gearbox output, about a third of the 2 oz·in (0.0141 N·m) stall


def step_torque(t: float) -> float:
    return STEP if t >= 0.5 else 0.0  # a finger pressing on an object, N·m


def test_gripper_torque_constant_comes_from_the_datasheet_once():
    # thesis §2.4: 2 oz·in and 1.6 A at stall, both at the 5:1 output -> 8.827 mN·m/A
    assert GRIPPER_KT == pytest.approx(2 * OZ_IN / 1.6, rel=1e-12)
    assert GRIPPER_KT == pytest.approx(8.827e-3, rel=1e-4)
    assert TorqueJoint().kt == GRIPPER_KT  # not 5x that (gear ratio applied twice)


def test_reaction_torque_observer_estimates_a_known_grip_force():
    g, phi, force = FingerGeometry(), 0.2, 0.5  # 0.5 N at the fingertip, finger at 0.2 rad
    tau = float(tension_for_grip_force(g, force, phi)) * g.spool_radius  # N·m at the output
    joint = TorqueJoint()
    # the finger held in place (disturbance fed back), as a gripper holding its grip
    run = simulate_observers(joint, lambda t: tau if t >= 0.5 else 0.0, duration=1.2,
                             g_reac=200.0, compensate=True)
    late = run.t >= 0.5 + 5 / 200.0
    est = float(np.mean(run.tau_ext_hat[late]))
    assert float(grip_force_from_tension(g, est / g.spool_radius, phi)) == pytest.approx(
        force, rel=0.05)
    # the current that holds it is the datasheet's: tau / K_t (1.6 A would be 2 oz·in)
    held = tau + gravity_torque(joint, run.q[-1]) + friction_torque(joint, run.qd[-1])
    assert run.current[-1] == pytest.approx(held / (2 * OZ_IN / 1.6), rel=0.002)
    assert 0.8 < run.current[-1] < 0.85  # amps (0.59 A of it the grip): under the 1.6 A stall


def settled(run, t0: float) -> np.ndarray:
    return run.t >= t0


def test_disturbance_observer_follows_the_true_disturbance():
    joint = TorqueJoint()
    run = simulate_observers(joint, step_torque, duration=1.2, j_n=0.8 * joint.inertia,
                             kt_n=1.1 * joint.kt, g_dis=200.0)
    k = settled(run, 0.5 + 5 / 200.0)
    # after 5 time constants the estimate sits on the true (model-error-including) disturbance
    err = np.abs(run.tau_dis_hat[k] - run.tau_dis[k])
    assert err.max() < 0.03 * STEP + 1e-4
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
    assert run.tau_ext_hat[after] == pytest.approx(STEP, rel=0.02)
    # the plain disturbance observer sees gravity and friction too, so it is not τ_ext
    assert abs(run.tau_dis_hat[after][-1] - STEP) > 1e-3


def test_feeding_back_the_disturbance_holds_the_joint():
    joint = TorqueJoint()
    plain = simulate_observers(joint, step_torque, duration=1.5)
    comp = simulate_observers(joint, step_torque, duration=1.5, compensate=True)
    assert abs(plain.q[-1] - 0.5) > 0.4  # the weak PD loop gives way to 5 mN·m
    assert abs(comp.q[-1] - 0.5) < 0.01  # with the observer it stays on target
