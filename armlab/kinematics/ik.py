"""Iterative inverse kinematics: the thesis's RMRC and damped least squares (thesis §3.3).

Resolved motion rate control with the Jacobian inverse (thesis eq. 3.16-3.22):

1. dX = X_t - X_a, the task-space error (eq. 3.16 read as a finite step);
2. J at the current joint angles (position rows only, eq. 3.17);
3. J^-1 = adj(J) / det(J) for a square J (eq. 3.20, the thesis's 3x3 arm), or the
   pseudo-inverse J^+ = J^T (J J^T)^-1 (eq. 3.19) for more joints than task rows;
4. error = |(I - J J^-1) dX| (eq. 3.21); while error > e, dX = dX / 2;
5. theta = theta + J^-1 dX (eq. 3.22);
6. repeat until the forward kinematics meets the target.

The thesis only follows a trajectory in small steps from the current pose. To solve any
target from any start, armlab closes the cases it leaves open, keeping its method:

- near a singularity (|det J| tiny next to |J|^n, :func:`is_singular`) adj/det is not
  usable, so the step is damped least squares J^T (J J^T + lambda^2 I)^-1 dX (Buss 2009,
  the thesis's ref. [5]), with lambda raised while it fails (Levenberg-Marquardt);
- |dX| is clamped to a quarter of the arm's reach, and after eq. 3.22 the step is halved
  again until the FK error actually decreases (the thesis's halving idea applied to the
  result, not only to the inverse);
- joint limits: every update is clipped into [lower, upper]; a joint resting on a limit
  that the step pushes further out is left out of the (damped) solve;
- when the run from ``q0`` ends short of the target (typically stopped at a joint limit
  on the wrong solution branch), more runs start from fixed poses spread over the joint
  space, those whose hand is nearest the target first (:func:`restart_poses`).

A target that cannot be met (beyond the reach, or behind a joint limit) ends with the
nearest configuration found, ``reached=False`` and a message; the angles are always finite.

Known limit: a few targets within about 0.5 mm of the fully stretched reach *and* within
about 3 degrees of theta0 = ±90 degrees on the receptionist arm (where that joint limit
coincides with the pole at which theta1 turns the arm about its own axis) can end
0.1-0.5 mm away: every start found ends at the limit on a local minimum.

Arrays: ``target`` (m,) position in the chain's base frame (m), with m = len(task_dims)
(3 for a spatial arm, 2 with ``task_dims=(0, 1)`` for a planar arm in the x-y plane);
``q0`` and ``IKResult.q`` (n,) joint positions (rad / m).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from armlab.kinematics.fk import fk_and_jacobian
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import floats, scalar

#: |det J| / |J|_F^m below this counts as singular (scale-free; 0 at a singularity).
SINGULAR_RATIO = 1e-6
#: Most halvings of dX in the eq. 3.21 loop before the inverse is declared unusable.
MAX_HALVINGS = 30
#: Most halvings of a step while waiting for the FK error to decrease.
MAX_BACKTRACKS = 8
#: Iterations in a row without real progress after which the solver stops.
MAX_STALLS = 4
#: Restart poses drawn per restart; the ones whose hand is nearest the target run first.
POOL_FACTOR = 4
#: Largest task step |dX| per iteration, as a fraction of the reach bound (RMRC, DLS).
STEP_FRACTION = 0.25
DLS_STEP_FRACTION = 0.1


@dataclass(frozen=True)
class IKResult:
    """Outcome of an IK solve.

    Attributes:
        q: (n,) joint positions, finite and inside the joint limits.
        reached: the FK of ``q`` is within ``tol`` of the target.
        error: |target - FK(q)| on the task rows, m.
        iterations: steps taken (each at a new Jacobian), summed over all runs.
        message: one sentence a person can read ("reached ..." or why not).
    """

    q: np.ndarray
    reached: bool
    error: float
    iterations: int
    message: str


# ---------------------------------------------------------------------------
# One function per thesis equation


def jacobian_inverse(J: np.ndarray) -> np.ndarray:
    """J^-1 = adj(J) / det(J) (thesis eq. 3.20) for a square (n, n) Jacobian.

    For 3x3 this is the thesis's printed cofactor list (J_inv11 .. J_inv33; its printed
    J_inv32 = -(J11 J31 - J31 J12)/det is a typo for -(J11 J32 - J31 J12)/det).

    Raises:
        ValueError: if J is not square or det(J) = 0 (check :func:`is_singular` first).
    """
    n, m = J.shape
    if n != m:
        raise ValueError(f"J must be square for eq. 3.20, got shape {J.shape}")
    if n == 3:
        (a, b, c), (d, e, f), (g, h, i) = J.tolist()
        A, B, C = e * i - h * f, -(d * i - g * f), d * h - g * e
        det = a * A + b * B + c * C
        if det == 0.0:
            raise ValueError("J is singular (det = 0); use a damped step")
        return np.array([
            [A, -(b * i - h * c), b * f - e * c],
            [B, a * i - g * c, -(a * f - d * c)],
            [C, -(a * h - g * b), a * e - d * b],
        ]) / det
    if n == 2:
        (a, b), (c, d) = J.tolist()
        det = a * d - b * c
        if det == 0.0:
            raise ValueError("J is singular (det = 0); use a damped step")
        return np.array([[d, -b], [-c, a]]) / det
    if np.linalg.det(J) == 0.0:
        raise ValueError("J is singular (det = 0); use a damped step")
    return np.linalg.inv(J)


def pseudo_inverse(J: np.ndarray) -> np.ndarray:
    """J^+ = J^T (J J^T)^-1 (thesis eq. 3.19), (n, m) for an (m, n) Jacobian with m <= n."""
    return J.T @ jacobian_inverse(J @ J.T)


def damped_inverse(J: np.ndarray, damping: float) -> np.ndarray:
    """Damped least-squares inverse J^T (J J^T + lambda^2 I)^-1, (n, m) (Buss 2009, ref. [5]).

    Finite for every J when ``damping`` (lambda, in the units of J's entries: m/rad) > 0.
    """
    m = J.shape[0]
    A = J @ J.T
    A[np.diag_indices(m)] += damping * damping
    # symmetric positive definite: det > 0, so the closed form of eq. 3.20 holds (2 x 2, 3 x 3)
    return J.T @ (jacobian_inverse(A) if m <= 3 else np.linalg.inv(A))


def inverse_error(J: np.ndarray, J_inv: np.ndarray, dX: np.ndarray) -> float:
    """error = |(I - J J^-1) dX| (thesis eq. 3.21), in the units of dX (m)."""
    r = dX - J @ (J_inv @ dX)
    return math.sqrt(float(r @ r))


def halved_step(
    J: np.ndarray, J_inv: np.ndarray, dX: np.ndarray, e: float, *, max_halvings: int = MAX_HALVINGS
) -> tuple[np.ndarray, int]:
    """Thesis steps 4-5: while |(I - J J^-1) dX| > e, dX = dX / 2 (eq. 3.21).

    Returns:
        ``(dX, halvings)``: the accepted (m,) task step, and how many halvings it took;
        ``halvings > max_halvings`` means the inverse is too inaccurate to use.
    """
    halvings = 0
    while inverse_error(J, J_inv, dX) > e:
        halvings += 1
        if halvings > max_halvings:
            break
        dX = 0.5 * dX
    return dX, halvings


def joint_update(
    q: np.ndarray, J_inv: np.ndarray, dX: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """theta = theta + J^-1 dX (thesis eq. 3.22), clipped into the joint limits; (n,)."""
    return np.minimum(np.maximum(q + J_inv @ dX, lower), upper)


def singularity_ratio(J: np.ndarray) -> float:
    """Scale-free closeness to a singularity: sqrt(det(J J^T)) / |J|_F^m, (m, n) J.

    0 at a singular configuration; for a square J it is |det J| / |J|_F^n.
    """
    m = J.shape[0]
    norm = math.sqrt(float(np.vdot(J, J)))
    if norm == 0.0:
        return 0.0
    if J.shape[0] == J.shape[1]:
        gram_det = np.linalg.det(J) ** 2 if m != 3 else _det3(J) ** 2
    else:
        gram_det = float(np.linalg.det(J @ J.T))
    return math.sqrt(max(gram_det, 0.0)) / norm**m


def is_singular(J: np.ndarray) -> bool:
    """True when adj/det (eq. 3.20) or eq. 3.19 would not give a usable inverse of J."""
    return singularity_ratio(J) < SINGULAR_RATIO


def _det3(J: np.ndarray) -> float:
    (a, b, c), (d, e, f), (g, h, i) = J.tolist()
    return a * (e * i - h * f) - b * (d * i - g * f) + c * (d * h - g * e)


# ---------------------------------------------------------------------------
# Solvers


@dataclass(frozen=True)
class _Problem:
    """Validated inputs of one solve; ``lower``/``upper`` (n,) cached joint limits."""

    model: SerialChain
    rows: list[int]
    target: np.ndarray
    q0: np.ndarray
    tol: float
    max_iter: int
    lower: np.ndarray
    upper: np.ndarray


def _problem(model: object, target: object, q0: object, tol: object, max_iter: object,
             task_dims: object) -> _Problem:
    if not isinstance(model, SerialChain):
        raise ValueError(
            f"model must be a SerialChain (for a quadruped pass one leg, e.g. "
            f"model.legs['RF']), got {type(model).__name__}"
        )
    try:
        dims = [int(d) for d in task_dims]  # type: ignore[attr-defined]  # any object: validated here
    except (TypeError, ValueError):
        raise ValueError(f"task_dims must be a tuple of axis indices 0-2, got {task_dims!r}") \
            from None
    if not dims or len(set(dims)) != len(dims) or any(d not in (0, 1, 2) for d in dims):
        raise ValueError(f"task_dims must be distinct axis indices 0-2, got {task_dims!r}")
    return _Problem(
        model=model,
        rows=dims,
        target=np.array(floats("target", target, len(dims))),
        q0=np.array(floats("q0", q0, model.n)),
        tol=scalar("tol", tol, positive=True),
        max_iter=_count("max_iter", max_iter, minimum=1),
        lower=model.lower,
        upper=model.upper,
    )


def _count(name: str, value: object, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _evaluate(p: _Problem, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Task error dX (m,), task Jacobian (m, n) and |dX| at q (n,)."""
    T, J6 = fk_and_jacobian(p.model, q, check=False)
    if p.rows == [0, 1, 2]:  # position: contiguous rows, no fancy indexing
        dX, J = p.target - T[:3, 3], J6[:3]
    else:
        dX, J = p.target - T[p.rows, 3], J6[p.rows]
    return dX, J, math.sqrt(float(dX @ dX))


#: Outcome of one iterative run: (q, error m, iterations, why it stopped).
_Run = tuple[np.ndarray, float, int, str]
#: An accepted step: (q, dX, J, error) at the new pose.
_Step = tuple[np.ndarray, np.ndarray, np.ndarray, float]

_NOT_MET = "the error stopped decreasing (out of reach or behind a joint limit)"


def _limited_inverse(
    p: _Problem, J: np.ndarray, dX: np.ndarray, q: np.ndarray, lam: float
) -> np.ndarray:
    """Damped inverse (n, m) that leaves joints resting on a limit out of the solve.

    A joint at its limit whose step would push it further out gets its Jacobian column
    zeroed, so the task error is shared among the joints that can still move.
    """
    J_inv = damped_inverse(J, lam)
    dq = J_inv @ dX
    blocked = ((q <= p.lower) & (dq < 0.0)) | ((q >= p.upper) & (dq > 0.0))
    if blocked.any():
        J = J.copy()
        J[:, blocked] = 0.0
        J_inv = damped_inverse(J, lam)
    return J_inv


def _halving_search(
    p: _Problem, q: np.ndarray, J_inv: np.ndarray, dX: np.ndarray, err: float
) -> _Step | None:
    """Eq. 3.22 with dX halved until the FK error decreases; None if it never does."""
    for _ in range(MAX_BACKTRACKS):
        q_new = joint_update(q, J_inv, dX, p.lower, p.upper)
        dX_new, J_new, err_new = _evaluate(p, q_new)
        if err_new < err:
            return q_new, dX_new, J_new, err_new
        dX = 0.5 * dX
    return None


def _damped_search(
    p: _Problem, q: np.ndarray, J: np.ndarray, dX: np.ndarray, err: float, lam: float
) -> tuple[_Step | None, float]:
    """Levenberg-Marquardt: raise lambda (x4) until the damped step lowers the FK error.

    Returns the accepted step (or None) and the lambda that was last tried.
    """
    for _ in range(MAX_BACKTRACKS):
        q_new = joint_update(q, _limited_inverse(p, J, dX, q, lam), dX, p.lower, p.upper)
        dX_new, J_new, err_new = _evaluate(p, q_new)
        if err_new < err:
            return (q_new, dX_new, J_new, err_new), lam
        lam *= 4.0
    return None, lam


def _rmrc_from(p: _Problem, q: np.ndarray, e: float, lam: float, max_step: float) -> _Run:
    """One RMRC run (thesis steps 1-7) from q (n,)."""
    q = np.clip(q, p.lower, p.upper)
    dX, J, err = _evaluate(p, q)
    square = J.shape[0] == J.shape[1]
    stalls = 0
    it = 0
    lam_k = lam
    while err > p.tol:
        if it == p.max_iter:
            return q, err, it, f"{p.max_iter} iterations were not enough"
        it += 1
        step = None
        if not is_singular(J):
            try:
                J_inv = jacobian_inverse(J) if square else pseudo_inverse(J)  # eq. 3.20/3.19
            except ValueError:  # det rounded to exactly 0: take the damped step
                J_inv = None
            if J_inv is not None:
                dX_c = dX if err <= max_step else dX * (max_step / err)
                dX_h, halvings = halved_step(J, J_inv, dX_c, e)  # eq. 3.21
                if halvings <= MAX_HALVINGS:
                    step = _halving_search(p, q, J_inv, dX_h, err)  # eq. 3.22
        if step is None:  # singular, inaccurate inverse, at a limit, or no progress
            step, lam_k = _damped_search(p, q, J, dX, err, lam_k)
            lam_k = max(lam, 0.25 * lam_k)
        if step is None:
            return q, err, it, _NOT_MET
        q, dX, J, err_new = step
        stalls = stalls + 1 if err - err_new < 1e-3 * p.tol else 0
        err = err_new
        if stalls >= MAX_STALLS:
            return q, err, it, _NOT_MET
    return q, err, it, "reached"


def _dls_from(p: _Problem, q: np.ndarray, lam: float, max_step: float) -> _Run:
    """One damped-least-squares run from q (n,): fixed lambda, |dX| clamped to max_step."""
    q = np.clip(q, p.lower, p.upper)
    dX, J, err = _evaluate(p, q)
    best: _Run = (q, err, 0, _NOT_MET)
    stalls = 0
    it = 0
    while err > p.tol:
        if it == p.max_iter:
            return best[0], best[1], it, f"{p.max_iter} iterations were not enough"
        it += 1
        dX_c = dX if err <= max_step else dX * (max_step / err)  # Buss's clamping
        q = joint_update(q, _limited_inverse(p, J, dX_c, q, lam), dX_c, p.lower, p.upper)
        dX, J, err_new = _evaluate(p, q)
        stalls = stalls + 1 if abs(err - err_new) < 1e-3 * p.tol else 0
        err = err_new
        if err < best[1]:
            best = (q, err, it, _NOT_MET)
        if stalls >= MAX_STALLS:
            return best[0], best[1], it, _NOT_MET
    return q, err, it, "reached"


def reach_bound(model: SerialChain) -> float:
    """Upper bound (m) on the distance from the first joint to the end effector.

    The sum of the fixed offsets between joints and to the tool, plus the stroke of any
    prismatic joint: no pose puts the end effector farther than this from the first joint.
    """
    cached = model.__dict__.get("_armlab_reach_bound")  # memoised like dynamics_model
    if cached is None:
        offsets = [np.linalg.norm(j.origin[:3, 3]) for j in model.joints[1:]]
        strokes = [max(abs(j.lower), abs(j.upper)) for j in model.joints
                   if j.kind == "prismatic"]
        cached = float(sum(offsets) + sum(strokes) + np.linalg.norm(model.tip[:3, 3]))
        model.__dict__["_armlab_reach_bound"] = cached
    return cached


def restart_poses(model: SerialChain, count: int) -> np.ndarray:
    """(count, n) start poses spread over the joint space, the same on every call.

    First the 2^n corners of the joint-limit box shrunk to 3/4 of each range (n <= 4),
    then poses drawn uniformly inside the limits from a fixed random seed.
    """
    lower, upper = model.lower, model.upper
    inset = 0.125 * (upper - lower)
    poses: list[np.ndarray] = []
    if model.n <= 4:
        for k in range(2**model.n):
            bits = np.array([(k >> i) & 1 for i in range(model.n)], dtype=bool)
            poses.append(np.where(bits, upper - inset, lower + inset))
    rng = np.random.default_rng(0)
    while len(poses) < count:
        poses.append(rng.uniform(lower, upper))
    return np.array(poses[:count]).reshape(count, model.n)


def _positions(model: SerialChain, Q: np.ndarray) -> np.ndarray:
    """End-effector positions (k, 3) of k poses Q (k, n) at once (thesis eq. 3.13, batched)."""
    k = Q.shape[0]
    R = np.broadcast_to(np.eye(3), (k, 3, 3))
    p = np.zeros((k, 3))
    for i, joint in enumerate(model.joints):
        p = p + R @ joint.origin[:3, 3]
        R = R @ joint.origin[:3, :3]
        a = joint.axis
        if joint.kind == "prismatic":
            p = p + (R @ a) * Q[:, i, None]
            continue
        c, s = np.cos(Q[:, i])[:, None, None], np.sin(Q[:, i])[:, None, None]
        K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        R = R @ (c * np.eye(3) + s * K + (1.0 - c) * np.outer(a, a))
    return p + R @ model.tip[:3, 3]


def _nearest_first(p: _Problem, poses: np.ndarray) -> np.ndarray:
    """poses (k, n) sorted by how close their end effector is to the target."""
    dist = np.linalg.norm(_positions(p.model, poses)[:, p.rows] - p.target, axis=1)
    return poses[np.argsort(dist, kind="stable")]


def _solve(p: _Problem, run: Callable[[np.ndarray], _Run], restarts: int) -> IKResult:
    """Run from q0, then (unless the target is beyond reach) from restart poses; keep the best."""
    q, err, total, why = run(p.q0)
    beyond = 0.0
    if err > p.tol:  # missed: is the target beyond reach, or worth other start poses?
        bound = reach_bound(p.model)
        shoulder = p.model.joints[0].origin[:3, 3][p.rows]
        beyond = float(np.linalg.norm(p.target - shoulder)) - bound
    if err > p.tol and beyond > p.tol:
        why = (f"the target is {beyond * 1e3:.4g} mm beyond the arm's reach "
               f"({bound * 1e3:.4g} mm)")
    elif err > p.tol and restarts > 0:
        for start in _nearest_first(p, restart_poses(p.model, POOL_FACTOR * restarts))[:restarts]:
            q_r, err_r, its, why_r = run(start)
            total += its
            if err_r < err:
                q, err, why = q_r, err_r, why_r
            if err <= p.tol:
                break
        else:
            why += f"; tried q0 and {restarts} other start poses"
    if err <= p.tol:
        message = f"reached: {err * 1e3:.3g} mm from the target after {total} iterations"
    else:
        message = (f"target not reached: {why}; the nearest point found is "
                   f"{err * 1e3:.4g} mm from it")
    return IKResult(q=q, reached=err <= p.tol, error=err, iterations=total, message=message)


def rmrc(
    model: SerialChain,
    target: np.ndarray,
    q0: np.ndarray,
    *,
    tol: float = 1e-4,
    max_iter: int = 200,
    halving_tol: float = 1e-9,
    damping: float = 0.01,
    task_dims: tuple[int, ...] = (0, 1, 2),
    restarts: int = 24,
) -> IKResult:
    """Resolved motion rate control with the Jacobian inverse (thesis eq. 3.16-3.22).

    The thesis iterates from the current pose; so does this, from ``q0``. A 3-joint arm
    with joint limits often has its solution on another branch than the one the
    iteration heads for (it then stops at a limit), so when the run from ``q0`` misses,
    up to ``restarts`` more runs start from :func:`restart_poses` (armlab's addition;
    ``restarts=0`` is the thesis's single run). The best run is returned.

    Args:
        model: a serial chain (one leg of a quadruped).
        target: (m,) end-effector position in the base frame, m (rows ``task_dims``).
        q0: (n,) start angles (clipped into the limits), e.g. the previous solution.
        tol: stop when |X_t - X_a| <= tol, m (0.1 mm by default).
        max_iter: most steps per run.
        halving_tol: the thesis's e in eq. 3.21 (m): dX is halved while the inverse's
            error exceeds it.
        damping: lambda (m) of the damped step used near a singularity or a limit.
        task_dims: which position rows form the task: (0, 1, 2) for x, y, z, (0, 1) for
            a planar arm. With fewer rows than joints eq. 3.19's pseudo-inverse is used.
        restarts: extra start poses to try when the run from q0 misses the target.

    Returns:
        :class:`IKResult` (iterations summed over runs); ``reached`` False, with finite,
        in-limit ``q`` nearest to the target and a message, when no run meets it.

    Raises:
        ValueError: naming the argument for a wrongly shaped or non-finite input.

    Example:
        >>> from kinematics import load_robot
        >>> arm = load_robot("receptionist_arm")
        >>> res = rmrc(arm, [0.2, 0.1, -0.1], arm.neutral())
        >>> res.reached, bool(np.linalg.norm(arm.fk(res.q)[:3, 3] - [0.2, 0.1, -0.1]) < 1e-4)
        (True, True)
    """
    p = _problem(model, target, q0, tol, max_iter, task_dims)
    e = scalar("halving_tol", halving_tol, positive=True)
    lam = scalar("damping", damping, positive=True)
    n_restarts = _count("restarts", restarts, minimum=0)
    step = STEP_FRACTION * reach_bound(p.model)
    return _solve(p, lambda q: _rmrc_from(p, q, e, lam, step), n_restarts)


def dls(
    model: SerialChain,
    target: np.ndarray,
    q0: np.ndarray,
    *,
    damping: float = 0.01,
    tol: float = 1e-4,
    max_iter: int = 300,
    task_dims: tuple[int, ...] = (0, 1, 2),
    restarts: int = 24,
) -> IKResult:
    """Damped least squares: theta += J^T (J J^T + lambda^2 I)^-1 dX (Buss 2009, ref. [5]).

    The thesis's eq. 3.18/3.22 with the inverse replaced by the damped one, so every step
    is finite, also at a singularity (e.g. the fully stretched receptionist arm at q = 0).
    Fixed lambda, no line search; |dX| is clamped to a tenth of the reach (Buss's
    clamping), each update is clipped into the limits and joints resting on a limit are
    left out of the solve. Restarts as in :func:`rmrc`.

    Args:
        model, target, q0, tol, max_iter, task_dims, restarts: as for :func:`rmrc`.
        damping: lambda, m (units of J's entries); larger is steadier and slower.

    Returns:
        :class:`IKResult` (``reached`` False with the nearest finite ``q`` when not met).
    """
    p = _problem(model, target, q0, tol, max_iter, task_dims)
    lam = scalar("damping", damping, positive=True)
    n_restarts = _count("restarts", restarts, minimum=0)
    step = DLS_STEP_FRACTION * reach_bound(p.model)
    return _solve(p, lambda q: _dls_from(p, q, lam, step), n_restarts)
