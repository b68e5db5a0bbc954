"""``armlab experiment observers``: disturbance and reaction-torque observers (thesis §2.1.1).

A torque-driven joint (J θ̈ = K_t I − τ_l, thesis eq. 2.27–2.29) holds a position
under a PD current loop; at ``--at`` s an external torque step ``--step`` N·m hits
it. The disturbance observer (eq. 2.36) and the reaction-torque observer
(eq. 2.37) estimate it from the current and the speed alone. Prints how closely
each follows the truth (the total disturbance τ_dis, which also holds gravity and
friction, for the DOB; τ_ext for the RTOB), how fast the RTOB picks up the step
(its 63 % time should be about 1/g_reac), and, with
the estimate fed back (thesis fig. 2.9), how much less the joint gives way.

With ``--backend serial`` (servos that measure their motor current: XM430-W350,
XL330-M288, real or ``armlab emulate``d) both observers run on the servos instead: the
arm holds still (goal = present position, or ``--pose`` first), the present current (as
torque, through the datasheet's torque constant), position and velocity are read every
:data:`SERVO_PERIOD`. The DOB's estimate of ``--joint`` before and after a torque applied
to the joint (a weight hung on it, or ``armlab emulate --disturb``) is compared with
``--applied`` as a step. The RTOB subtracts the known load, the arm model's gravity and
velocity torques at the measured pose (RNEA with q̈ = 0), and so estimates the applied
torque itself: it should read 0 before the step and ``--applied`` after it. Its reading
before the step (``rtob_before_nm``) is the model's error at the pose: on
``armlab emulate`` nearly nil, because the emulator's plant is moved by the same model;
on a real arm the model's masses and centres of mass, cables and the gears' static
friction show there as an offset, which is also in ``rtob_after_nm``. RX-24F servos
report a load estimate, not a current: the observers are a simulation lesson on them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.control.backend import Backend, CurrentSensing
from armlab.control.experiments import BackendOptions, Experiment, Keep, option
from armlab.control.observers import (
    ObserverRun,
    ObserverState,
    TorqueJoint,
    disturbance_observer,
    simulate_observers,
)
from armlab.control.runs import Run, lab_version, utc_now
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.dynamics import bias_torques, mass_matrix
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import index, joint_index, scalar, vector

DECIMATE = 20  #: CSV rows: every 20th sample (2 ms at the 0.1 ms step)
SIM_STEP, SIM_AT, SIM_DURATION, SIM_G = 0.004, 0.5, 1.5, 200.0  #: the simulation's defaults

SERVO_PERIOD = 0.01  #: s between two readings of the servos
SERVO_G = 20.0  #: rad/s, both observers' default cut-off on servos (well under 1/period)
SERVO_DURATION = 10.0  #: s of holding and reading, by default
SERVO_ROBOT = "open_manipulator_x"  #: the arm with current-sensing servos (XM430-W350)
#: s the servo's own position loop and the DOB take to settle after the torque went on
#: or a torque step came (the XM430's P+D hold settles in ~0.3 s, the DOB in 5/g)
SETTLE_S = 1.0
MARGIN_S = 0.2  #: s left out before the step (the estimate starts moving before its midpoint)
MIN_WINDOW_S = 0.5  #: s of settled readings each side of the step at least
POSE_SPEED = 1.0  #: rad/s going to ``--pose``
POSE_TOLERANCE = 0.05  #: rad from the pose (the servo's P hold sags under gravity)
STILL = 0.05  #: rad/s under which the joint counts as still
SERVO_DECIMATE = 5  #: rows of the servo run: every 5th reading (50 ms)


def _rise_time(t: np.ndarray, est: np.ndarray, true: np.ndarray, at: float) -> float:
    """Seconds after ``at`` until ``est`` has covered 63 % of the jump ``true`` makes there
    (inf if never)."""
    k = int(np.searchsorted(t, at))
    base, jump = true[k - 1], true[k + 1] - true[k - 1]
    reached = np.nonzero((t >= at) & (np.sign(jump) * (est - base) >= 0.632 * abs(jump)))[0]
    return float(t[reached[0]] - at) if reached.size else float("inf")


def _summary(run: ObserverRun, at: float, settle: float) -> dict[str, float]:
    late = run.t >= at + settle
    return {
        "dob_error_max_nm": float(np.max(np.abs(run.tau_dis_hat - run.tau_dis)[late])),
        "rtob_error_max_nm": float(np.max(np.abs(run.tau_ext_hat - run.tau_ext)[late])),
        "rtob_rise_s": _rise_time(run.t, run.tau_ext_hat, run.tau_ext, at),
        "final_offset_rad": float(abs(run.q[-1] - run.q[np.searchsorted(run.t, at) - 1])),
    }


def observers(*, step: float = 0.004, at: float = 0.5, duration: float = 1.5,
              g_dis: float = 200.0, g_reac: float = 200.0,
              model_error: float = 0.0) -> tuple[dict[str, Any], ObserverRun]:
    """Run the joint without and with disturbance compensation; summarise both.

    Args:
        step: external torque step, N·m.
        at: time of the step, s.
        g_dis, g_reac: observer cut-offs, rad/s.
        model_error: relative error of the nominal inertia J_n (0.2 = 20 % too large).

    Returns:
        (figures, the uncompensated run's time series).
    """
    for name, value in (("g_dis", g_dis), ("g_reac", g_reac), ("duration", duration)):
        scalar(name, value, positive=True)
    scalar("step", step)
    if not 0.0 <= at < duration:
        raise ValueError(f"at must be within [0, duration), got {at}")
    if not -0.9 < scalar("model_error", model_error) < 10.0:
        raise ValueError(f"model_error must be in (-0.9, 10), got {model_error}")
    joint = TorqueJoint()
    j_n = joint.inertia * (1.0 + model_error)

    def tau_ext(t: float) -> float:
        return step if t >= at else 0.0

    settle = 5.0 / min(g_dis, g_reac)
    runs = {
        comp: simulate_observers(joint, tau_ext, duration=duration, j_n=j_n, g_dis=g_dis,
                                 g_reac=g_reac, compensate=comp)
        for comp in (False, True)
    }
    free, held = (_summary(runs[c], at, settle) for c in (False, True))
    figures = {
        "step_nm": step, "g_dis": g_dis, "g_reac": g_reac, "model_error": model_error,
        "expected_rise_s": 1.0 / g_reac,
        **free,
        "offset_compensated_rad": held["final_offset_rad"],
    }
    return figures, runs[False]


# -- on servos that measure their current ---------------------------------------------

BackendFactory = Callable[..., Backend]


def dob_series(t: np.ndarray, qd: np.ndarray, tau_m: np.ndarray, *, j_n: float,
               g_dis: float) -> np.ndarray:
    """The disturbance observer (thesis eq. 2.36 through the LPF of fig. 2.7–2.8) over a
    recording: τ̂_dis at every reading.

    Args:
        t: (N,) reading times, s (each step's own interval is its sample time: a bus is
            read at a jittery rate).
        qd: (N,) θ̇, rad/s.
        tau_m: (N,) K_tn I, N·m: the measured current through the datasheet's torque
            constant (what a current-sensing backend reports as ``JointState.load``), so
            the observer gets I in N·m with K_tn = 1.
        j_n: nominal inertia J_n, kg·m².  g_dis: cut-off, rad/s.

    Returns:
        (N,) τ̂_dis, N·m; the filter starts settled on the first reading.
    """
    state = ObserverState(z=float(tau_m[0] + g_dis * j_n * qd[0]))
    out = np.empty(len(t))
    out[0] = tau_m[0]
    for k in range(1, len(t)):
        dt = max(float(t[k] - t[k - 1]), 1e-6)
        out[k] = disturbance_observer(state, float(tau_m[k]), float(qd[k]), j_n=j_n,
                                      kt_n=1.0, g_dis=g_dis, dt=dt)
    return out


def known_torques(model: SerialChain, joint: int, q: np.ndarray, qd: np.ndarray
                  ) -> np.ndarray:
    """The RTOB's known load on ``joint`` at every reading: τ_g + τ_int of thesis eq. 2.37
    from the arm model, g(q) + C(q, q̇) q̇ (RNEA with q̈ = 0, thesis eq. 2.41–2.50) at the
    measured pose and speeds (thesis sign: the torque the motor must give to carry it).

    The joint's own J_n θ̈ is the observer's (its g J_n θ̇ terms); the other joints'
    accelerations are left out (the arm is held still). The model has no friction: what
    a held joint's gears hold stays in the estimate (nil at rest in the emulator's plant,
    part of the offset on a real arm).

    Args:
        q, qd: (N, n) positions rad and velocities rad/s of the whole arm.

    Returns:
        (N,) N·m.
    """
    return np.array([bias_torques(model, qk, qdk)[joint] for qk, qdk in zip(q, qd, strict=True)])


def rtob_series(t: np.ndarray, qd: np.ndarray, tau_m: np.ndarray, tau_known: np.ndarray, *,
                j_n: float, g_reac: float) -> np.ndarray:
    """The reaction-torque observer (thesis eq. 2.37) over a recording: τ̂_reac at every
    reading, the external load torque (thesis sign: the motor works against it, so a
    torque applied along the joint's axis reads as −τ̂_reac).

    Args:
        t, qd, tau_m: as :func:`dob_series` (K_tn I in N·m with K_tn = 1).
        tau_known: (N,) the known load, N·m (:func:`known_torques`).
        j_n: nominal inertia J_n, kg·m².  g_reac: cut-off, rad/s.

    Returns:
        (N,) τ̂_reac, N·m; the filter starts settled on the first reading.
    """
    # eq. 2.37 is eq. 2.36's filter with the known load taken out of its input
    # (armlab.control.observers.reaction_torque_observer)
    return dob_series(t, qd, np.asarray(tau_m) - np.asarray(tau_known), j_n=j_n,
                      g_dis=g_reac)


def step_index(x: np.ndarray) -> int:
    """Where a step in ``x`` is: the k that best splits it into two constant levels
    x[:k], x[k:] (least squares, the classic change point); 1 <= k < len(x)."""
    n = len(x)
    if n < 2:
        raise ValueError("need at least two readings to find a step")
    c, c2 = np.cumsum(x), np.cumsum(x * x)
    k = np.arange(1, n)
    left = c2[k - 1] - c[k - 1] ** 2 / k
    right = (c2[-1] - c2[k - 1]) - (c[-1] - c[k - 1]) ** 2 / (n - k)
    return int(k[np.argmin(left + right)])


def step_windows(t: np.ndarray, est: np.ndarray, *, at: float | None = None,
                 settle: float = SETTLE_S) -> tuple[float, np.ndarray, np.ndarray]:
    """Where a step in ``est`` is and its settled readings each side: (the step's time,
    the readings in [``settle``, step − :data:`MARGIN_S`), those in [step + ``settle``,
    end]) (t from the first reading; masks (N,)), the step at ``at`` s or, when None,
    where :func:`step_index` finds it.

    Raises:
        ValueError: a window shorter than :data:`MIN_WINDOW_S` (the step came too early or
            too late for the run's duration).
    """
    step_at = float(t[step_index(est)]) if at is None else float(at)
    before = (t >= settle) & (t < step_at - MARGIN_S)
    after = t >= step_at + settle
    for name, window in (("before", before), ("after", after)):
        span = float(np.ptp(t[window])) if window.any() else 0.0
        if span < MIN_WINDOW_S:
            raise ValueError(
                f"the step at {step_at:.2f} s of the {t[-1]:.2f} s run leaves {span:.2f} s of "
                f"settled readings {name} it (need {MIN_WINDOW_S} s, {settle} s after the "
                "torque went on and after the step): apply it later or earlier, or give a "
                "longer --duration")
    return step_at, before, after


def step_figures(t: np.ndarray, est: np.ndarray, *, at: float | None = None,
                 settle: float = SETTLE_S) -> dict[str, float]:
    """The DOB's estimate before and after a step: its medians over the settled readings
    of :func:`step_windows`, and the torque that step implies, −Δτ̂_dis."""
    step_at, before, after = step_windows(t, est, at=at, settle=settle)
    lo, hi = float(np.median(est[before])), float(np.median(est[after]))
    return {"step_at_s": step_at, "dob_before_nm": lo, "dob_after_nm": hi,
            "estimated_nm": -(hi - lo)}


def _check_current(backend: Backend) -> None:
    if not (isinstance(backend, CurrentSensing) and backend.senses_current):
        raise ValueError("these servos report no motor current (a load estimate, e.g. RX-24F "
                         "or XL430 Present Load): the disturbance observer needs K_t I; use "
                         "servos that measure their current (XM430-W350, XL330-M288) or "
                         "--backend sim")


def _go_to(backend: Backend, pose: np.ndarray, t: float, period: float) -> float:
    """Send the arm to ``pose`` at :data:`POSE_SPEED` and wait (reading every ``period``)
    until it is there and still; returns the backend time reached."""
    here = backend.read().position
    goal = np.clip(pose, backend.lower, backend.upper)
    backend.write(goal, np.full(len(goal), POSE_SPEED))
    timeout = float(np.max(np.abs(goal - here))) / POSE_SPEED + 5.0
    for _ in range(int(timeout / period)):
        t += period
        backend.sync(t)
        s = backend.read()
        if np.all(np.abs(s.position - goal) < POSE_TOLERANCE) and \
                np.all(np.abs(s.velocity) < STILL):
            return t
    raise ValueError(f"the arm did not reach --pose {np.degrees(goal).round(1).tolist()}° in "
                     f"{timeout:.1f} s (it stands at {np.degrees(s.position).round(1).tolist()}°)")


def hold_and_read(backend: Backend, joint: int, duration: float, *,
                  pose: np.ndarray | None = None, period: float = SERVO_PERIOD
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Torque on; hold the arm where it stands (goal = present position) or, given a
    ``pose`` (n,) rad, go there first and hold it; read the servos every ``period`` for
    ``duration`` s.

    Returns:
        (t from the first reading s (N,), the whole arm's q rad (N, n) and q̇ rad/s (N, n),
        K_t I N·m of ``joint`` (N,)).

    Raises:
        ValueError: the servos measure no current, the pose was not reached, or the
            servo switched its torque off (a hardware error).
    """
    _check_current(backend)
    backend.set_torque(True)
    t = backend.read().t
    if pose is None:
        here = backend.read().position
        backend.write(here, np.full(len(here), POSE_SPEED))
    else:
        t = _go_to(backend, pose, t, period)
    rows = []
    for _ in range(int(round(duration / period))):
        t += period
        backend.sync(t)
        s = backend.read()
        if not s.torque_on[joint]:
            alarm = s.alarms[joint] if s.alarms else ""
            raise ValueError(f"joint {joint}'s servo switched its torque off"
                             f"{': ' + alarm if alarm else ''}")
        rows.append((s.t, s.position, s.velocity, s.load[joint]))
    t_, q, qd, tau = (np.array(c) for c in zip(*rows, strict=True))
    return t_ - t_[0], q, qd, tau


def _release(backend: Backend) -> None:
    """Torque off (an e-stop if that fails) and close, whatever happened."""
    try:
        backend.set_torque(False)
    except Exception:  # noqa: BLE001 - the link may be gone: try the e-stop, then close
        backend.estop()
    finally:
        backend.close()


def servo_observers(model: SerialChain, backend_factory: BackendFactory, *, joint: int,
                    duration: float = SERVO_DURATION, g_dis: float = SERVO_G,
                    g_reac: float = SERVO_G, applied: float | None = None,
                    at: float | None = None, pose: np.ndarray | None = None,
                    period: float = SERVO_PERIOD, keep: Keep | None = None) -> dict[str, Any]:
    """The disturbance and reaction-torque observers on servos that measure their current:
    hold, read, estimate.

    J_n is the model's mass-matrix diagonal at the held pose (the rotor's reflected inertia
    is left out: at rest J_n θ̈ is nil and the estimate is K_tn I, whatever J_n). The
    RTOB's known load is :func:`known_torques` at every reading's measured pose.

    Args:
        model: the arm; ``backend_factory(model)`` opens its servos.
        joint: the joint index to observe.
        duration: s of holding and reading.  g_dis, g_reac: the DOB's and the RTOB's
            cut-offs, rad/s.
        applied: the torque applied to the joint during the run, N·m along its axis
            (positive like the joint's angle), to compare with; None: not known.
        at: s after the first reading the torque came; None: found in the estimate.
        pose: (n,) rad to go to and hold first (an arm hanging on its stops, whose
            torque the stops would share); None: hold where it stands.
        keep: handed the readings: the whole arm's angles as "q" at every reading (the
            observed joint's current and estimates are in the returned "series").

    Returns:
        {"joint", "j_n", "g_dis", "g_reac", "period_s", "samples", "step_at_s",
        "dob_before_nm", "dob_after_nm", "estimated_nm", "rtob_before_nm", "rtob_after_nm",
        ["applied_nm", "relative_error", "rtob_error_pct"], "series"}: τ̂_dis before and
        after (thesis sign: the load the motor works against, J θ̈ = K_t I − τ_dis), the
        applied torque that step implies, −Δτ̂_dis; the RTOB's estimate of the torque
        applied along the joint's axis (−τ̂_reac, like ``applied``) before the step (the
        model's offset: ~0 where the model is right) and after it, and its error against
        ``applied``, absolute (not a difference), in % of it.
    """
    shortest = 2.0 * (SETTLE_S + MIN_WINDOW_S)
    if not scalar("duration", duration, positive=True) >= shortest:
        raise ValueError(f"--duration must be at least {shortest:g} s on servos (settled "
                         f"readings before and after the step), got {duration:g}")
    scalar("g_dis", g_dis, positive=True)
    scalar("g_reac", g_reac, positive=True)
    index("joint", joint, model.n)
    if applied is not None and scalar("applied", applied) == 0.0:
        raise ValueError("--applied must not be 0 (the relative error divides by it)")
    if at is not None:
        scalar("at", at, nonnegative=True)
    backend = backend_factory(model)
    try:
        t, q, qd, tau = hold_and_read(backend, joint, duration, pose=pose, period=period)
    finally:
        _release(backend)
    j_n = float(mass_matrix(model, q[0])[joint, joint])
    est = dob_series(t, qd[:, joint], tau, j_n=j_n, g_dis=g_dis)
    known = known_torques(model, joint, q, qd)
    ext = -rtob_series(t, qd[:, joint], tau, known, j_n=j_n, g_reac=g_reac)
    figures: dict[str, Any] = {"joint": model.joint_names[joint], "j_n": j_n, "g_dis": g_dis,
                               "g_reac": g_reac, "period_s": period, "samples": len(t),
                               **step_figures(t, est, at=at)}
    _, before, after = step_windows(t, ext, at=figures["step_at_s"])
    figures["rtob_before_nm"] = float(np.median(ext[before]))
    figures["rtob_after_nm"] = float(np.median(ext[after]))
    if applied is not None:
        figures["applied_nm"] = applied
        figures["relative_error"] = abs(figures["estimated_nm"] - applied) / abs(applied)
        figures["rtob_error_pct"] = 100.0 * abs(figures["rtob_after_nm"] - applied) / abs(applied)
    sl = slice(None, None, SERVO_DECIMATE)
    if keep is not None:
        keep(Run(robot=model.name, joint_names=model.joint_names,
                 source="experiment:observers", lab_version=lab_version(), created=utc_now(),
                 params={"g_dis": g_dis, "g_reac": g_reac, "period": period,
                         "joint": model.joint_names[joint]},
                 commands=({"t": 0.0, "kind": "Hold", "pose_rad": q[0].tolist()},),
                 figures={}, t=t, signals={"q": q}))
    figures["series"] = {"t": t[sl].tolist(), "q": q[sl, joint].tolist(),
                         "qd": qd[sl, joint].tolist(), "tau_m": tau[sl].tolist(),
                         "tau_dis_hat": est[sl].tolist(), "tau_known": known[sl].tolist(),
                         "applied_hat": ext[sl].tolist()}
    return figures


# -- options -------------------------------------------------------------------------

@dataclass(frozen=True)
class ObserverOptions(BackendOptions):
    """Options of ``observers`` (see :func:`observers` and :func:`servo_observers`)."""

    step: float | None = option(None, f"external torque step, N·m (simulation; default "
                                f"{SIM_STEP:g})")
    at: float | None = option(None, f"time of the step, s (default {SIM_AT:g}; on servos: s "
                              "after the first reading, default: found in the estimate)")
    g_dis: float | None = option(None, f"DOB cut-off, rad/s (default {SIM_G:g}; "
                                 f"{SERVO_G:g} on servos)")
    g_reac: float | None = option(None, f"RTOB cut-off, rad/s (default {SIM_G:g}; "
                                  f"{SERVO_G:g} on servos)")
    model_error: float | None = option(None, "relative error of the nominal inertia J_n "
                                       "(0.2 = 20 %% too large; simulation, default 0)")
    duration: float | None = option(None, f"s of the run (default {SIM_DURATION:g}; "
                                    f"{SERVO_DURATION:g} on servos)")
    robot: str | None = option(None, f"robot model on servos (default {SERVO_ROBOT})",
                               metavar="NAME")
    joint: str | None = option(None, "on servos: the joint to observe, index or name "
                               "(e.g. 1 or joint2)", metavar="J")
    applied: float | None = option(None, "on servos: the torque applied to the joint during "
                                   "the run, N·m along its axis, to compare with",
                                   metavar="NM")
    pose: str | None = option(None, "on servos: go to these joint angles first, degrees "
                              "(comma-separated), then hold (default: hold where the arm "
                              "stands)", metavar="DEG,...")


_SIM_ONLY = ("step", "model_error")
_SERVO_ONLY = ("robot", "joint", "applied", "pose")


def _run(options: ObserverOptions, *, backend_factory: BackendFactory | None = None,
         keep: Keep | None = None) -> dict[str, Any]:
    o = options
    if o.backend == "sim":
        given = [n for n in _SERVO_ONLY + ("port", "baud") if getattr(o, n) is not None]
        if given:
            raise ValueError(f"{_names(given)} for the servos (--backend serial)")
        return _sim_run(o, keep=keep)
    given = [n for n in _SIM_ONLY if getattr(o, n) is not None]
    if given:
        raise ValueError(f"{_names(given)} for the simulation (--backend sim); on servos "
                         "apply a torque to the joint and give it as --applied")
    if o.joint is None:
        raise ValueError("--joint: name the joint to observe on the servos (index or name)")
    if backend_factory is None:
        raise ValueError("the servo run needs a backend_factory")
    model = load_robot(o.robot or SERVO_ROBOT)
    if not isinstance(model, SerialChain):
        raise ValueError(f"--robot {o.robot}: the observers run on a serial arm")
    pose = None
    if o.pose is not None:
        try:
            values = [float(x) for x in o.pose.split(",")]
        except ValueError:
            raise ValueError(f"--pose: {model.n} angles in degrees, comma-separated; got "
                             f"{o.pose!r}") from None
        pose = np.radians(vector("--pose", values, model.n))
    return servo_observers(model, backend_factory, joint=joint_index(o.joint, model.joint_names),
                           duration=SERVO_DURATION if o.duration is None else o.duration,
                           g_dis=SERVO_G if o.g_dis is None else o.g_dis,
                           g_reac=SERVO_G if o.g_reac is None else o.g_reac,
                           applied=o.applied, at=o.at, pose=pose, keep=keep)


def _names(fields: list[str]) -> str:
    """"--step is" / "--step, --g-reac are": the options named by their fields."""
    opts = ", ".join("--" + f.replace("_", "-") for f in fields)
    return f"{opts} {'is' if len(fields) == 1 else 'are'}"


def _sim_run(o: ObserverOptions, *, keep: Keep | None = None) -> dict[str, Any]:
    figures, run = observers(step=SIM_STEP if o.step is None else o.step,
                             at=SIM_AT if o.at is None else o.at,
                             duration=SIM_DURATION if o.duration is None else o.duration,
                             g_dis=SIM_G if o.g_dis is None else o.g_dis,
                             g_reac=SIM_G if o.g_reac is None else o.g_reac,
                             model_error=0.0 if o.model_error is None else o.model_error)
    sl = slice(None, None, DECIMATE)
    figures["series"] = {k: getattr(run, k)[sl].tolist()
                         for k in ("t", "tau_dis", "tau_dis_hat", "tau_ext", "tau_ext_hat")}
    if keep is not None:
        # the same rows as "series": θ, and the RTOB's estimate as the run's τ_ext
        keep(Run(robot="torque_joint", joint_names=("joint",), source="experiment:observers",
                 lab_version=lab_version(), created=utc_now(),
                 params={k: figures[k] for k in ("step_nm", "g_dis", "g_reac", "model_error")},
                 commands=({"t": SIM_AT if o.at is None else o.at, "kind": "TorqueStep",
                            "torque_nm": figures["step_nm"]},),
                 figures={}, t=run.t[sl],
                 signals={"q": run.q[sl, None], "tau_ext": run.tau_ext_hat[sl, None]}))
    return figures


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    s = result["series"]
    return [dict(zip(s, vals, strict=True)) for vals in zip(*s.values(), strict=True)]


EXPERIMENTS = (
    Experiment("observers", "disturbance and reaction-torque observers on a torque-driven "
               "joint (thesis eq. 2.36, 2.37); both on current-sensing servos with "
               "--backend serial, where rtob_before_nm (the RTOB with nothing applied) is "
               "the arm model's error: ~0 on the emulator (same model), an offset on a "
               "real arm", ObserverOptions, _run, _rows, needs=("backend_factory",)),
)
