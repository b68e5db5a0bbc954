"""The controller exercises: the PD reference model (2.20), the environment impedance (2.7),
the compliance law (2.6) and the disturbance observer (2.36).

Besides single calls, each is run in closed loop: the student's function takes the place
of the lab's own in the same run the lab does (the thesis's chapter-4 line on the
simulated arm, through :class:`~armlab.control.compliance.Laws`; the observer's
torque-driven joint through :func:`~armlab.control.observers.simulate_observers`), and the
run is compared with the lab's own, so a law right at one sample only still fails.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import lru_cache
from typing import Any

import numpy as np

from armlab.control.compliance import Laws, environment_step, pd_reference_accel
from armlab.control.experiments.contact import joint_stiffness, predicted_force, wall_across_line
from armlab.control.experiments.thesis import LineRun, max_angle_error, run_line
from armlab.control.laws import compliance_accel
from armlab.control.observers import (
    ObserverState,
    TorqueJoint,
    disturbance_observer,
    lpf_gain,
    simulate_observers,
)
from armlab.control.params import DEFAULT, PRESETS, Params
from armlab.control.trajectory import thesis_line
from armlab.exercises.core import Exercise, Mistake, RunCase, ValueCase
from armlab.exercises.student import CheckedLaw
from armlab.kinematics import SerialChain, load_robot
from armlab.kinematics.hand_statics import GRIPPER_KT
from armlab.kinematics.stiffness import cartesian_compliance, cartesian_stiffness

#: Closed-loop runs: the student's joint angles may differ from the lab's by this much, rad
#: (a tenth of a degree: the servos' goal is whole position units of 0.29°, so a goal a
#: hair different may land one unit off for a sample).
RUN_ANGLE_TOL = math.radians(0.1)
#: The thesis's own gains (ch. 4) and its Table 4.1 / conclusion environment.
THESIS = PRESETS["thesis Table 4.1"]
CONCLUSION = PRESETS["thesis conclusion"]
#: The push of the closed-loop compliance runs, N (the lab's chapter-4 default).
PUSH_N = 3.0


@lru_cache(maxsize=1)
def _arm() -> SerialChain:
    arm = load_robot("receptionist_arm")
    assert isinstance(arm, SerialChain)
    return arm


def _sim(model: SerialChain, **kw: Any) -> Any:
    from armlab.hardware.families.dynamixel1.sim_backend import SimBackend

    return SimBackend(model, **kw)


def _line(params: Params, controller: str, push_n: float, laws: Laws | None) -> LineRun:
    return run_line(_arm(), _sim, params, controller=controller, push_n=push_n, laws=laws)


@lru_cache(maxsize=8)
def _reference_line(params: Params, controller: str, push_n: float) -> LineRun:
    return _line(params, controller, push_n, None)


def _compare_lines(law: CheckedLaw, laws: Laws, params: Params, controller: str,
                   push_n: float) -> str:
    """Run the chapter-4 line with ``laws`` and compare with the lab's own run."""
    ref = _reference_line(params, controller, push_n)
    ref_err = np.degrees(max_angle_error(ref)).round(2).tolist()
    try:
        run = _line(params, controller, push_n, laws)
    except Exception as exc:  # the loop stopped: the student's error, or a fault it saw
        law.raise_error()
        if not isinstance(exc, ValueError):
            raise
        return (f"{exc} (the lab's own law ran the same line with max angle error "
                f"{ref_err}°)")
    law.raise_error()
    m = min(len(run.snapshot["t"]), len(ref.snapshot["t"]))
    gap = np.nanmax(np.abs(run.snapshot["q"][:m] - ref.snapshot["q"][:m]))
    err = np.degrees(max_angle_error(run)).round(2).tolist()
    if not math.isfinite(gap) or gap > RUN_ANGLE_TOL:
        k = int(np.nanargmax(np.max(np.abs(run.snapshot["q"][:m] - ref.snapshot["q"][:m]),
                                    axis=1)))
        return (f"the arm's angles left the lab's own run by {math.degrees(gap):.3g}° at "
                f"t = {ref.snapshot['t'][k]:.3f} s (tolerance {math.degrees(RUN_ANGLE_TOL):g}°);"
                f" max angle error {err}° where the lab's law gives {ref_err}°")
    return ""


