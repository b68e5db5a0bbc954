"""The kinematics exercises: thesis FK and Jacobian, one RMRC step, seed 004's planar IK,
seed 003's leg IK and seed 002's null-space step.

Each reference is the lab's own implementation (armlab.kinematics) behind the student's
signature; the planted mistakes are that reference with one common mistake made.
"""

from __future__ import annotations

import math
from functools import cache, lru_cache

import numpy as np

from armlab.control.experiments.seed004_data import TABLE1
from armlab.control.trajectory import THESIS_LINE_START, THESIS_Q_GUESS
from armlab.exercises.core import Exercise, Mistake, RunCase, ValueCase
from armlab.exercises.student import CheckedLaw
from armlab.kinematics import SerialChain, load_robot
from armlab.kinematics import planar_ik as p4
from armlab.kinematics.catalog import RECEPTIONIST_PRESETS
from armlab.kinematics.ik import (
    MAX_HALVINGS,
    damped_inverse,
    halved_step,
    inverse_error,
    jacobian_inverse,
    joint_update,
    pseudo_inverse,
    rmrc,
)
from armlab.kinematics.leg_ik import LegGeometry, leg_fk
from armlab.kinematics.leg_ik import leg_ik as lab_leg_ik
from armlab.kinematics.redundancy import (
    CircleTask,
    gradient_projection,
    limit_violation,
    simulate_circle,
)

#: Link lengths (L1, L2) of the receptionist arm's presets, m.
ARM_LENGTHS = {"18.5/25": (0.185, 0.25), "18.5/18.5": (0.185, 0.185), "17/25": (0.17, 0.25)}
assert set(ARM_LENGTHS) == set(RECEPTIONIST_PRESETS)


@cache
def thesis_arm(L1: float, L2: float) -> SerialChain:
    """The receptionist arm with links L1, L2 (m): one of the thesis's three presets."""
    for name, (a, b) in ARM_LENGTHS.items():
        if abs(a - L1) < 1e-9 and abs(b - L2) < 1e-9:
            arm = load_robot("receptionist_arm", preset=name)
            assert isinstance(arm, SerialChain)
            return arm
    raise ValueError(f"no receptionist-arm preset has L1 = {L1} m, L2 = {L2} m")


def _rng(name: str) -> np.random.Generator:
    """The same random cases on every run, a different stream per exercise."""
    return np.random.default_rng(sum(name.encode()))


# ---------------------------------------------------------------------------
# Thesis FK, eq. 3.13


def hand_position(q: np.ndarray, L1: float, L2: float) -> np.ndarray:
    """Reference: thesis eq. 3.13 as the lab computes it (the receptionist arm's FK)."""
    return thesis_arm(L1, L2).fk(np.asarray(q, dtype=float))[:3, 3].copy()


def _fk_missing_l1(q: np.ndarray, L1: float, L2: float) -> np.ndarray:
    t1, t0, _ = np.asarray(q, dtype=float)
    return hand_position(q, L1, L2) - [0.0, L1 * math.cos(t0) * math.sin(t1), 0.0]


def _fk_cases() -> list[ValueCase]:
    arm = thesis_arm(0.185, 0.25)
    q_start = rmrc(arm, THESIS_LINE_START, THESIS_Q_GUESS).q
    cases = [
        ValueCase("thesis ch. 4: the line's first point (-0.11322, 0.07653, 0) m "
                  "(the thesis's -11.322, 7.653, 0 cm)",
                  (q_start, 0.185, 0.25), expected=THESIS_LINE_START, atol=2e-4),
        *(ValueCase(f"stretched arm, q = 0, preset {name}: (L1 + L2, 0, 0)",
                    (np.zeros(3), L1, L2)) for name, (L1, L2) in ARM_LENGTHS.items()),
        ValueCase("at the lower joint limits", (arm.lower.copy(), 0.185, 0.25)),
        ValueCase("at the upper joint limits", (arm.upper.copy(), 0.185, 0.25)),
    ]
    rng = _rng("thesis_fk")
    for k, (L1, L2) in enumerate([*ARM_LENGTHS.values()] * 2, start=1):
        cases.append(ValueCase(f"random pose {k}", (rng.uniform(arm.lower, arm.upper), L1, L2)))
    return cases


