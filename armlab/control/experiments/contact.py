"""``armlab experiment contact``: the hand driven into a wall, PD against the compliance law.

The receptionist arm stands at the thesis line's start; a wall (a plane across the line's
direction, ``--wall-cm`` ahead of the hand) blocks the way; the command moves the hand
along the line at the thesis's hand speed (2.5 mm per 16 ms) to ``--depth-cm`` behind the
wall's surface, then holds there. The wall pushes back ``--stiffness`` N/m of
penetration and ``--damping`` N·s/m (the plant's contact, never pulling).

What it measures, from the plant's ground truth (a force sensor the arm does not have) as
the control loop records it every period (``f_contact`` and ``f_contact_peak`` of
:mod:`armlab.control.recorder`; a contact challenge judges the same record with the same
:func:`contact_figures`): the peak force of the impact (the largest at any plant step),
the steady force (the mean over the last second), how often the hand bounced off
(contact lost and made again), and how long the force took to settle within 10 % of its
steady value (None: it never did).
Beside them, the steady force the law's static stiffness predicts: the compliance law
(eq. 2.6 with 2.7) holds a steady external torque with θ − θ_cmd = K_f τ / K_env, a joint stiffness
K_q = K_env / K_f on every joint (1 / K_f for the literal eq. 2.26); through the
Jacobian at the command, the hand's compliance along the wall's normal n is
nᵀ J K_q⁻¹ Jᵀ n, in series with the wall's 1 / k, so a command d behind the surface
presses with f = d / (nᵀ J K_q⁻¹ Jᵀ n + 1 / k). The PD law (eq. 2.20) has no finite
stiffness: its reference integrates the error twice, so against a wall it winds up until
the servo's torque or the lab's lag check stops it (:data:`PD_NOTE`).

How well the arm reads a force it has no sensor for: beside the wall's recorded force, the
hand's force along the normal each of the arm's torque estimates implies
(:func:`estimated_forces`: the lab's τ_ext of eq. 2.21–2.23 as the loop recorded it, the
disturbance observer of eq. 2.36 and the reaction-torque observer of eq. 2.37 run over
the record's rows, :mod:`armlab.control.arm_observers`), each as its steady mean, its
error against the recorded steady force (N and %) and its RMS error over the run
(:func:`force_estimate_figures`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from armlab.control.arm_observers import CUTOFF, hand_normal_forces, observe_record
from armlab.control.backend import FRICTION_RANGE, Backend, Touchable, WallSetting
from armlab.control.commands import RunTrajectory, SetVirtualWall
from armlab.control.experiments import BackendOptions, Experiment, Keep, advance, option
from armlab.control.laws import LAWS
from armlab.control.loop import APPROACH_MIN, TARGET_SPEED, ControlLoop
from armlab.control.params import DEFAULT, Params
from armlab.control.runs import run_from_snapshot
from armlab.control.trajectory import (
    JointTrajectory,
    approach_duration,
    cartesian_to_joint,
    hold,
    line_points,
    minimum_jerk,
    thesis_line,
)
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.stiffness import cartesian_compliance

SETTLE_S = 0.5  #: s held at the start before the move
#: periods the arm holds at the start before the command is applied: a challenge's
#: restart applies its plan in the third period after it (armlab.control.restart), so the
#: experiment and the contact challenge's run are the same periods from the same state
LEAD = 2
HOLD_S = 4.0  #: s held at the command behind the wall after it
STEADY_S = 1.0  #: s at the end the steady force is the mean of
SETTLE_BAND = 0.10  #: the force has settled once it stays within 10 % of its steady value
#: N: the hand touches the wall while the force is above this (a bounce: it falls below
#: and rises again after the first touch)
TOUCH_N = 0.05
#: What the PD law's run says when its reference winds up against the wall
PD_NOTE = ("PD (eq. 2.20) has no finite stiffness: blocked, its reference integrates the "
           "error twice and winds up until the servo's torque or the lab's lag check stops it")


#: N/m and N·s/m a wall's stiffness and damping may be (this experiment's, and the
#: emulator's ``--wall``): soft foam to steel under a servo arm's hand
STIFFNESS_RANGE = (100.0, 1e6)
DAMPING_RANGE = (0.0, 1e4)


def check_wall_numbers(*, stiffness: float, damping: float, names: tuple[str, ...],
                       friction: float = 0.0) -> None:
    """ValueError naming the option (``names``: the stiffness's, the damping's and the
    friction's) whose value is not finite or outside :data:`STIFFNESS_RANGE` /
    :data:`DAMPING_RANGE` / ``FRICTION_RANGE``."""
    for name, value, (lo, hi) in ((names[0], stiffness, STIFFNESS_RANGE),
                                  (names[1], damping, DAMPING_RANGE),
                                  (names[-1], friction, FRICTION_RANGE)):
        if not (math.isfinite(value) and lo <= value <= hi):
            raise ValueError(f"{name} must be in {lo:g}..{hi:g}, got {value:g}")


def joint_stiffness(params: Params, controller: str) -> float | None:
    """N·m/rad of every joint's static stiffness under ``controller`` with ``params``: the
    compliance law holds a steady external torque τ with θ − θ_cmd = K_f τ / K_env (eq. 2.6,
    2.7), so K_q = K_env / K_f (1 / K_f for the literal eq. 2.26); None for PD and no
    controller (no finite stiffness: the reference integrates the error)."""
    if controller != "compliance" or not params.compliance:
        return None
    return LAWS[params.law].joint_stiffness(params)


def predicted_force(model: SerialChain, q: np.ndarray, normal: np.ndarray, depth: float, *,
                    k_joint: float, k_wall: float) -> float:
    """N the hand presses a wall with at rest, ``depth`` m of command behind its surface:
    f = d / (nᵀ J K_q⁻¹ Jᵀ n + 1 / k), J the position rows of the Jacobian at ``q`` (n,)
    rad, K_q = ``k_joint`` I (N·m/rad), n the wall's unit ``normal`` (3,), k ``k_wall`` N/m."""
    J = model.jacobian(np.asarray(q, dtype=float))[:3]
    n = np.asarray(normal, dtype=float)
    compliance = float(n @ cartesian_compliance(J, k_joint * np.eye(model.n)) @ n)
    return float(depth / (compliance + 1.0 / k_wall))


def wall_across_line(model: SerialChain, q_start: np.ndarray, q_end: np.ndarray,
                     distance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A wall across the hand's straight line from its place at ``q_start`` to its place
    at ``q_end`` (rad), ``distance`` m ahead of the start: (x0, u, origin, normal), base
    frame, x0 the start (3,) m, u the line's unit direction, origin a point of the wall
    (3,) m and normal its unit normal towards the free side (−u, facing the hand)."""
    x0 = model.fk(np.asarray(q_start, dtype=float))[:3, 3]
    u = model.fk(np.asarray(q_end, dtype=float))[:3, 3] - x0
    u = u / np.linalg.norm(u)
    return x0, u, x0 + distance * u, -u


def wall_torque(model: SerialChain, q: np.ndarray, normal: np.ndarray,
                force: np.ndarray) -> np.ndarray:
    """(m, n) N·m the joints hold against the wall: −Jᵀ f n at each of ``q`` (m, n) rad,
    ``force`` (m,) N the wall pushes the hand with along its unit ``normal`` (3,). That is
    what the sensorless estimate of thesis eq. 2.21-2.23 reads: τ_ext = LPF(τ_dist) − τ_dyn
    is the servos' load beyond the motion's own torque, the reaction to the push (Jᵀ f n)."""
    n = np.asarray(normal, dtype=float)
    return np.array([-(model.jacobian(qi)[:3].T @ (fi * n))
                     for qi, fi in zip(np.asarray(q, dtype=float),
                                       np.asarray(force, dtype=float), strict=True)]
                    ).reshape(len(force), model.n)


def estimate_figures(t: np.ndarray, tau_wall: np.ndarray, tau_ext: np.ndarray
                     ) -> dict[str, Any]:
    """How well the lab's estimate ``tau_ext`` (m, n) N·m (eq. 2.21-2.23, as the loop
    recorded it) read the wall's torque ``tau_wall`` (m, n) at loop times ``t`` (m,) s: its
    steady error on each joint (the means over the last :data:`STEADY_S` s) and the RMS
    error over the whole run, N·m (the estimate's low-pass lags an impact)."""
    steady = t >= t[-1] - STEADY_S
    ok = np.all(np.isfinite(tau_ext), axis=1)
    wall_mean = tau_wall[steady & ok].mean(axis=0)
    est_mean = tau_ext[steady & ok].mean(axis=0)
    return {"wall_torque_steady_nm": [float(v) for v in wall_mean],
            "estimate_steady_nm": [float(v) for v in est_mean],
            "estimate_steady_error_nm": [float(v) for v in est_mean - wall_mean],
            "estimate_rms_error_nm": float(np.sqrt(np.mean((tau_ext[ok] - tau_wall[ok]) ** 2)))}


#: the estimates of the hand's force ``armlab experiment contact`` sets beside the wall's:
#: the lab's (eq. 2.21–2.23), the disturbance observer's (eq. 2.36, its change since the
#: run's start) and the reaction-torque observer's (eq. 2.37)
ESTIMATES = ("tau_ext", "dob", "rtob")


def estimated_forces(model: SerialChain, rows: Mapping[str, np.ndarray], normal: np.ndarray,
                     *, rest: np.ndarray, g: float = CUTOFF) -> dict[str, np.ndarray]:
    """The hand's force along the wall's unit ``normal`` (3,) by each of :data:`ESTIMATES`
    at every row of the loop's record ``rows`` (``t`` s, ``q`` rad, ``load`` and
    ``tau_ext`` N·m), each (m,) N (:func:`~armlab.control.arm_observers.hand_normal_forces`):
    τ_ext as the loop recorded it (NaN under PD); the observers of
    :mod:`armlab.control.arm_observers` (cut-off ``g`` rad/s) run causally over the rows
    from the first, the DOB's torque taken as its change from its mean over the rows
    ``rest`` marks ((m,) bool: the arm at rest off the wall, before it moves)."""
    t = np.asarray(rows["t"], dtype=float)
    q = np.asarray(rows["q"], dtype=float)
    dis, reac = observe_record(model, t, q, np.asarray(rows["load"], dtype=float),
                               g_dis=g, g_reac=g)
    forces = hand_normal_forces(model, q, (np.asarray(rows["tau_ext"], dtype=float),
                                           dis - dis[rest].mean(axis=0), reac), normal)
    return dict(zip(ESTIMATES, forces, strict=True))


def force_estimate_figures(t: np.ndarray, force: np.ndarray,
                           estimates: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """How well each estimate of ``estimates`` (name: (m,) N, :func:`estimated_forces`) read
    the wall's recorded ``force`` (m,) N at loop times ``t`` (m,) s: ``NAME_force_steady_n``
    its mean over the last :data:`STEADY_S` s (the steady force's window),
    ``NAME_force_error_n`` that minus the recorded mean, ``NAME_force_error_pct`` in % of
    it (None while the recorded press is under :data:`TOUCH_N`), and
    ``NAME_force_rms_error_n`` over the whole run (an impact between two estimates' rows
    counts); None for an estimate with no finite row in the window (τ_ext under PD)."""
    t = np.asarray(t, dtype=float)
    force = np.nan_to_num(np.asarray(force, dtype=float))
    steady = t >= t[-1] - STEADY_S
    recorded = float(np.mean(force[steady]))
    out: dict[str, Any] = {}
    for name, est in estimates.items():
        est = np.asarray(est, dtype=float)
        ok = np.isfinite(est)
        keys = [f"{name}_force_{k}" for k in ("steady_n", "error_n", "error_pct",
                                              "rms_error_n")]
        if not (ok & steady).any():
            out.update(dict.fromkeys(keys, None))
            continue
        mean = float(np.mean(est[ok & steady]))
        err = mean - recorded
        out.update(zip(keys, (mean, err,
                              100.0 * err / recorded if recorded > TOUCH_N else None,
                              float(np.sqrt(np.mean((est[ok] - force[ok]) ** 2)))),
                       strict=True))
    return out


def contact_figures(t: np.ndarray, force: np.ndarray, peak: np.ndarray) -> dict[str, Any]:
    """The figures of one contact run: ``force`` (N) and ``peak`` (N, the largest at any
    plant step of each period) sampled at loop times ``t`` (s)."""
    force, peak = np.nan_to_num(force), np.nan_to_num(peak)  # (no wall: no force)
    touching = force > TOUCH_N
    if not touching.any():
        return {"touched": False, "peak_force_n": 0.0, "steady_force_n": None,
                "bounces": 0, "settle_s": None, "first_touch_s": None}
    first = int(np.argmax(touching))
    # a bounce: contact lost after the first touch, and made again
    edges = np.flatnonzero(np.diff(touching[first:].astype(int)) == 1)
    steady_rows = t >= t[-1] - STEADY_S
    steady = float(np.mean(force[steady_rows]))
    band = max(SETTLE_BAND * abs(steady), TOUCH_N)
    out = np.flatnonzero(np.abs(force - steady) > band)
    if not len(out):
        settle: float | None = 0.0
    elif out[-1] + 1 >= len(t) or t[-1] - t[out[-1] + 1] < STEADY_S:
        settle = None  # still moving in the last second: never settled
    else:
        settle = float(t[out[-1] + 1] - t[first])
    return {"touched": True, "peak_force_n": float(np.max(peak)),
            "steady_force_n": steady, "bounces": int(len(edges)),
            "settle_s": settle, "first_touch_s": float(t[first])}


@dataclass(frozen=True)
class WallOptions(BackendOptions):
    """The wall and the gains of a run into it (``contact-compare``'s options; ``contact``
    adds the law)."""

    wall_cm: float = option(4.0, "cm from the hand to the wall along the thesis line")
    depth_cm: float = option(2.0, "cm behind the wall's surface the command ends")
    stiffness: float = option(2e4, "N/m the wall pushes back per m of penetration "
                              "(default: a wooden table under a servo arm's hand)")
    damping: float = option(50.0, "N·s/m of the wall's damping while in contact")
    friction: float = option(0.0, "μ of the wall's Coulomb friction (0: frictionless; on "
                             "servos the rendered wall has none)")
    k_env: float | None = option(None, "K_env, N·m/rad (default: the lab's)")
    k_f: float | None = option(None, "K_f (default: the lab's)")
    d_env: float | None = option(None, "D_env, N·m·s/rad (default: the lab's)")
    alpha: float | None = option(None, "α of the LPF on the servo load (default: the "
                                 "thesis's 0.05; 0.3 and up press the table steadily)")
    block_cm: str | None = option(None, "W,H,T: a block W × H cm across its face and T cm "
                                  "thick in place of the plane (the arm's links meet it "
                                  "too), e.g. 22,22,5")


def box_size_cm(text: str, *, option: str, example: str) -> tuple[float, float, float]:
    """A box's ``W,H,T`` in cm, as ``option`` takes it (``--block-cm``, emulate's
    ``--wall-size``) -> (width, height, thickness) m.

    Raises:
        ValueError: one line naming ``option``: not numbers, or not three sizes above 0
            and at most 1000 cm.
    """
    expected = f"expected W,H,T in cm, e.g. {option} {example}"
    shown = repr(text[:40]) + ("…" if len(text) > 40 else "")
    try:
        cm = [float(v) for v in text.split(",", 3)]
    except ValueError:
        raise ValueError(f"{option} {shown}: not numbers; {expected}") from None
    if len(cm) != 3 or not all(0.0 < v <= 1000.0 for v in cm):
        raise ValueError(f"{option} {shown}: three sizes above 0 and at most 1000 cm; "
                         f"{expected}")
    return cm[0] / 100.0, cm[1] / 100.0, cm[2] / 100.0


@dataclass(frozen=True)
class ContactOptions(WallOptions):
    """Options of ``contact``."""

    controller: Literal["pd", "compliance"] = option(
        "compliance", "the law that drives the hand into the wall")


@dataclass(frozen=True)
class ContactPlan:
    """The command of a run into a wall and the wall it meets (:func:`contact_plan`).

    Attributes:
        plan: held :data:`SETTLE_S` at the thesis line's start, along the line into the
            wall to ``depth`` behind its surface, held :data:`HOLD_S` there.
        origin, normal: the wall's point (3,) m and unit normal (3,), base frame.
        q_end: (n,) rad, the command behind the wall (where the prediction is worked out).
        depth: m of command behind the surface.
        periods: the loop periods the run is recorded for.
    """

    plan: JointTrajectory
    origin: np.ndarray
    normal: np.ndarray
    q_end: np.ndarray
    depth: float
    periods: int


def contact_plan(model: SerialChain, period: float, *, wall: float,
                 depth: float) -> ContactPlan:
    """The run of ``armlab experiment contact`` (module docstring) for ``model`` at loop
    ``period`` s: the wall ``wall`` m ahead of the thesis line's start, the command
    ``depth`` m behind it.

    Raises:
        ValueError: ``wall`` outside 0.5..20 cm or ``depth`` outside 0..10 cm.
    """
    for name, value, lo, hi in (("--wall-cm", wall, 0.005, 0.2),
                                ("--depth-cm", depth, 0.0, 0.1)):
        if not (math.isfinite(value) and lo <= value <= hi):
            raise ValueError(f"{name} must be in {lo * 100:g}..{hi * 100:g}, got "
                             f"{value * 100:g}")
    line = thesis_line(model)
    q0 = line.q[0]
    x0, u, origin, normal = wall_across_line(model, q0, line.q[-1], wall)
    points = line_points(x0, x0 + (wall + depth) * u, TARGET_SPEED * period)
    move = cartesian_to_joint(model, points, q0, dt=period, name="into the wall")
    plan = hold(q0, SETTLE_S).then(move).then(hold(move.q[-1], HOLD_S), name="contact")
    return ContactPlan(plan, origin, normal, move.q[-1].copy(), depth,
                       int(math.ceil(plan.duration / period - 1e-9)))


def recorded_contact(rows: Mapping[str, np.ndarray], *, start: int = 0) -> dict[str, Any]:
    """:func:`contact_figures` of a loop's record ``rows`` (a ``Recorder.snapshot`` or a
    window of one: ``t`` s, ``f_contact`` N and ``f_contact_peak`` N, one each a period)
    from row ``start`` on (the period the command is applied: :data:`LEAD`), its times
    counted from there. A run the loop stopped (a row recorded with the controller off,
    its ``error`` NaN: the lag check under PD) has no steady force, and ``fault`` says
    so (None otherwise)."""
    t = np.asarray(rows["t"], dtype=float)[start:]
    figures = contact_figures(t - t[0], np.asarray(rows["f_contact"], dtype=float)[start:],
                              np.asarray(rows["f_contact_peak"], dtype=float)[start:])
    error = np.asarray(rows["error"], dtype=float)[start:]
    stopped = bool((~np.isfinite(error)).any())
    figures["fault"] = "the arm stopped (torque off) during the run" if stopped else None
    if stopped:
        figures["steady_force_n"] = None
    return figures


def _on_servos(loop: ControlLoop, plan: JointTrajectory, wall: WallSetting) -> int:
    """The run on servos, paced by the clock: the arm moved to the line's start from
    wherever it stands (minimum jerk), the virtual wall set there (on the hand's free side:
    set with the hand inside, the loop refuses it), then the plan. Returns the record's
    row the plan starts at."""
    loop.start()
    advance(loop, 0.1)
    if loop.status.fault is not None:
        raise ValueError(f"the loop stopped: {loop.status.fault}")
    here = loop.recorder.snapshot(0.0)["q_cmd"][-1]
    if np.max(np.abs(here - plan.q[0])) > APPROACH_MIN:
        approach = minimum_jerk(here, plan.q[0], approach_duration(here, plan.q[0]))
        loop.post(RunTrajectory(approach, approach=False))
        advance(loop, loop.status.t + approach.duration + SETTLE_S)
    loop.post(SetVirtualWall(wall))
    t0 = loop.status.t
    loop.post(RunTrajectory(plan, approach=False))
    advance(loop, t0 + plan.duration + 0.05)
    t = loop.recorder.snapshot()["t"]
    return int(np.searchsorted(t, t0))


def run_contact(model: SerialChain, backend_factory: Any, params: Params, *,
                controller: str, wall: float, depth: float, stiffness: float,
                damping: float, friction: float = 0.0, keep: Keep | None = None,
                size: tuple[float, float, float] | None = None) -> dict[str, Any]:
    """Drive the hand of ``model`` into a wall ``wall`` m ahead, to ``depth`` m behind it
    (see the module docstring), its Coulomb ``friction`` μ along it (``size``: a block of
    (width, height, thickness) m, its face there, instead of a plane); the figures, the
    prediction and, when the loop stopped, why.

    On a backend whose world holds no wall (real servos, the emulator's) the wall is
    virtual: the compliance law renders it (:mod:`armlab.control.virtual_wall`), and the
    force recorded is the one it renders.

    Raises:
        ValueError: PD on a backend without a wall of its own (PD renders none), servos
            that stop the loop before the run, or options out of range.
    """
    run = contact_plan(model, params.period, wall=wall, depth=depth)
    check_wall_numbers(stiffness=stiffness, damping=damping, friction=friction,
                       names=("--stiffness", "--damping", "--friction"))
    plan, origin, normal, q0 = run.plan, run.origin, run.normal, run.plan.q[0]
    backend: Backend = backend_factory(model, q0=q0)
    loop: ControlLoop | None = None
    try:
        virtual = not isinstance(backend, Touchable)
        if virtual and controller != "compliance":
            raise ValueError("on servos the wall is virtual, rendered by the compliance law; "
                             "PD renders none: run --controller compliance")
        if virtual and size is not None:
            raise ValueError("on servos the wall the compliance law renders is a plane: "
                             "a block needs the simulated arm")
        if isinstance(backend, Touchable):
            backend.set_wall(origin, normal, stiffness=stiffness, damping=damping,
                             friction=friction, size=size)
        loop = ControlLoop(model, backend, params, controller=controller,  # type: ignore[arg-type]  # a Touchable backend is a Backend too (the factory's)
                           realtime=virtual, history_s=plan.duration + 30.0)
        if virtual:
            start = _on_servos(loop, plan, WallSetting(origin, normal, stiffness, damping))
        else:
            for _ in range(LEAD):  # holding, as a challenge's restarted arm does
                loop.step()
            start = LEAD
            loop.post(RunTrajectory(plan, approach=False))
            for _ in range(run.periods):
                loop.step()
                if loop.status.fault is not None:
                    break
        fault = loop.status.fault
        snap = loop.recorder.snapshot()
    finally:
        if loop is not None:
            loop.shutdown()
        backend.close()
    if virtual:  # the run from the line's start on (the approach before it is not its)
        snap = {k: v[start:] for k, v in snap.items()}
        start = 0
    figures = recorded_contact(snap, start=start)
    # the wall's torque on the joints beside the lab's estimate of it, period by period
    figures.update(estimate_figures(snap["t"], wall_torque(model, snap["q"], normal,
                                                           np.nan_to_num(snap["f_contact"])),
                                    snap["tau_ext"]))
    # the hand's force along the normal by τ_ext and by the observers, beside the wall's;
    # the DOB's reference: the plan's first hold, the arm at rest at the line's start
    t_run = snap["t"] - snap["t"][start]
    rest = (t_run >= 0.0) & (t_run < SETTLE_S - 1e-9)
    figures.update(force_estimate_figures(
        snap["t"][start:], snap["f_contact"][start:],
        {k: v[start:] for k, v in estimated_forces(model, snap, normal, rest=rest).items()}))
    figures["observer_cutoff_rad_s"] = CUTOFF
    k_q = joint_stiffness(params, controller)
    figures.update({
        "controller": controller, "fault": fault,
        "wall_kind": "virtual" if virtual else "simulated",
        "predicted_force_n": None if k_q is None else predicted_force(
            model, run.q_end, normal, depth, k_joint=k_q, k_wall=stiffness),
        "joint_stiffness_nm_per_rad": k_q,
        "wall": {"origin_m": origin.tolist(), "normal": normal.tolist(),
                 "stiffness_n_per_m": stiffness, "damping_ns_per_m": damping,
                 "distance_m": wall, "depth_m": depth,
                 "size_m": None if size is None else list(size)},
    })
    if fault is not None:
        figures["steady_force_n"] = None
    if k_q is None:
        figures["note"] = PD_NOTE
    if keep is not None:
        keep(run_from_snapshot(
            snap, robot=model.name, joint_names=model.joint_names, source="experiment:contact",
            params={**params.as_dict(), "controller": controller},
            commands=({"t": 0.0, "kind": "RunTrajectory", "name": plan.name,
                       "duration_s": plan.duration},),
            figures={k: float(v) for k, v in figures.items()
                     if isinstance(v, int | float) and not isinstance(v, bool)},
            extra={"wall": figures["wall"]}))
    return figures


def _params(o: WallOptions) -> Params:
    """The lab's gains with the options' K_env, K_f, D_env and α where given."""
    given = {k: getattr(o, k) for k in ("k_env", "k_f", "d_env", "alpha")
             if getattr(o, k) is not None}
    return replace(DEFAULT, **given)


def _run(o: WallOptions, controller: str, *, backend_factory: Any,
         keep: Keep | None = None) -> dict[str, Any]:
    return run_contact(load_robot("receptionist_arm"), backend_factory, _params(o),
                       controller=controller, wall=o.wall_cm / 100.0,
                       depth=o.depth_cm / 100.0, stiffness=o.stiffness, damping=o.damping,
                       friction=o.friction, keep=keep,
                       size=None if o.block_cm is None else box_size_cm(
                           o.block_cm, option="--block-cm", example="22,22,5"))


def _contact_run(options: ContactOptions, *, backend_factory: Any,
                 keep: Keep | None = None) -> dict[str, Any]:
    return _run(options, options.controller, backend_factory=backend_factory, keep=keep)


#: The figures ``contact-compare`` sets side by side, each with its label and unit.
COMPARED = (("peak_force_n", "peak force", "N"), ("steady_force_n", "steady force", "N"),
            ("predicted_force_n", "the law predicts", "N"), ("bounces", "bounces", ""),
            ("settle_s", "settles in", "s"), ("stopped", "torque off", ""))


def compare_contact(run: Callable[[str], dict[str, Any]]) -> dict[str, Any]:
    """PD and the compliance law through the same wall, one run each (``run(controller)``
    gives one's figures), side by side: ``{"pd": figures, "compliance": figures, "rows":
    [{"figure", "unit", "pd", "compliance"}, ...]}`` of :data:`COMPARED`. The impact,
    the steady press and the settling a teacher compares (PD has no steady press: it
    winds up until the lag check stops it)."""
    pd, cl = run("pd"), run("compliance")
    for fig in (pd, cl):  # the fault's words stay in the figures; the table says whether
        fig["stopped"] = "yes" if fig.get("fault") else "no"
    rows = [{"figure": label, "unit": unit, "pd": pd.get(key), "compliance": cl.get(key)}
            for key, label, unit in COMPARED]
    return {"pd": pd, "compliance": cl, "rows": rows}


def _compare_run(options: WallOptions, *, backend_factory: Any,
                 keep: Keep | None = None) -> dict[str, Any]:
    return compare_contact(lambda controller: _run(
        options, controller, backend_factory=backend_factory, keep=keep))


def _compare_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    return list(result["rows"])


def _contact_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    return [{"figure": k, "value": v} for k, v in result.items()
            if not isinstance(v, dict)]


EXPERIMENTS = (
    Experiment("contact", "the hand driven into a wall (PD or the compliance law): peak "
               "and steady force, the force the law's stiffness predicts, bounces, settling",
               ContactOptions, _contact_run, _contact_rows, needs=("backend_factory",)),
    Experiment("contact-compare", "PD and the compliance law into the same wall, side by "
               "side: peak and steady force, the prediction, bounces, settling",
               WallOptions, _compare_run, _compare_rows, needs=("backend_factory",)),
)