def _line_case(name: str, params: Params, controller: str, push_n: float, law_name: str,
               field: str, shape: Callable[[tuple[Any, ...]], tuple[int, ...]]) -> RunCase:
    def run(fn: Callable[..., Any]) -> str:
        law = CheckedLaw(fn, law_name, shape)
        p = replace(params, law="2.6")
        return _compare_lines(law, Laws.with_student(field, law), p, controller, push_n)
    return RunCase(name, run)


def _joints(args: tuple[Any, ...]) -> tuple[int, ...]:
    return np.shape(args[2])


# ---------------------------------------------------------------------------
# State carried from call to call: the function called in sequence, its own returned
# state fed to its next call, the whole sequence compared with the lab's


def _sequence_case(name: str, law_name: str, step: Callable[..., Any],
                   calls: Sequence[Callable[..., tuple[Any, ...]]], state0: Any,
                   state_of: Callable[[np.ndarray], Any], shape: tuple[int, ...],
                   labels: tuple[str, ...], n_state: int, stuck_hint: str, own_hint: str, *,
                   rtol: float = 1e-7, atol: float = 1e-12) -> RunCase:
    """A case that calls the function ``len(calls)`` times in a row: call ``k``'s
    arguments are ``calls[k](state)`` with the state the previous call returned
    (``state_of`` its output, whose first ``n_state`` rows of ``labels`` are the state;
    ``state0`` first), for the student as for the lab's ``step``. The first call whose
    output leaves the lab's fails, with the hint that fits (:func:`_carry_hint`)."""

    def close(a: Any, b: Any) -> bool:
        return bool(np.allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float),
                                rtol=rtol, atol=atol))

    def run(fn: Callable[..., Any]) -> str:
        law = CheckedLaw(fn, law_name, shape)
        ref_state, mine_state = state0, state0
        for k, make in enumerate(calls):
            want = np.array(step(*make(ref_state)), dtype=float)
            got = np.asarray(law(*make(mine_state)), dtype=float)
            if not close(got, want):
                g, w = got.reshape(len(labels), -1), want.reshape(len(labels), -1)
                bad = int(np.argmax(np.abs(g - w).max(axis=1)))
                hint = _carry_hint(law, make, mine_state, g, w, labels, n_state, close,
                                   stuck_hint, own_hint)
                return (f"call {k + 1} of {len(calls)} in a row (each given the state the "
                        f"call before returned): {labels[bad]} is "
                        f"{np.round(g[bad], 9).tolist()}, the lab's "
                        f"{np.round(w[bad], 9).tolist()}; {hint}")
            ref_state, mine_state = state_of(want), state_of(got)
        return ""

    return RunCase(name, run)


def _carry_hint(law: CheckedLaw, make: Callable[[Any], tuple[Any, ...]], state: Any,
                got: np.ndarray, want: np.ndarray, labels: tuple[str, ...], n_state: int,
                close: Callable[[Any, Any], bool], stuck_hint: str, own_hint: str) -> str:
    """Why a call of a sequence is off, when the state carried explains it (each call
    before it was right, so the state it was given is the lab's): the function keeps a
    state of its own (two calls alike differ, or the state passed in changes nothing);
    the state comes back as it went in; a new state is another of the lab's outputs;
    else the step itself is off."""
    given = np.asarray(state, dtype=float).reshape(n_state, -1)
    again = np.asarray(law(*make(state)), dtype=float).reshape(got.shape)
    moved = np.asarray(law(*make(_nudged(state))), dtype=float).reshape(got.shape)
    if not close(again, got) or close(moved, got):
        return f"hint (state from call to call): {own_hint}"
    if close(got[:n_state], given) and not close(want[:n_state], given):
        return f"hint (state from call to call): {stuck_hint}"
    for i in range(n_state):
        for j in range(len(labels)):
            if j != i and close(got[i], want[j]) and not close(got[i], want[i]) \
                    and not close(want[i], want[j]):
                return (f"hint (state from call to call): your new {labels[i]} is the lab's "
                        f"{labels[j]}: return the new {labels[i]}, which the next call is "
                        "given")
    return ("the state carried was right up to this call: the step itself is off for these "
            "arguments")