FK = Exercise(
    name="thesis_fk",
    title="forward kinematics of the receptionist arm (thesis 000, eq. 3.13)",
    function="hand_position",
    reference=hand_position,
    mistakes=(
        Mistake("degrees for radians", "q is in radians already: do not convert it "
                "(np.cos takes radians)", lambda q, L1, L2: hand_position(np.radians(q), L1, L2)),
        Mistake("joint order", "q is (θ1, θ0, θ2): θ1, about z, comes first, θ0 second",
                lambda q, L1, L2: hand_position(np.asarray(q)[[1, 0, 2]], L1, L2)),
        Mistake("a sign", "z = −L1 s0 − L2 c2 s0: z is negative for θ0 > 0",
                lambda q, L1, L2: hand_position(q, L1, L2) * [1.0, 1.0, -1.0]),
        Mistake("swapped lengths", "L1 is the upper arm, L2 the forearm (x = L1 c0 c1 + ...)",
                lambda q, L1, L2: _swapped_lengths(q, L1, L2)),
        Mistake("a missing term", "y = L2 (c1 s2 + c0 c2 s1) + L1 c0 s1: the upper arm's "
                "term L1 c0 s1 is missing", _fk_missing_l1),
        Mistake("centimetres for metres", "return metres, as L1 and L2 are given (the lab "
                "shows cm, it computes in m): you returned 100 times the position",
                lambda q, L1, L2: 100.0 * hand_position(q, L1, L2)),
    ),
    cases=_fk_cases,
    teaches="The product of transforms of eq. 3.8–3.12 worked out by hand for a 3-joint arm, "
            "and its joint order (θ1 about z, then θ0, then the elbow θ2).",
    lesson="compliance (the receptionist arm: its hand follows eq. 3.13 as the joints move); "
           "arm (joint sliders, the hand's pose, any URDF)",
)


def _swapped_lengths(q: np.ndarray, L1: float, L2: float) -> np.ndarray:
    """Eq. 3.13 with L1 and L2 exchanged, for lengths no preset has swapped."""
    t1, t0, t2 = np.asarray(q, dtype=float)
    c0, s0, c1, s1, c2, s2 = (math.cos(t0), math.sin(t0), math.cos(t1), math.sin(t1),
                              math.cos(t2), math.sin(t2))
    a, b = L2, L1
    return np.array([a * c0 * c1 - b * (s1 * s2 - c0 * c1 * c2),
                     b * (c1 * s2 + c0 * c2 * s1) + a * c0 * s1,
                     -a * s0 - b * c2 * s0])


# ---------------------------------------------------------------------------
# The Jacobian (thesis §3.3)


def hand_jacobian(q: np.ndarray, L1: float, L2: float) -> np.ndarray:
    """Reference: the position rows of the lab's geometric Jacobian (thesis §3.3)."""
    return thesis_arm(L1, L2).jacobian(np.asarray(q, dtype=float))[:3].copy()


def _jacobian_cases() -> list[ValueCase]:
    arm = thesis_arm(0.185, 0.25)
    cases = [
        ValueCase("thesis worked pose q = 0 (stretched, singular): J = [[0,0,0],"
                  "[0.435,0,0.25],[0,-0.435,0]]", (np.zeros(3), 0.185, 0.25),
                  expected=np.array([[0, 0, 0], [0.435, 0, 0.25], [0, -0.435, 0]]),
                  atol=1e-12),
        ValueCase("elbow folded at its limit", (np.array([0.4, 0.3, arm.upper[2]]), 0.185,
                                                0.25)),
        ValueCase("the line's start pose (θ0 = 0)", (THESIS_Q_GUESS.copy(), 0.17, 0.25)),
    ]
    rng = _rng("jacobian")
    for k, (L1, L2) in enumerate([*ARM_LENGTHS.values()] * 2, start=1):
        cases.append(ValueCase(f"random pose {k}", (rng.uniform(arm.lower, arm.upper), L1, L2)))
    return cases


