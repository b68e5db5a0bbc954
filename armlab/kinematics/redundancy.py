"""Redundancy resolution with joint limits (seed 002: a redundant planar 3R arm).

The task is the end-effector position (m = 2 rows of the Jacobian), the arm has n = 3
joints, so one joint velocity direction moves the arm without moving the end effector.
This module holds, one function per equation of the paper:

- :func:`manipulability` w = sqrt(det(J Jᵀ)) and :func:`manipulability_gradient` ∇w (eq. 2-3);
- :func:`gradient_projection` θ̇ = J⁺ẋ + (I − J⁺J) k_a ∇w (eq. 1-4);
- :func:`velocity_bounds` (θ_min − θ)/Δt ≤ θ̇ ≤ (θ_max − θ)/Δt, shifted by θ̇_NS (eq. 5-7);
- :func:`limit_inequality` A θ̇ ≥ B (eq. 8-10);
- :func:`decomposition` J = [J_r  J_nr] → J_c, N (eq. 11-17);
- :func:`decomposition_rate` the paper's least-squares choice of θ̇_r (eq. 18-20);
- :func:`bounded_rate` a method that guarantees the limits (bounded least squares,
  ``scipy.optimize.lsq_linear``), not in the paper.

The same gradient projection on any serial arm whose task is its hand's position in
space (m = 3 rows, :data:`POSITION_ROWS`; n > 3 joints leave n − 3 spare ones): the
criterion of eq. 2 is :func:`log_manipulability_gradient` (eq. 3's ∇w divided by w),
:func:`joint_limit_gradient` (staying away from the joint limits; not in the paper) or
both (:func:`aim_gradient`), and :func:`null_space_rate` moves the spare joints.

Shapes: ``J`` is (m, n), joint vectors are (n,), task vectors are (m,).
Why the printed decomposition method cannot raise the manipulability (modes 2 and 4 give
the same motion) is derived in docs/redundancy.md and shown by ``tests/test_seed002_*``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from armlab.kinematics.fk import fk_and_jacobian
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import cross3
from armlab.kinematics.validate import matrix, scalar, vector

#: Task rows of the 6 x n geometric Jacobian used for a planar arm: base-frame x and y.
PLANAR_ROWS = (0, 1)
#: Task rows for a hand position in space: base-frame x, y and z.
POSITION_ROWS = (0, 1, 2)
#: What the spare joints of an arm following a hand target may aim for (a key of
#: :func:`aim_gradient`): nothing, away from the joint limits, more manipulability, both.
AIMS = ("off", "limits", "manipulability", "both")


def task_jacobian(model: SerialChain, q: np.ndarray, rows: tuple[int, ...] = PLANAR_ROWS
                  ) -> np.ndarray:
    """(m, n) rows of the geometric Jacobian (seed 002 eq. 11: ẋ = J θ̇), base frame."""
    return model.jacobian(q)[list(rows)]


def manipulability(J: np.ndarray) -> float:
    """Yoshikawa's measure of manipulability w = sqrt(det(J Jᵀ)) (seed 002 §2).

    Args:
        J: (m, n) task Jacobian, m <= n.
    """
    J = np.asarray(J, dtype=float)
    return float(np.sqrt(max(np.linalg.det(J @ J.T), 0.0)))


def jacobian_derivatives(model: SerialChain, q: np.ndarray,
                         rows: tuple[int, ...] = PLANAR_ROWS) -> np.ndarray:
    """∂J/∂q_k of the positional geometric Jacobian, analytically (all joints revolute).

    Column i of the linear Jacobian is z_i × (p_e − p_i). A joint k distal to or at i
    moves only p_e: ∂J_i/∂q_k = z_i × (z_k × (p_e − p_k)); a joint k proximal to i turns
    the whole column: ∂J_i/∂q_k = z_k × J_i.

    Returns:
        (n, m, n) array: entry k is ∂J/∂q_k restricted to ``rows``.
    """
    poses = model.link_poses(q)
    p_e = (poses[-1] @ model.tip)[:3, 3]
    n = model.n
    z = np.array([poses[i][:3, :3] @ model.joints[i].axis for i in range(n)])
    p = poses[:, :3, 3]
    zs, arms = z.tolist(), (p_e - p).tolist()  # the crosses on floats (cross3)
    cols = [cross3(zs[i], arms[i]) for i in range(n)]  # the linear Jacobian's columns
    dJ = np.zeros((n, 3, n))
    for k in range(n):
        dpe = cross3(zs[k], arms[k])
        for i in range(n):
            dJ[k, :, i] = cross3(zs[i], dpe) if k >= i else cross3(zs[k], cols[i])
    return dJ[:, list(rows), :]


def manipulability_gradient(model: SerialChain, q: np.ndarray,
                            rows: tuple[int, ...] = PLANAR_ROWS) -> np.ndarray:
    """∇w = [∂w/∂θ_1 … ∂w/∂θ_n]ᵀ (seed 002 eq. 3), analytic.

    ∂w/∂θ_k = w · tr((J Jᵀ)⁻¹ ∂J/∂θ_k Jᵀ), from ∂ sqrt(det M) = ½ w tr(M⁻¹ ∂M).
    At a singular pose (w = 0) the gradient is returned as zeros.

    Returns:
        (n,) gradient.
    """
    q = vector("q", q, model.n)
    J = task_jacobian(model, q, rows)
    M = J @ J.T
    w = manipulability(J)
    if w < 1e-12:
        return np.zeros(model.n)
    Minv = np.linalg.inv(M)
    dJ = jacobian_derivatives(model, q, rows)
    return np.array([w * np.trace(Minv @ dJ[k] @ J.T) for k in range(model.n)])


def log_manipulability_gradient(model: SerialChain, q: np.ndarray,
                                rows: tuple[int, ...] = POSITION_ROWS) -> np.ndarray:
    """∇(ln w) = ∇w / w: seed 002 eq. 3 divided by w.

    The same direction as eq. 3 and the same maximum, but free of the arm's size (w of a
    position task has units m³, so eq. 2's k_a would differ by orders of magnitude from
    a 20 cm arm to a 1 m one); k_a then has units 1/s. Zeros at a singular pose (w = 0).

    Returns:
        (n,) gradient, 1/rad.
    """
    q = vector("q", q, model.n)
    w = manipulability(task_jacobian(model, q, rows))
    if w < 1e-12:
        return np.zeros(model.n)
    return manipulability_gradient(model, q, rows) / w


def joint_limit_criterion(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """H(θ) = −½ Σ ((θ_i − θ̄_i) / (½ (θ_max,i − θ_min,i)))², θ̄ the middle of each range.

    Not in seed 002 (which keeps the limits by velocity bounds, eq. 5-7): the distance
    from the middle of the joint ranges (Liégeois 1977), 0 with every joint mid-range,
    −½ for each joint at a limit. Used in place of w in eq. 2 it keeps the spare joints
    away from their limits.
    """
    q = vector("q", q)
    mid, half = _mid_half(q.size, lower, upper)
    return float(-0.5 * np.sum(((q - mid) / half) ** 2))


def joint_limit_gradient(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """∇H = −(θ − θ̄) / (½ (θ_max − θ_min))² of :func:`joint_limit_criterion` (not in
    seed 002), 1/rad: it points from each joint towards the middle of its range."""
    q = vector("q", q)
    mid, half = _mid_half(q.size, lower, upper)
    return -(q - mid) / half**2


def _mid_half(n: int, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = vector("lower", lower, n), vector("upper", upper, n)
    if np.any(hi <= lo):
        raise ValueError("joint limits: every upper limit must be above its lower limit")
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def aim_gradient(model: SerialChain, q: np.ndarray, aim: str, *, lower: np.ndarray,
                 upper: np.ndarray, rows: tuple[int, ...] = POSITION_ROWS) -> np.ndarray:
    """The ∇ of seed 002 eq. 2 for an aim of :data:`AIMS` (1/rad): zeros ("off"),
    :func:`joint_limit_gradient` ("limits"), :func:`log_manipulability_gradient`
    ("manipulability"), or their sum ("both": each is of order 1/rad).

    Raises:
        ValueError: an aim not in :data:`AIMS`.
    """
    if aim not in AIMS:
        raise ValueError(f"aim must be one of {', '.join(AIMS)}, got {aim!r}")
    q = vector("q", q, model.n)
    grad = np.zeros(model.n)
    if aim in ("limits", "both"):
        grad += joint_limit_gradient(q, lower, upper)
    if aim in ("manipulability", "both"):
        grad += log_manipulability_gradient(model, q, rows)
    return grad


def null_space_projector(J: np.ndarray) -> np.ndarray:
    """(n, n) null-space projection matrix I − J⁺J (seed 002 eq. 1)."""
    J = np.asarray(J, dtype=float)
    return np.eye(J.shape[1]) - np.linalg.pinv(J) @ J


def gradient_projection(J: np.ndarray, xdot: np.ndarray, grad_w: np.ndarray, k_a: float
                        ) -> np.ndarray:
    """θ̇ = J⁺ẋ + (I − J⁺J) k_a ∇w (seed 002 eq. 4; eq. 1 with the choice of eq. 2).

    Args:
        J: (m, n) task Jacobian.
        xdot: (m,) end-effector velocity.
        grad_w: (n,) gradient of the criterion (k_a > 0 maximises it).
        k_a: gain of eq. 2.

    Returns:
        (n,) joint velocity.
    """
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    xdot = vector("xdot", xdot, m)
    grad_w = vector("grad_w", grad_w, n)
    return np.linalg.pinv(J) @ xdot + null_space_rate(J, grad_w, k_a)


def null_space_rate(J: np.ndarray, grad_w: np.ndarray, k_a: float) -> np.ndarray:
    """θ̇_NS = (I − J⁺J) k_a ∇w, the self-motion term of seed 002 eq. 6."""
    return null_space_projector(J) @ (k_a * np.asarray(grad_w, dtype=float))


def velocity_bounds(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, dt: float,
                    qdot_ns: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Joint limits as velocity bounds over one sample (seed 002 eq. 5-7).

    (θ_min − θ)/Δt − θ̇_NS ≤ θ̇ ≤ (θ_max − θ)/Δt − θ̇_NS: the bounds on the part of the
    joint velocity that is added to θ̇_NS (eq. 7; θ̇_NS = 0 for eq. 5-6).

    Returns:
        (lo, hi), each (n,).
    """
    q = vector("q", q)
    dt = scalar("dt", dt, positive=True)
    ns = np.zeros_like(q) if qdot_ns is None else vector("qdot_ns", qdot_ns, q.size)
    return (np.asarray(lower) - q) / dt - ns, (np.asarray(upper) - q) / dt - ns