def _nudged(state: Any) -> Any:
    """``state`` (a number or a tuple of arrays) moved a little."""
    if isinstance(state, tuple):
        return tuple(np.asarray(x, dtype=float) + 1e-3 for x in state)
    return float(state) + 1e-3


# ---------------------------------------------------------------------------
# PD reference model, eq. 2.20


def _pd_cases() -> list[ValueCase | RunCase]:
    rng = np.random.default_rng(220)
    q_cmd, qd_cmd = np.array([0.8, 0.0, 2.5]), np.array([0.1, 0.0, -0.3])
    q, qd = np.array([0.75, 0.01, 2.6]), np.array([0.05, -0.02, 0.0])
    cases: list[ValueCase | RunCase] = [
        ValueCase("thesis ch. 4 gains Kp = 3.8, Kv = 0.2", (3.8, 0.2, q_cmd, qd_cmd, q, qd)),
        ValueCase("the thesis's conclusion Kv = 0.02", (3.8, 0.02, q_cmd, qd_cmd, q, qd)),
        ValueCase("zero gains: no acceleration", (0.0, 0.0, q_cmd, qd_cmd, q, qd)),
        ValueCase("on the command: no acceleration", (10.0, 2.0, q_cmd, qd_cmd, q_cmd, qd_cmd)),
        ValueCase("one joint, plain floats", (20.0, 5.0, 0.3, 0.0, 0.1, 0.2)),
    ]
    for k in range(1, 4):
        cases.append(ValueCase(f"random state {k}", (
            rng.uniform(0, 50), rng.uniform(0, 10), *rng.normal(0, 1, (4, 3)))))
    cases.append(_line_case("closed loop: the thesis's 20 cm line, PD, on the simulated arm",
                            DEFAULT, "pd", 0.0, "pd_reference_accel", "pd", _joints))
    return cases


PD = Exercise(
    name="pd_reference",
    title="the PD reference model's acceleration (thesis 000, eq. 2.20)",
    function="pd_reference_accel",
    reference=pd_reference_accel,
    mistakes=(
        Mistake("swapped gains", "Kp multiplies the position error, Kv the speed error",
                lambda kp, kv, *a: pd_reference_accel(kv, kp, *a)),
        Mistake("a sign", "the error is command minus measured: θ_cmd − θ",
                lambda kp, kv, *a: -pd_reference_accel(kp, kv, *a)),
        Mistake("a missing term", "the speed term Kv (θ̇_cmd − θ̇) is missing",
                lambda kp, kv, *a: pd_reference_accel(kp, 0.0, *a)),
        Mistake("degrees for radians", "the angles are in radians: do not convert the "
                "errors to degrees", lambda *a: np.degrees(pd_reference_accel(*a))),
    ),
    cases=_pd_cases,
    teaches="The reference model a PD position loop makes of the servo (eq. 2.3), and how "
            "Kp and Kv set its natural frequency and damping (eq. 2.11–2.12).",
    lesson="compliance (controller PD, Step test; `armlab experiment step`, `armlab "
           "experiment thesis-line --controller pd`)",
)


# ---------------------------------------------------------------------------
# Environment impedance, eq. 2.7


def _env_explicit(m, d, k, kf, tau, q, qd, dt):
    qdd = (kf * tau - d * qd - k * q) / m
    return q + dt * qd, qd + dt * qdd, qdd