JACOBIAN = Exercise(
    name="jacobian",
    title="the receptionist arm's Jacobian ∂(x, y, z)/∂q (thesis 000, §3.3, eq. 3.17)",
    function="hand_jacobian",
    reference=hand_jacobian,
    mistakes=(
        Mistake("a transposed matrix", "row i is ∂(x, y, z)[i], column j is ∂/∂q[j]: "
                "you returned the transpose", lambda q, L1, L2: hand_jacobian(q, L1, L2).T),
        Mistake("the thesis's column order", "the thesis prints its columns as (θ1, θ2, θ0); "
                "here column j is ∂/∂q[j] with q = (θ1, θ0, θ2)",
                lambda q, L1, L2: hand_jacobian(q, L1, L2)[:, [0, 2, 1]]),
        Mistake("a sign", "every entry has the opposite sign: differentiate x, y, z of "
                "eq. 3.13, not their negatives", lambda q, L1, L2: -hand_jacobian(q, L1, L2)),
        Mistake("degrees for radians", "q is in radians already: do not convert it",
                lambda q, L1, L2: hand_jacobian(np.radians(q), L1, L2)),
    ),
    cases=_jacobian_cases,
    teaches="Differentiating eq. 3.13 by each joint, the column order of J, and where J "
            "loses rank (the stretched arm).",
    lesson="arm (drag the hand target: RMRC steps through J; a stretched arm is singular)",
)


# ---------------------------------------------------------------------------
# One RMRC step with step halving (eq. 3.20-3.22)