def limit_inequality(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounds as one inequality A θ̇ ≥ B (seed 002 eq. 8-10).

    A = [I_n; −I_n] (2n, n), B = [lo; −hi] (2n,).
    """
    n = len(lo)
    return np.vstack([np.eye(n), -np.eye(n)]), np.concatenate([lo, -np.asarray(hi)])


def decomposition(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split J = [J_r  J_nr] and build θ̇ = J_c ẋ + N θ̇_r (seed 002 eq. 11-17).

    The first n − m joints are the redundant ones (θ̇_r), the last m the non-redundant
    ones: θ̇_nr = J_nr⁻¹ ẋ − J_nr⁻¹ J_r θ̇_r (eq. 14).

    Returns:
        J_c (n, m) = [0; J_nr⁻¹] and N (n, n − m) = [I; −J_nr⁻¹ J_r] (eq. 17). Every
        column of N lies in the null space of J.

    Raises:
        ValueError: when J_nr is singular (for the planar arm: sin θ3 = 0).
    """
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    r = n - m
    J_r, J_nr = J[:, :r], J[:, r:]
    if abs(np.linalg.det(J_nr)) < 1e-12:
        raise ValueError("J_nr is singular: the decomposition method needs an invertible "
                         "non-redundant block (seed 002 eq. 14)")
    J_nr_inv = np.linalg.inv(J_nr)
    J_c = np.vstack([np.zeros((r, m)), J_nr_inv])
    N = np.vstack([np.eye(r), -J_nr_inv @ J_r])
    return J_c, N


def decomposition_rate(J: np.ndarray, xdot: np.ndarray, A: np.ndarray, B: np.ndarray
                       ) -> np.ndarray:
    """The paper's joint velocity with joint limits (seed 002 eq. 18-20).

    θ̇_r minimises ‖B − A θ̇‖² over θ̇ = J_c ẋ + N θ̇_r (eq. 18), giving
    θ̇ = (I − N (Nᵀ AᵀA N)⁻¹ Nᵀ AᵀA) J_c ẋ + N (Nᵀ AᵀA N)⁻¹ Nᵀ Aᵀ B (eq. 19),
    i.e. J⁺ = (I − N (Nᵀ AᵀA N)⁻¹ Nᵀ AᵀA) J_c (eq. 20).

    Note that this is a least-squares fit, not a constraint: it does not guarantee
    A θ̇ ≥ B (see docs/redundancy.md).

    Args:
        J: (m, n); xdot: (m,); A: (2n, n), B: (2n,) from :func:`limit_inequality`.

    Returns:
        (n,) joint velocity (without θ̇_NS; add it back as in eq. 6).
    """
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    xdot = vector("xdot", xdot, m)
    A = matrix("A", A, (2 * n, n))
    B = vector("B", B, 2 * n)
    J_c, N = decomposition(J)
    AtA = A.T @ A
    G = np.linalg.inv(N.T @ AtA @ N)
    J_plus = (np.eye(n) - N @ G @ N.T @ AtA) @ J_c  # eq. 20
    return J_plus @ xdot + N @ G @ N.T @ A.T @ B


def bounded_rate(J: np.ndarray, xdot: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 preferred: np.ndarray, *, weight: float = 1e-6) -> np.ndarray:
    """Joint velocity that never leaves lo ≤ θ̇ ≤ hi (not in seed 002: bounded least squares).

    Minimises ‖J θ̇ − ẋ‖² + weight · ‖θ̇ − θ̇_pref‖² subject to the velocity bounds of
    eq. 5 (``scipy.optimize.lsq_linear``). With a small weight the task comes first and
    the preferred velocity (e.g. eq. 4's gradient projection) fills the rest.

    Returns:
        (n,) joint velocity, inside [lo, hi] exactly.
    """
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    xdot = vector("xdot", xdot, m)
    preferred = vector("preferred", preferred, n)
    lo, hi = vector("lo", lo, n), vector("hi", hi, n)
    s = np.sqrt(weight)
    A = np.vstack([J, s * np.eye(n)])
    b = np.concatenate([xdot, s * preferred])
    # The current pose is inside the limits, so lo <= 0 <= hi and the box is never empty.
    lo_s, hi_s = np.minimum(lo, hi), np.maximum(lo, hi)
    from scipy.optimize import lsq_linear  # here: importing it costs every start 0.3 s

    res = lsq_linear(A, b, bounds=(lo_s, hi_s + 1e-15), method="bvls")
    return np.clip(res.x, lo_s, hi_s)


# ---------------------------------------------------------------------------
# The paper's simulation: a circle tracked by the 3 x 0.5 m arm


@dataclass(frozen=True)
class CircleTask:
    """Seed 002 §5: circle x_d(t) = (0.25(1 − cos πt), 0.25(2 + sin πt)) m for 2 s.

    Attributes:
        duration: s. dt: sample time Δt, s. gain: K = diag(gain, gain) of the position
        loop ẋ = ẋ_d + K (x_d − x). k_a: gradient gain of eq. 2.
        q0: (3,) initial joint angles θ(0), rad.
    """

    duration: float = 2.0
    dt: float = 0.004
    gain: float = 400.0
    k_a: float = 200.0
    q0: tuple[float, float, float] = (np.pi, -np.pi / 2, -np.pi / 2)


def circle_target(t: float) -> tuple[np.ndarray, np.ndarray]:
    """x_d(t) and ẋ_d(t) of seed 002 §5, each (2,), m and m/s."""
    c, s = np.cos(np.pi * t), np.sin(np.pi * t)
    return (np.array([0.25 * (1.0 - c), 0.25 * (2.0 + s)]),
            np.array([0.25 * np.pi * s, 0.25 * np.pi * c]))


#: Eq. 4 as a function: (J (m, n), ẋ (m,), ∇w (n,), k_a) -> θ̇ (n,).
Projection = Callable[[np.ndarray, np.ndarray, np.ndarray, float], np.ndarray]

#: The paper's four simulations and the guaranteed method, by name.
MODES = {
    "1": "no redundancy use, no joint limits: θ̇ = J⁺ẋ",
    "2": "no redundancy use, joint limits by the decomposition method (eq. 10-20)",
    "3": "redundancy (manipulability gradient), no limits: eq. 4",
    "4": "redundancy and joint limits: eq. 4 with the decomposition method (eq. 7-20)",
    "bounded": "redundancy and joint limits by bounded least squares (guaranteed)",
}


def joint_rate(mode: str, model: SerialChain, q: np.ndarray, xdot: np.ndarray, *,
               dt: float, k_a: float, projection: Projection | None = None) -> np.ndarray:
    """Joint velocity of one of the seed 002 simulations (a key of :data:`MODES`).

    Args:
        q: (n,) joint angles. xdot: (m,) commanded end-effector velocity.
        projection: eq. 4 of modes 3 and "bounded" (default :func:`gradient_projection`;
            coursework runs a student's in its place), called as it is.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    J = task_jacobian(model, q)
    if mode == "1":
        return np.linalg.pinv(J) @ xdot
    if mode in ("3", "bounded"):
        project = gradient_projection if projection is None else projection
        qdot = project(J, xdot, manipulability_gradient(model, q), k_a)  # eq. 4
        if mode == "3":
            return qdot
        lo, hi = velocity_bounds(q, model.lower, model.upper, dt)
        return bounded_rate(J, xdot, lo, hi, qdot)
    ns = null_space_rate(J, manipulability_gradient(model, q), k_a) if mode == "4" \
        else np.zeros(model.n)
    lo, hi = velocity_bounds(q, model.lower, model.upper, dt, ns)  # eq. 7
    A, B = limit_inequality(lo, hi)  # eq. 10
    return decomposition_rate(J, xdot, A, B) + ns  # eq. 19 + θ̇_NS (eq. 6)


@dataclass(frozen=True)
class CircleRun:
    """Time series of one simulation. t (T,), q (T, n), x (T, 2), x_d (T, 2), w (T,)."""

    mode: str
    t: np.ndarray
    q: np.ndarray
    x: np.ndarray
    x_d: np.ndarray
    w: np.ndarray

    def error(self) -> np.ndarray:
        """(T,) position error norm |x_d − x|, m."""
        return np.linalg.norm(self.x_d - self.x, axis=1)


def simulate_circle(model: SerialChain, mode: str, task: CircleTask | None = None, *,
                    projection: Projection | None = None) -> CircleRun:
    """Run one of the paper's simulations (seed 002 §5) with Euler steps of Δt.

    Closed loop in task space: ẋ = ẋ_d + K (x_d − x); θ̇ from :func:`joint_rate`
    (``projection`` as there); θ ← θ + Δt θ̇.
    """
    task = task or CircleTask()
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    dt = scalar("dt", task.dt, positive=True)
    gain = scalar("gain", task.gain, positive=True)
    scalar("k_a", task.k_a)
    if gain * dt >= 2.0:
        raise ValueError(f"gain K = {gain:g} 1/s with dt = {dt:g} s is unstable in discrete "
                         f"time (K dt must be < 2); use K < {2.0 / dt:g}")
    steps = int(round(task.duration / task.dt))
    q = np.array(task.q0, dtype=float)
    ts, qs, xs, xds, ws = [], [], [], [], []
    for k in range(steps + 1):
        t = k * task.dt
        T, J = fk_and_jacobian(model, q)
        x = T[:2, 3]
        x_d, xd_d = circle_target(t)
        ts.append(t)
        qs.append(q.copy())
        xs.append(x)
        xds.append(x_d)
        ws.append(manipulability(J[list(PLANAR_ROWS)]))
        if k == steps:
            break
        xdot = xd_d + task.gain * (x_d - x)
        q = q + task.dt * joint_rate(mode, model, q, xdot, dt=task.dt, k_a=task.k_a,
                                     projection=projection)
    return CircleRun(mode, np.array(ts), np.array(qs), np.array(xs), np.array(xds),
                     np.array(ws))


def limit_violation(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(n,) worst excursion of each joint beyond its limits over a run q (T, n); 0 = inside."""
    q = np.atleast_2d(q)
    over = np.maximum(q - np.asarray(upper), 0.0)
    under = np.maximum(np.asarray(lower) - q, 0.0)
    return np.max(np.maximum(over, under), axis=0)