def _env_cases() -> list[ValueCase | RunCase]:
    rng = np.random.default_rng(27)
    tau = np.array([-0.2, 0.05, 0.4])
    q, qd = np.array([0.01, -0.02, 0.0]), np.array([0.1, 0.0, -0.05])
    t41 = (THESIS.m_env, THESIS.d_env, THESIS.k_env, THESIS.k_f)
    end = (CONCLUSION.m_env, CONCLUSION.d_env, CONCLUSION.k_env, CONCLUSION.k_f)
    steady = THESIS.k_f * tau / THESIS.k_env
    cases: list[ValueCase | RunCase] = [
        ValueCase("thesis Table 4.1 (M 1, D 5, K 12, K_f 0.3), 16 ms", (*t41, tau, q, qd, 0.016)),
        ValueCase("thesis conclusion (M 9, D 5, K 9, K_f 0.2), 16 ms", (*end, tau, q, qd, 0.016)),
        ValueCase("at rest, no torque: stays at rest",
                  (*t41, np.zeros(3), np.zeros(3), np.zeros(3), 0.016)),
        ValueCase("at the static offset K_f τ / K_env: stays there",
                  (*t41, tau, steady, np.zeros(3), 0.016)),
        ValueCase("zero stiffness K_env = 0", (1.0, 5.0, 0.0, 0.3, tau, q, qd, 0.016)),
        ValueCase("one joint, plain floats", (2.0, 3.0, 10.0, 0.5, 0.3, 0.01, -0.2, 0.001)),
    ]
    for k in range(1, 3):
        cases.append(ValueCase(f"random state {k}", (
            rng.uniform(0.5, 5), rng.uniform(0, 10), rng.uniform(0, 20), rng.uniform(0, 2),
            *rng.normal(0, 0.3, (3, 3)), 0.016)))
    cases.append(_line_case(
        "closed loop: the 20 cm line with a 3 N push, compliance (law 2.6), simulated arm",
        DEFAULT, "compliance", PUSH_N, "environment_step", "environment",
        lambda a: (3, *np.shape(a[4]))))
    cases.append(_env_sequence_case())
    return cases


#: the torques of the environment's sequence case: a push on, then off, N·m
ENV_SEQUENCE_TAU = (np.array([0.0, 0.0, 0.0]),) * 3 + (np.array([0.4, -0.2, 0.1]),) * 20 \
    + (np.array([0.0, 0.0, 0.0]),) * 12


def _env_sequence_case() -> RunCase:
    """30-odd samples of eq. 2.7 in a row, θ_env and θ̇_env fed back from each call."""
    m, d, k, kf = THESIS.m_env, THESIS.d_env, THESIS.k_env, THESIS.k_f

    calls = [lambda st, tau=tau: (m, d, k, kf, tau, st[0], st[1], 0.016)
             for tau in ENV_SEQUENCE_TAU]
    return _sequence_case(
        f"in sequence: a push on then off, {len(calls)} samples, θ_env and θ̇_env fed back "
        "from each call to the next (from an offset, moving)", "environment_step",
        environment_step, calls,
        (np.array([0.01, -0.02, 0.0]), np.array([0.1, 0.0, -0.05])),
        lambda out: (out[0], out[1]), (3, 3),
        ("θ_env", "θ̇_env", "θ̈_env"), 2,
        "your θ_env and θ̇_env come back as they went in: return the new ones (θ̇ + dt θ̈, "
        "then θ + dt θ̇), which the next call is given",
        "your function does not work from the θ_env and θ̇_env it is given (a state of "
        "its own, or one that starts again each call): step from the arguments alone",
        rtol=1e-9, atol=1e-12)