def rmrc_step(q: np.ndarray, J: np.ndarray, J_inv: np.ndarray, dX: np.ndarray, e: float,
              lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Reference: the lab's eq. 3.21 (:func:`halved_step`) then eq. 3.22 (:func:`joint_update`);
    more than MAX_HALVINGS halvings: the step is not taken (the lab then damps it)."""
    dX_h, halvings = halved_step(np.asarray(J, float), np.asarray(J_inv, float),
                                 np.asarray(dX, float), e)
    if halvings > MAX_HALVINGS:
        return np.array(q, dtype=float)
    return joint_update(np.asarray(q, float), np.asarray(J_inv, float), dX_h,
                        np.asarray(lower, float), np.asarray(upper, float))


def _rmrc_once(q, J, J_inv, dX, e, lower, upper):
    J, J_inv, dX = (np.asarray(a, float) for a in (J, J_inv, dX))
    if np.linalg.norm(dX - J @ J_inv @ dX) > e:
        dX = 0.5 * dX
    return joint_update(np.asarray(q, float), J_inv, dX, np.asarray(lower), np.asarray(upper))


def _rmrc_allowing(most: int, q, J, J_inv, dX, e, lower, upper):
    """Eq. 3.21-3.22 giving up only after ``most`` halvings (an off-by-one)."""
    dX_h, halvings = halved_step(np.asarray(J, float), np.asarray(J_inv, float),
                                 np.asarray(dX, float), e, max_halvings=most)
    if halvings > most:
        return np.array(q, dtype=float)
    return joint_update(np.asarray(q, float), np.asarray(J_inv, float), dX_h,
                        np.asarray(lower, float), np.asarray(upper, float))


def _rmrc_taken_anyway(q, J, J_inv, dX, e, lower, upper):
    """Eq. 3.21-3.22 with the step taken after MAX_HALVINGS halvings even so."""
    dX_h, _ = halved_step(np.asarray(J, float), np.asarray(J_inv, float),
                          np.asarray(dX, float), e)
    return joint_update(np.asarray(q, float), np.asarray(J_inv, float), dX_h,
                        np.asarray(lower, float), np.asarray(upper, float))


def _rmrc_cases() -> list[ValueCase]:
    arm = thesis_arm(0.185, 0.25)
    planar = load_robot("redundant_planar")
    assert isinstance(planar, SerialChain)
    lo, hi = arm.lower.copy(), arm.upper.copy()
    rng = _rng("rmrc_step")
    cases = []
    for k in range(1, 4):
        q = rng.uniform(lo / 2, hi / 2)
        J = arm.jacobian(q)[:3]
        cases.append(ValueCase(f"exact inverse (eq. 3.20), no halving needed {k}",
                               (q, J, jacobian_inverse(J), rng.normal(0, 0.01, 3), 1e-9, lo, hi)))
    for k, t2 in enumerate((0.05, 0.2), start=1):
        q = np.array([0.3, 0.2, t2])
        J = arm.jacobian(q)[:3]
        cases.append(ValueCase(f"near the stretched singularity, damped inverse: dX halved {k}",
                               (q, J, damped_inverse(J, 0.05), np.array([0.01, -0.02, 0.015]),
                                1e-4, lo, hi)))
    q = np.array([2.5, -0.6, -2.0])
    J = planar.jacobian(q)[:2]
    cases.append(ValueCase("planar 3R arm (2 x 3 J), pseudo-inverse of eq. 3.19",
                           (q, J, pseudo_inverse(J), np.array([0.01, 0.02]), 1e-9,
                            planar.lower.copy(), planar.upper.copy())))
    q = np.array([0.3, 0.2, hi[2] - 0.001])
    J = arm.jacobian(q)[:3]
    J_inv = jacobian_inverse(J)
    dX = J @ np.array([0.02, -0.01, 0.05])  # pushes the elbow past its upper limit
    cases.append(ValueCase("the step pushes the elbow past its limit: clipped",
                           (q, J, J_inv, dX, 1e-9, lo, hi)))
    q = np.array([0.3, 0.2, 0.05])
    J = arm.jacobian(q)[:3]
    J_inv = damped_inverse(J, 0.05)
    dX = np.array([0.01, -0.02, 0.015])
    cases.append(ValueCase(f"e too strict: more than {MAX_HALVINGS} halvings, q unchanged "
                           "(exactly)", (q, J, J_inv, dX, 1e-15, lo, hi), atol=0.0, rtol=0.0))
    err = inverse_error(J, J_inv, dX)  # halving dX halves it exactly (a power of 2)
    for k, what in ((MAX_HALVINGS - 1, "taken"), (MAX_HALVINGS, "taken (the last allowed)"),
                    (MAX_HALVINGS + 1, "given up: q unchanged (exactly)")):
        # e between err/2^k and err/2^(k-1): exactly k halvings bring the error under e
        cases.append(ValueCase(f"a step that needs exactly {k} halvings: {what}",
                               (q, J, J_inv, dX, 1.5 * err * 0.5**k, lo, hi),
                               atol=0.0 if k > MAX_HALVINGS else 1e-15, rtol=0.0))
    q0 = np.zeros(3)
    J0 = arm.jacobian(q0)[:3]  # stretched: rank 2, x (along the arm) out of its reach
    cases.append(ValueCase("the stretched arm (singular J, its pseudo-inverse): dX partly "
                           "along the arm, halved until the error is under e",
                           (q0, J0, np.linalg.pinv(J0), np.array([0.01, 0.02, -0.01]), 1e-9,
                            lo, hi), atol=1e-15, rtol=1e-12))
    cases.append(ValueCase("zero step: q unchanged", (q, J, jacobian_inverse(J), np.zeros(3),
                                                      1e-9, lo, hi)))
    return cases


RMRC_STEP = Exercise(
    name="rmrc_step",
    title="one RMRC step with step halving (thesis 000, eq. 3.20–3.22)",
    function="rmrc_step",
    reference=rmrc_step,
    mistakes=(
        Mistake("a missing step", "the halving of eq. 3.21 is missing: while "
                "|(I − J J_inv) dX| > e, halve dX, then update",
                lambda q, J, J_inv, dX, e, lo, hi: joint_update(
                    np.asarray(q, float), np.asarray(J_inv), np.asarray(dX, float),
                    np.asarray(lo), np.asarray(hi))),
        Mistake("a sign", "eq. 3.22 adds the step: θ + J_inv dX",
                lambda q, J, J_inv, dX, e, lo, hi: rmrc_step(
                    q, J, -np.asarray(J_inv), dX, e, lo, hi)),
        Mistake("a transposed matrix", "use J_inv @ dX (shape (n, m) times (m,)), not its "
                "transpose", lambda q, J, J_inv, dX, e, lo, hi: rmrc_step(
                    q, J, np.asarray(J_inv).T, dX, e, lo, hi)),
        Mistake("a missing clip", "clip the new angles into [lower, upper]",
                lambda q, J, J_inv, dX, e, lo, hi: rmrc_step(
                    q, J, J_inv, dX, e, np.full(len(q), -np.inf), np.full(len(q), np.inf))),
        Mistake("halved once", "halve dX *while* the error exceeds e (a loop), not once",
                _rmrc_once),
        Mistake("a step taken anyway", f"when {MAX_HALVINGS} halvings are not enough the "
                "inverse cannot be trusted: return q unchanged, take no step",
                _rmrc_taken_anyway),
        Mistake("one halving too many", f"{MAX_HALVINGS} halvings are allowed: a step that "
                f"needs a {MAX_HALVINGS + 1}st is given up (q unchanged)",
                lambda *a: _rmrc_allowing(MAX_HALVINGS + 1, *a)),
        Mistake("one halving too few", f"{MAX_HALVINGS} halvings are allowed: a step that "
                f"needs exactly {MAX_HALVINGS} is taken",
                lambda *a: _rmrc_allowing(MAX_HALVINGS - 1, *a)),
    ),
    cases=_rmrc_cases,
    teaches="Resolved motion rate control: why the inverse is checked (eq. 3.21) and the "
            "step halved until it can be trusted, and that joint limits clip the update.",
    lesson="arm (the hand target followed by RMRC); compliance (Run thesis line: each sample "
           "an RMRC solve, `armlab experiment thesis-line`)",
)


# ---------------------------------------------------------------------------
# Seed 004: the planar arm's geometric IK


def planar_ik(X: float, Y: float, l1: float, l2: float, l3: float) -> tuple[float, float, float]:
    """Reference: the lab's seed 004 solver, elbow down, exact angles."""
    return p4.solve(X, Y, arm=p4.PlanarArm(l1, l2, l3), elbow="down").angles


def _planar_typo(X: float, Y: float, l1: float, l2: float, l3: float) -> tuple[float, ...]:
    t0 = math.atan2(Y, X)
    x, y = X * math.cos(t0), Y * math.sin(t0)  # the paper's printed typo
    c2 = min(1.0, max(-1.0, p4.elbow_cosine(x, y, l1, l2)))
    t2 = p4.elbow_angle(c2, "down")
    t1 = p4.shoulder_angle(x, y, t2, l1, l2)
    return t1, t2, p4.wrist_angle(t0, t1, t2)


def _table_check(X1: float, Y1: float):
    def check(got: np.ndarray) -> str:
        if got.shape != (3,):
            return f"expected 3 angles, got shape {got.shape}"
        servo = [p4.round_command(s, "truncate") for s in p4.servo_angles(tuple(got))]
        X, Y, _ = p4.fk(p4.joint_angles(servo))
        if abs(X * 100 - X1) <= 0.01 + 1e-9 and abs(Y * 100 - Y1) <= 0.01 + 1e-9:
            return ""
        return (f"expected the paper's computed point ({X1:.2f}, {Y1:.2f}) cm after the "
                f"servo's whole-degree command, got ({X * 100:.2f}, {Y * 100:.2f}) cm")
    return check


def _planar_cases() -> list[ValueCase]:
    L = (0.065, 0.105, 0.065)
    cases = []
    for no in (*range(1, 6), *range(20, 25)):
        _, X, Y, X1, Y1, *_ = TABLE1[no - 1]
        cases.append(ValueCase(f"seed 004 Table 1 row {no}: target ({X:g}, {Y:g}) cm, judged in cm",
                               (X / 100, Y / 100, *L), check=_table_check(X1, Y1)))
    rng = _rng("planar_ik")
    arm = p4.PlanarArm()
    k = 0
    while k < 4:
        t = (rng.uniform(-math.pi, math.pi), rng.uniform(-2.5, -0.2), 0.0)
        X, Y, _ = p4.fk(t, arm)
        if p4.solve(X, Y).reachable:
            k += 1
            cases.append(ValueCase(f"random reachable target {k}", (X, Y, *L), angles=True))
    cases += [
        ValueCase("stretched along x: (0.235, 0) m", (0.235, 0.0, *L), angles=True, atol=1e-6),
        ValueCase("out of reach (0.30, 0) m: the stretched arm towards it",
                  (0.30, 0.0, *L), angles=True),
        ValueCase("other links (0.10, 0.10, 0.05 m)", (0.12, 0.08, 0.10, 0.10, 0.05), angles=True),
    ]
    return cases


PLANAR_IK = Exercise(
    name="planar_ik",
    title="geometric IK of the planar 3-link arm (seed 004, eq. 1–24)",
    function="planar_ik",
    reference=planar_ik,
    mistakes=(
        Mistake("degrees for radians", "return radians (the lab converts to the servo's "
                "degrees itself)", lambda *a: np.degrees(planar_ik(*a))),
        Mistake("the paper's typo", "the wrist point is (X − l3 cos θ0, Y − l3 sin θ0): the "
                "paper's printed x = X cos θ0 is a typo", _planar_typo),
        Mistake("elbow up", "take the minus root, θ2 = atan2(−√(1 − c2²), c2) (elbow down, "
                "as the paper's table)", lambda X, Y, l1, l2, l3: p4.solve(
                    X, Y, arm=p4.PlanarArm(l1, l2, l3), elbow="up").angles),
        Mistake("a sign", "θ1 = atan2(y, x) − atan2(k2, k1): minus, not plus",
                lambda X, Y, l1, l2, l3: _planar_plus(X, Y, l1, l2, l3)),
    ),
    cases=_planar_cases,
    teaches="Closed-form IK by geometry: fix the hand's orientation, step back to the wrist, "
            "solve two links; and how whole-degree servo commands cost accuracy (Table 1).",
    lesson="ik_accuracy (Run the paper's table; `armlab experiment seed004-table`)",
)


def _planar_plus(X: float, Y: float, l1: float, l2: float, l3: float) -> tuple[float, ...]:
    t0 = math.atan2(Y, X)
    x, y = p4.wrist_point(X, Y, t0, l3)
    c2 = min(1.0, max(-1.0, p4.elbow_cosine(x, y, l1, l2)))
    t2 = p4.elbow_angle(c2, "down")
    k1, k2 = l1 + l2 * math.cos(t2), l2 * math.sin(t2)
    t1 = math.atan2(y, x) + math.atan2(k2, k1)
    return t1, t2, p4.wrist_angle(t0, t1, t2)


# ---------------------------------------------------------------------------
# Seed 003: the leg's IK


def leg_ik(x: float, y: float, z: float, l1: float, l2: float) -> tuple[float, float, float]:
    """Reference: the lab's seed 003 leg IK (the seed's + root)."""
    return lab_leg_ik((x, y, z), LegGeometry(l1, l2)).angles


def _leg_swapped(x: float, y: float, z: float, l1: float, l2: float) -> tuple[float, ...]:
    t1, t2, t3 = leg_ik(x, y, z, l1, l2)
    return math.atan2(y, x), t2, t3


def _leg_cases() -> list[ValueCase]:
    rng = _rng("leg_ik")
    geom = LegGeometry()
    cases = [
        ValueCase("standing foot (0, 0.10, -0.09) m", (0.0, 0.10, -0.09, 0.075, 0.10), angles=True),
        ValueCase("foot forward and low (0.04, 0.08, -0.11) m", (0.04, 0.08, -0.11, 0.075, 0.10),
                  angles=True),
        ValueCase("leg stretched straight out (0.175, 0, 0) m along x",
                  (0.175, 0.0, 0.0, 0.075, 0.10), angles=True, atol=1e-6),
        ValueCase("out of reach (0, 0.30, 0) m: stretched towards it",
                  (0.0, 0.30, 0.0, 0.075, 0.10), angles=True),
    ]
    for k in range(1, 5):
        t = (rng.uniform(-0.8, 0.8), rng.uniform(-0.5, 1.0), rng.uniform(0.3, 2.0))
        x, y, z = leg_fk(t, geom)
        cases.append(ValueCase(f"random foot {k}", (x, y, z, 0.075, 0.10), angles=True))
    cases.append(ValueCase("other links (0.06, 0.12 m)", (0.02, 0.09, -0.08, 0.06, 0.12),
                           angles=True))
    return cases


LEG_IK = Exercise(
    name="leg_ik",
    title="IK of one quadruped leg in atan2 form (seed 003, eq. 3.1–3.9)",
    function="leg_ik",
    reference=leg_ik,
    mistakes=(
        Mistake("swapped atan2 arguments", "θ1 = atan2(x, y): the yaw is measured from the "
                "outward axis y towards x", _leg_swapped),
        Mistake("the other knee", "θ3 = atan2(+√(1 − A²), A): the seed takes the plus root",
                lambda x, y, z, l1, l2: lab_leg_ik((x, y, z), LegGeometry(l1, l2),
                                                   knee=-1).angles),
        Mistake("degrees for radians", "return radians", lambda *a: np.degrees(leg_ik(*a))),
        Mistake("swapped lengths", "l1 is the femur (hip to knee), l2 the tibia",
                lambda x, y, z, l1, l2: leg_ik(x, y, z, l2, l1)),
    ),
    cases=_leg_cases,
    teaches="The same two-link geometry in 3-D: a hip yaw first, then the knee from the law "
            "of cosines, then the hip pitch.",
    lesson="quadruped (the legs follow the sine pattern through this IK; `armlab "
           "experiment seed003-gait`)",
)


# ---------------------------------------------------------------------------
# Seed 002: the null-space step


def joint_rate(J: np.ndarray, xdot: np.ndarray, grad_w: np.ndarray, k_a: float) -> np.ndarray:
    """Reference: the lab's gradient projection (seed 002 eq. 4, the null-space term eq. 6)."""
    return gradient_projection(np.asarray(J, float), xdot, grad_w, k_a)


#: Seed 002's simulation 3 (redundancy, no limits): each joint's worst excursion, rad.
MODE3_VIOLATIONS = np.array([0.0912, 0.2179, 0.2231])


@lru_cache(maxsize=1)
def _circle_reference() -> np.ndarray:
    planar = load_robot("redundant_planar")
    assert isinstance(planar, SerialChain)
    return simulate_circle(planar, "3").q


def _circle_run(fn) -> str:
    planar = load_robot("redundant_planar")
    assert isinstance(planar, SerialChain)
    law = CheckedLaw(fn, "joint_rate", (planar.n,))
    try:
        run = simulate_circle(planar, "3", CircleTask(), projection=law)
    except (ArithmeticError, ValueError) as exc:  # the arm's angles blew up
        law.raise_error()
        return f"the arm's simulation diverged ({exc})"
    law.raise_error()
    viol = limit_violation(run.q, planar.lower, planar.upper)
    ref = _circle_reference()
    gap = float(np.max(np.abs(run.q - ref)))
    if not np.all(np.isfinite(run.q)) or gap > 1e-6:
        return (f"the arm's angles left the lab's own run by up to {gap:.3g} rad "
                f"(tolerance 1e-06); joint excursions beyond the limits "
                f"{np.round(viol, 4).tolist()} rad, the paper's {MODE3_VIOLATIONS.tolist()}")
    if np.max(np.abs(viol - MODE3_VIOLATIONS)) > 2e-3:
        return (f"excursions beyond the joint limits {np.round(viol, 4).tolist()} rad, the "
                f"paper's simulation 3: {MODE3_VIOLATIONS.tolist()}")
    return ""


def _null_full_rank(J, xd, g, k):
    """Seed 002 eq. 4 with J⁺ written as Jᵀ(JJᵀ)⁻¹ (right only at full rank)."""
    J = np.asarray(J, float)
    J_plus = J.T @ np.linalg.inv(J @ J.T)
    return J_plus @ xd + (np.eye(J.shape[1]) - J_plus @ J) @ (k * np.asarray(g, float))


def _null_cases() -> list[ValueCase | RunCase]:
    planar = load_robot("redundant_planar")
    assert isinstance(planar, SerialChain)
    rng = _rng("null_space_step")
    cases: list[ValueCase | RunCase] = []
    for k in range(1, 5):
        q = rng.uniform(planar.lower, planar.upper)
        cases.append(ValueCase(f"planar 3R arm, random pose {k}",
                               (planar.jacobian(q)[:2], rng.normal(0, 0.3, 2),
                                rng.normal(0, 1.0, 3), 200.0)))
    q0 = np.array([np.pi, -np.pi / 2, -np.pi / 2])
    cases += [
        ValueCase("k_a = 0: the minimum-norm J⁺ẋ alone",
                  (planar.jacobian(q0)[:2], np.array([0.1, -0.2]), np.array([1.0, 2.0, 3.0]),
                   0.0)),
        ValueCase("ẋ = 0: pure self-motion (the hand stays put)",
                  (planar.jacobian(q0)[:2], np.zeros(2), np.array([0.5, -1.0, 0.3]), 200.0)),
        ValueCase("the stretched arm turned 0.4 rad (J has rank 1: J⁺ is not Jᵀ(JJᵀ)⁻¹)",
                  (planar.jacobian(np.array([0.4, 0.0, 0.0]))[:2], np.array([0.1, -0.2]),
                   np.array([0.5, -1.0, 0.3]), 200.0), atol=1e-9, rtol=1e-9),
        ValueCase("the stretched arm along x (J's x row is zero, rank 1)",
                  (planar.jacobian(np.zeros(3))[:2], np.array([0.0, 0.3]),
                   np.array([0.5, -1.0, 0.3]), 200.0)),
        ValueCase("a 2 x 4 Jacobian (one more spare joint)",
                  (rng.normal(size=(2, 4)), np.array([0.2, 0.1]), rng.normal(size=4), 5.0)),
        RunCase("seed 002 simulation 3 (circle, redundancy, no limits): the paper's joint "
                "excursions [0.0912, 0.2179, 0.2231] rad", _circle_run),
    ]
    return cases


NULL_SPACE = Exercise(
    name="null_space_step",
    title="joint rate with a null-space step (seed 002, eq. 4 and 6)",
    function="joint_rate",
    reference=joint_rate,
    mistakes=(
        Mistake("a missing projection", "the gradient must pass through the null-space "
                "projector (I − J⁺J) so that it does not move the hand",
                lambda J, xd, g, k: np.linalg.pinv(J) @ xd + k * np.asarray(g)),
        Mistake("a sign", "+ (I − J⁺J) k_a ∇w: k_a > 0 climbs the gradient",
                lambda J, xd, g, k: joint_rate(J, xd, g, -k)),
        Mistake("a transposed matrix", "J⁺ is the pseudo-inverse (np.linalg.pinv(J)), not "
                "Jᵀ", lambda J, xd, g, k: np.asarray(J).T @ xd + (
                    np.eye(np.shape(J)[1]) - np.asarray(J).T @ J) @ (k * np.asarray(g))),
        Mistake("a missing term", "θ̇ = J⁺ẋ + (I − J⁺J) k_a ∇w: the identity I is missing "
                "from the projector", lambda J, xd, g, k: np.linalg.pinv(J) @ xd - (
                    np.linalg.pinv(J) @ J) @ (k * np.asarray(g))),
        Mistake("the full-rank pseudo-inverse", "J⁺ = Jᵀ(JJᵀ)⁻¹ holds only while J has full "
                "rank; at a singular pose (the stretched arm) use np.linalg.pinv(J)",
                _null_full_rank),
    ),
    cases=_null_cases,
    teaches="Redundancy: a joint velocity in the null space of J moves the arm without "
            "moving the hand, and can climb a criterion such as the manipulability.",
    lesson="redundancy (simulation 3, the manipulability gradient; `armlab experiment "
           "seed002-circle --mode 3`)",
)
