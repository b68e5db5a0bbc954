"""The reaction-torque observer (thesis eq. 2.37) on a joint of an arm model, at the
control layer: readings made from the model's own Newton–Euler (what an ideal
current-sensing servo would report, K_t I = the joint torque), fed to
``known_torques`` + ``rtob_series`` as ``armlab experiment observers --backend serial``
feeds them. The servo runs are tests/test_observers_servos.py (simulated XM430s) and
tests/test_bus_observers.py (the emulator over a pseudo-terminal)."""

from __future__ import annotations

import numpy as np
import pytest

from armlab.control.experiments.observers import (
    SERVO_G,
    SERVO_PERIOD,
    dob_series,
    known_torques,
    rtob_series,
)
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import gravity_torques, mass_matrix, rnea

OMX = load_robot("open_manipulator_x")
SHOULDER = 1
POSE = np.array([0.0, 0.3, -0.2, 0.1])
APPLIED = 0.2  #: N·m along the shoulder's axis (positive like its angle)
STEP_AT = 2.0  #: s
SETTLE = 5.0 / SERVO_G  #: s: five time constants of the observer's LPF
GIVE = 0.016  #: rad the hold gives way under the applied torque (0.9°, as an XM430's P hold)


def _held_readings() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The shoulder held at POSE; APPLIED from STEP_AT on, under which the hold gives way
    GIVE and the motor carries gravity at the new pose minus the applied torque."""
    t = np.arange(0.0, 4.0, SERVO_PERIOD)
    on = t >= STEP_AT
    q = np.tile(POSE, (len(t), 1))
    q[on, SHOULDER] += GIVE
    qd = np.zeros_like(q)
    tau_m = np.array([gravity_torques(OMX, qk)[SHOULDER] for qk in q]) - APPLIED * on
    return t, q, qd, tau_m


def test_on_a_held_joint_the_rtob_reads_zero_under_gravity_and_then_the_applied_torque():
    t, q, qd, tau_m = _held_readings()
    j_n = float(mass_matrix(OMX, POSE)[SHOULDER, SHOULDER])
    applied_hat = -rtob_series(t, qd[:, SHOULDER], tau_m, known_torques(OMX, SHOULDER, q, qd),
                               j_n=j_n, g_reac=SERVO_G)
    before, after = t < STEP_AT, t >= STEP_AT + SETTLE
    # gravity alone: the known load is all the motor carries
    assert np.max(np.abs(applied_hat[before])) < 1e-9
    # gravity (at the pose the hold gave way to) + the applied torque: that torque, absolute
    assert applied_hat[after] == pytest.approx(APPLIED, rel=0.01)  # e^-5 of it left
    # the DOB's levels carry gravity, and its step also the gravity change over GIVE
    dob = dob_series(t, qd[:, SHOULDER], tau_m, j_n=j_n, g_dis=SERVO_G)
    assert dob[before] == pytest.approx(gravity_torques(OMX, POSE)[SHOULDER])
    assert abs(-(dob[-1] - dob[0]) - APPLIED) > 1e-3


def test_the_rtob_takes_the_moving_joints_inertia_and_speed_terms_out():
    """The shoulder swings ±0.3 rad at 0.5 Hz (J_n θ̈ up to 0.04 N·m) under a constant
    applied torque: the observer's g J_n θ̇ terms and the model's velocity terms leave the
    applied torque; without J_n the inertial torque shows in the estimate."""
    t = np.arange(0.0, 4.0, SERVO_PERIOD)
    w, amp = np.pi, 0.3
    q, qd, qdd = (np.tile(POSE, (len(t), 1)), np.zeros((len(t), 4)), np.zeros((len(t), 4)))
    q[:, SHOULDER] += amp * np.sin(w * t)
    qd[:, SHOULDER] = amp * w * np.cos(w * t)
    qdd[:, SHOULDER] = -amp * w * w * np.sin(w * t)
    tau_m = np.array([rnea(OMX, *k)[SHOULDER] for k in zip(q, qd, qdd, strict=True)]) - APPLIED
    known = known_torques(OMX, SHOULDER, q, qd)
    j_n = float(mass_matrix(OMX, POSE)[SHOULDER, SHOULDER])
    late = t >= 1.0

    def error(jn: float) -> float:
        est = -rtob_series(t, qd[:, SHOULDER], tau_m, known, j_n=jn, g_reac=SERVO_G)
        return float(np.max(np.abs(est[late] - APPLIED)))

    # 10 ms samples: the sampled LPF's lag is 10 % short of 1/g on the inertial term
    assert error(j_n) < 0.03 * APPLIED
    assert error(0.0) > 0.15 * APPLIED