ENVIRONMENT = Exercise(
    name="environment_impedance",
    title="one step of the virtual environment impedance (thesis 000, eq. 2.7)",
    function="environment_step",
    reference=environment_step,
    mistakes=(
        Mistake("order of the updates", "semi-implicit Euler: first θ̇ += dt θ̈, then θ += "
                "dt θ̇ with the *new* θ̇", _env_explicit),
        Mistake("a sign", "the torque drives the offset: M θ̈ + D θ̇ + K θ = +K_f τ_ext",
                lambda m, d, k, kf, *a: environment_step(m, d, k, -kf, *a)),
        Mistake("swapped gains", "D_env multiplies θ̇_env and K_env multiplies θ_env",
                lambda m, d, k, *a: environment_step(m, k, d, *a)),
        Mistake("a missing term", "divide by M_env: θ̈ = (K_f τ − D θ̇ − K θ) / M",
                lambda m, *a: environment_step(1.0, *a)),
    ),
    cases=_env_cases,
    teaches="A virtual mass-spring-damper turns a measured torque into a position offset; "
            "its static gain K_f/K_env is the arm's compliance.",
    lesson="compliance (Push the hand: τ_ext and θ_env in the charts)",
)


# ---------------------------------------------------------------------------
# Compliance law, eq. 2.6


def _compliance_cases() -> list[ValueCase | RunCase]:
    rng = np.random.default_rng(26)
    q_cmd, qd_cmd = np.array([0.8, 0.0, 2.5]), np.array([0.1, 0.0, -0.3])
    q, qd = np.array([0.75, 0.01, 2.6]), np.array([0.05, -0.02, 0.0])
    env = (np.array([0.02, 0.0, -0.05]), np.array([0.1, 0.0, -0.2]),
           np.array([-0.5, 0.0, 1.0]))
    cases: list[ValueCase | RunCase] = [
        ValueCase("thesis gains, the hand pushed", (3.8, 0.2, q_cmd, qd_cmd, q, qd, *env)),
        ValueCase("no environment offset: eq. 2.20",
                  (3.8, 0.2, q_cmd, qd_cmd, q, qd, *np.zeros((3, 3)))),
        ValueCase("zero gains: only −θ̈_env", (0.0, 0.0, q_cmd, qd_cmd, q, qd, *env)),
        ValueCase("one joint, plain floats", (20.0, 5.0, 0.3, 0.0, 0.1, 0.2, 0.05, 0.1, -0.4)),
    ]
    for k in range(1, 4):
        cases.append(ValueCase(f"random state {k}", (
            rng.uniform(0, 50), rng.uniform(0, 10), *rng.normal(0, 1, (7, 3)))))
    cases.append(_line_case(
        "closed loop: the 20 cm line with a 3 N push, compliance, simulated arm",
        DEFAULT, "compliance", PUSH_N, "compliance_accel", "compliance", _joints))
    return cases


COMPLIANCE = Exercise(
    name="compliance_law",
    title="the compliance controller's acceleration (thesis 000, eq. 2.6)",
    function="compliance_accel",
    reference=compliance_accel,
    mistakes=(
        Mistake("a sign", "the offset is subtracted: θ_cmd − θ − θ_env (the arm yields "
                "with the push)", lambda kp, kv, qc, qdc, q, qd, e, ed, edd: compliance_accel(
                    kp, kv, qc, qdc, q, qd, -e, -ed, edd)),
        Mistake("a missing term", "the last term −θ̈_env is missing",
                lambda *a: compliance_accel(*a[:8], 0.0 * np.asarray(a[8]))),  # type: ignore[call-arg]  # a's 9 arguments: the first 8, then the 9th zeroed
        Mistake("swapped gains", "Kp multiplies the position error, Kv the speed error",
                lambda kp, kv, *a: compliance_accel(kv, kp, *a)),
        Mistake("a missing term", "the speed error is θ̇_cmd − θ̇ − θ̇_env: θ̇_env is missing",
                lambda kp, kv, qc, qdc, q, qd, e, ed, edd: compliance_accel(
                    kp, kv, qc, qdc, q, qd, e, 0.0 * np.asarray(ed), edd)),
    ),
    cases=_compliance_cases,
    teaches="Compliance as a moved reference: the PD loop follows θ_cmd − θ_env, so the arm "
            "gives way to a push as the virtual environment says.",
    lesson="compliance (push with compliance on and off, law 2.6 vs 2.26; `armlab "
           "experiment thesis-line --controller compliance`)",
)


# ---------------------------------------------------------------------------
# Disturbance observer, eq. 2.36


def observer_step(z: float, current: float, qd: float, j_n: float, kt_n: float,
                  g_dis: float, dt: float) -> tuple[float, float]:
    """Reference: one sample of the lab's disturbance observer (thesis eq. 2.36 with the
    LPF of fig. 2.7–2.8), its filter state passed in and out."""
    state = ObserverState(z)
    tau = disturbance_observer(state, current, qd, j_n=j_n, kt_n=kt_n, g_dis=g_dis, dt=dt)
    return state.z, tau


def _obs_euler_gain(z, current, qd, j_n, kt_n, g, dt):
    u = kt_n * current + g * j_n * qd
    z = z + g * dt * (u - z)
    return z, z - g * j_n * qd


def _obs_sign(z, current, qd, j_n, kt_n, g, dt):
    u = kt_n * current - g * j_n * qd
    z = z + lpf_gain(g, dt) * (u - z)
    return z, z + g * j_n * qd


@lru_cache(maxsize=1)
def _reference_observer_run() -> Any:
    return _observer_run(None)


def _observer_run(observer: Callable[..., float] | None) -> Any:
    return simulate_observers(TorqueJoint(), lambda t: 0.003 if t >= 0.05 else 0.0,
                              duration=0.25, compensate=True, observer=observer)


def _observer_closed_loop(fn: Callable[..., Any]) -> str:
    law = CheckedLaw(fn, "observer_step", (2,))

    def observer(state: ObserverState, current: float, qd: float, *, j_n: float, kt_n: float,
                 g_dis: float, dt: float) -> float:
        state.z, tau = law(state.z, current, qd, j_n, kt_n, g_dis, dt)
        return float(tau)

    ref = _reference_observer_run()
    try:
        run = _observer_run(observer)
    except (ArithmeticError, ValueError) as exc:  # the joint's simulation blew up
        law.raise_error()
        return (f"with your observer feeding the disturbance back, the joint's simulation "
                f"diverged ({exc}); with the lab's it ends {0.5 - ref.q[-1]:.3g} rad from "
                "its command")
    law.raise_error()
    gap_q = float(np.max(np.abs(run.q - ref.q)))
    gap_tau = float(np.max(np.abs(run.tau_dis_hat - ref.tau_dis_hat)))
    if gap_q > 1e-7 or gap_tau > 1e-7 or not math.isfinite(gap_q + gap_tau):
        return (f"with your observer feeding the disturbance back, the joint's angle left the "
                f"lab's run by {gap_q:.3g} rad and the estimate by {gap_tau:.3g} N·m "
                f"(tolerance 1e-07); the final angle error is {0.5 - run.q[-1]:.3g} rad, "
                f"the lab's {0.5 - ref.q[-1]:.3g} rad")
    return ""


def _observer_cases() -> list[ValueCase | RunCase]:
    rng = np.random.default_rng(236)
    j = TorqueJoint()
    nominal = dict(j_n=j.inertia, kt_n=GRIPPER_KT)
    cases: list[ValueCase | RunCase] = [
        ValueCase("gripper motor, g = 200 rad/s, 0.1 ms, from rest",
                  (0.0, 0.2, 0.0, *nominal.values(), 200.0, 1e-4), rtol=1e-7, atol=1e-12),
        ValueCase("gripper motor, moving", (1e-3, 0.5, 3.0, *nominal.values(), 200.0, 1e-4),
                  rtol=1e-7, atol=1e-12),
        ValueCase("cut-off g = 0: the estimate stays put",
                  (2e-3, 0.5, 3.0, *nominal.values(), 0.0, 1e-4), rtol=1e-7, atol=1e-12),
        ValueCase("a long sample, g dt = 5", (1e-3, 0.5, 3.0, *nominal.values(), 500.0, 0.01),
                  rtol=1e-7, atol=1e-12),
    ]
    for k in range(1, 4):
        cases.append(ValueCase(f"random state {k}", (
            rng.normal(0, 0.01), rng.normal(0, 1), rng.normal(0, 5), rng.uniform(1e-5, 1e-4),
            rng.uniform(5e-3, 2e-2), rng.uniform(50, 500), rng.uniform(1e-4, 1e-3)),
            rtol=1e-7, atol=1e-12))
    cases.append(RunCase("closed loop: the observer's estimate fed back on the torque-driven "
                         "joint, a 3 mN·m load step", _observer_closed_loop))
    cases.append(_observer_sequence_case())
    return cases


#: the currents and speeds of the observer's sequence case: a current step, the joint
#: speeding up (A, rad/s)
OBSERVER_SEQUENCE = tuple((0.0 if k < 3 else 0.4, 0.05 * max(0, k - 3)) for k in range(40))


def _observer_sequence_case() -> RunCase:
    """40 samples of the observer in a row, its filter state z fed back from each call."""
    j = TorqueJoint()
    j_n, kt_n, g, dt = j.inertia, GRIPPER_KT, 200.0, 1e-4

    calls = [lambda z, i=i, w=w: (z, i, w, j_n, kt_n, g, dt) for i, w in OBSERVER_SEQUENCE]
    return _sequence_case(
        f"in sequence: a current step, {len(calls)} samples, the filter state z fed back "
        "from each call to the next (from z = 2e-3)", "observer_step", observer_step,
        calls, 2e-3,
        lambda out: float(out[0]), (2,), ("z (the filter's state)", "τ_dis (the estimate)"),
        1, "your z comes back as it went in: return the filter's new state z + a (u − z), "
        "which the next call is given",
        "your function does not filter from the z it is given (a state of its own, or "
        "one that starts again each call): z + a (u − z) with the z passed in")


OBSERVER = Exercise(
    name="disturbance_observer",
    title="one sample of the disturbance observer (thesis 000, eq. 2.36, fig. 2.7–2.8)",
    function="observer_step",
    reference=observer_step,
    mistakes=(
        Mistake("a missing term", "the estimate is the filter's output minus g J_n θ̇",
                lambda *a: (observer_step(*a)[0],) * 2),
        Mistake("a sign", "the filter's input is K_tn I + g J_n θ̇, and g J_n θ̇ is then "
                "subtracted", _obs_sign),
        Mistake("the filter's gain", "the sampled LPF g/(s + g) has the gain "
                "a = 1 − exp(−g dt), not g dt", _obs_euler_gain),
        Mistake("a missing term", "the motor's torque is K_tn I: multiply the current by K_tn",
                lambda z, i, qd, j_n, kt_n, g, dt: observer_step(z, i / kt_n, qd, j_n, kt_n,
                                                                 g, dt)),
    ),
    cases=_observer_cases,
    teaches="Estimating every unmodelled torque from the current and the speed alone, "
            "through a low-pass filter instead of differentiating θ̇.",
    lesson="`armlab experiment observers` (a simulation lesson: the RX-24F takes no "
           "current command); hand (current-driven fingers)",
)

# ---------------------------------------------------------------------------
# The hand's stiffness from the joints' (the contact lesson's prediction)


def hand_stiffness(J: np.ndarray, K_q: np.ndarray) -> np.ndarray:
    """Reference: K_x = (J K_q⁻¹ Jᵀ)⁻¹ (:func:`armlab.kinematics.stiffness.cartesian_stiffness`)."""
    return cartesian_stiffness(J, K_q)


def _stiffness_cases() -> list[ValueCase]:
    arm = load_robot("receptionist_arm")
    line = thesis_line(arm)
    q_line = line.q[0]
    J = arm.jacobian(q_line)[:3]
    k_q = joint_stiffness(DEFAULT, "compliance")  # 4 N·m/rad: K_env 12 / K_f 3
    assert k_q is not None
    # the contact experiment's wall across the line, pressed 2 cm deep
    _, _, _, normal = wall_across_line(arm, q_line, line.q[-1], 0.04)
    depth, k_wall = 0.02, 2e4
    force = predicted_force(arm, q_line, normal, depth, k_joint=k_q, k_wall=k_wall)

    def presses(out: np.ndarray) -> str:
        """The contact experiment's steady force from the student's K_x."""
        if out.shape != (3, 3) or not np.all(np.isfinite(out)):
            return f"expected a finite (3, 3) matrix, got shape {out.shape}"
        try:
            f = depth / (float(normal @ np.linalg.solve(out, normal)) + 1.0 / k_wall)
        except np.linalg.LinAlgError:
            return "your K_x is singular: it has no inverse to press the wall through"
        if not math.isclose(f, force, rel_tol=1e-6):
            return (f"pressing 2 cm into a 2·10⁴ N/m wall along n, your K_x gives "
                    f"f = d / (nᵀ K_x⁻¹ n + 1/k) = {f:.4g} N; the lab predicts {force:.4g} N")
        return ""

    planar = load_robot("redundant_planar")
    q_planar = np.array([0.4, -0.7, 0.9])
    near = np.array([0.3, 0.2, 0.02])  # the elbow 1° from stretched: stiff along the arm
    rng = np.random.default_rng(2026)
    cases = [
        ValueCase("the thesis line's start, K_q = K_env / K_f = 4 N·m/rad on every joint",
                  (J, k_q * np.eye(3)), rtol=1e-7, atol=1e-9),
        ValueCase("joints of different stiffness, K_q = diag(2, 8, 4)",
                  (J, np.diag([2.0, 8.0, 4.0])), rtol=1e-7, atol=1e-9),
        ValueCase("seed 002's redundant planar 3R: a (2, 3) J, K_q = I (three joints hold "
                  "two directions)", (planar.jacobian(q_planar)[:2], np.eye(3)),
                  rtol=1e-7, atol=1e-9),
        ValueCase("the elbow 1° from stretched: far stiffer along the arm than across it",
                  (arm.jacobian(near)[:3], k_q * np.eye(3)), rtol=1e-6, atol=1e-6),
        ValueCase("the contact experiment's prediction: pressed 2 cm into the wall, "
                  f"f = {force:.3g} N", (J, k_q * np.eye(3)), check=presses),
    ]
    for k in range(1, 3):
        q = rng.uniform(arm.lower, arm.upper)
        A = rng.normal(0.0, 1.0, (3, 3))
        cases.append(ValueCase(f"random pose and a full joint stiffness {k}",
                               (arm.jacobian(q)[:3], A @ A.T + 2.0 * np.eye(3)),
                               rtol=1e-7, atol=1e-9))
    return cases


STIFFNESS = Exercise(
    name="hand_stiffness",
    title="the hand's stiffness from the joints': K_x = (J K_q⁻¹ Jᵀ)⁻¹ (contact; thesis "
          "000, eq. 2.6 with 2.7 at rest)",
    function="hand_stiffness",
    reference=hand_stiffness,
    mistakes=(
        Mistake("the compliance for the stiffness", "J K_q⁻¹ Jᵀ is the hand's compliance "
                "(m/N); the stiffness is its inverse",
                lambda J, K: cartesian_compliance(J, K)),
        Mistake("the joint stiffness pushed through J", "a stiffness does not map as "
                "J K_q Jᵀ: a force f needs τ = Jᵀ f, which moves the joints by K_q⁻¹ τ and "
                "the hand by J K_q⁻¹ Jᵀ f; invert that",
                lambda J, K: np.asarray(J) @ np.asarray(K) @ np.asarray(J).T),
        Mistake("J and Jᵀ swapped", "J K_q⁻¹ Jᵀ: J on the left (a row per direction of the "
                "hand), Jᵀ on the right",
                lambda J, K: np.linalg.inv(np.asarray(J).T @ np.linalg.solve(
                    np.asarray(K), np.asarray(J)))),
    ),
    cases=_stiffness_cases,
    teaches="How stiff the hand is, each way, when every joint holds with the compliance "
            "law's K_env / K_f: stiff along a stretched arm, soft across it, and the force "
            "a command behind a wall presses with.",
    lesson="compliance (Contact tab; `armlab experiment contact`)",
)
