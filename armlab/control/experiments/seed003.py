"""``armlab experiment seed003-gait``: one cycle of the quadruped's trot or crawl.

Foot positions from the sine pattern of seed 003 Table 1.1 (trot) or a statically
stable crawl, joint angles from the leg IK (eq. 3.1-3.9), the body walked across the
floor so that the stance feet stay put, and the static stability margin of every sample.

Then (``--cycles`` > 0) the gait walks on 12 servos: simulated AX-12A legs carrying the
body (default), or servos on ``--backend serial --port`` (the emulator's legs carry it
too). From the servos' reports come seed 003's two figures: the eq. 4.1 error
(commanded vs reported angle, per servo number and overall; the seed: 1.201 %, servo 2
worst) and the body's tilt that the deflected legs imply on flat ground (the seed:
3.6–5.7°, :func:`armlab.kinematics.body_statics.implied_tilt_deg`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from armlab.control.experiments import BackendOptions, Experiment, Keep, option
from armlab.control.gait_loop import STAND_UP_S, GaitLoop
from armlab.control.runs import Run, lab_version, run_from_snapshot, utc_now
from armlab.control.trajectory import APPROACH_SPEED
from armlab.control.walking import GaitSpec, Walker, plan_gait, walking_tilts_deg
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.gait import SineParams, crawl, cycle_angles, cycle_margins, trot, walk
from armlab.kinematics.model import Quadruped
from armlab.kinematics.quadruped import LEGS, QuadrupedGeometry

#: plant step of the simulated legs, s (``armlab.hardware.families.dynamixel1.quadruped.SIM_DT``)
SIM_DT = 2e-3
SPEED = 0.5  #: gait cycles per second on the servos (and in the planned cycle's run file)


def joint_names(model: Quadruped) -> tuple[str, ...]:
    """The 12 joints in the gait's order: each leg of :data:`LEGS`, hip yaw to knee."""
    return tuple(name for leg in LEGS for name in model.legs[leg].joint_names)


def gait_cycle(gait: str = "trot", params: SineParams | None = None, *, samples: int = 36,
               right_direction: int = 0, keep: Keep | None = None) -> dict[str, Any]:
    """One cycle of ``gait`` ("trot" or "crawl"); lengths in m, angles in degrees.

    ``rows`` holds one entry per sample: phase, body pose, stance flags, feet (leg frames
    and world), joint angles and static stability margin. ``keep`` is handed the planned
    cycle: its 12 joint angles (IK) as "q_cmd" and "q", one sample per row, timed at
    :data:`SPEED` cycles/s (phase / 360° / SPEED s); nothing is measured in it.
    """
    params = params or SineParams()
    geom = QuadrupedGeometry()
    if gait == "trot":
        cycle = trot(params, samples=samples,
                     directions={"RF": right_direction, "RH": right_direction})
    elif gait == "crawl":
        cycle = crawl(params, geom, samples=samples)
    else:
        raise ValueError(f"gait must be trot or crawl, got {gait!r}")
    angles, reachable = cycle_angles(cycle, geom)
    warnings = [] if reachable else [
        f"some feet are out of the leg's reach ({geom.leg.femur + geom.leg.tibia:.3f} m from "
        "the hip): their joint angles are the nearest reachable pose"]
    # Two cycles: the first is the cycle itself, the same phase in the second gives the advance.
    moved = walk(cycle, geom, cycles=2)
    margins = cycle_margins(cycle, moved, angles, geom)
    out = []
    for j, w in enumerate(cycle.omega_deg):
        out.append({
            "omega_deg": float(w),
            "body": moved.body[j].tolist(),
            "stance": {leg: bool(cycle.stance[j, i]) for i, leg in enumerate(LEGS)},
            "feet_m": {leg: cycle.feet[j, i].tolist() for i, leg in enumerate(LEGS)},
            "feet_world_m": {leg: moved.feet_world[j, i].tolist() for i, leg in enumerate(LEGS)},
            "angles_deg": {leg: np.degrees(angles[j, i]).tolist() for i, leg in enumerate(LEGS)},
            "margin_m": float(margins[j]) if math.isfinite(margins[j]) else None,
        })
    n = len(cycle.omega_deg)
    if keep is not None:
        q = np.asarray(angles, dtype=float).reshape(n, 12)
        keep(Run(robot="quadruped", joint_names=joint_names(load_robot_quadruped()),
                 source="experiment:seed003-gait", lab_version=lab_version(),
                 created=utc_now(), params={"gait": gait, **params.named()},
                 commands=({"t": 0.0, "kind": "Gait", "gait": gait,
                            "speed_cycles_s": SPEED},),
                 figures={}, t=np.asarray(cycle.omega_deg, dtype=float) / 360.0 / SPEED,
                 signals={"q_cmd": q, "q": q.copy()},
                 extra={"planned": True, "series": {
                     "body": moved.body[:n].tolist(),
                     "margin_m": [float(m) if math.isfinite(m) else None
                                  for m in margins[:n]]}}))
    return {
        "gait": gait,
        "params": params.named(),
        "leg_m": {"femur": geom.leg.femur, "tibia": geom.leg.tibia},
        "reachable": reachable,
        "min_margin_m": float(np.min(margins)),
        "max_slip_m": float(np.max(moved.slip)),
        "advance_per_cycle_m": (moved.body[n, :2] - moved.body[0, :2]).tolist(),
        "yaw_per_cycle_rad": float(moved.body[n, 3] - moved.body[0, 3]),
        "warnings": warnings,
        "rows": out,
    }


def walk_on_servos(backend_factory: Any, gait: str = "trot", params: SineParams | None = None,
                   *, cycles: float = 2.0, speed: float = SPEED, period: float = 0.02,
                   realtime: bool = False, keep: Keep | None = None) -> dict[str, Any]:
    """Walk ``cycles`` gait cycles on the 12 servos ``backend_factory(model, q0=...)`` opens;
    ``keep`` is handed the loop's record (goals sent "q_cmd", angles read "q", per period).

    Returns:
        {"eq41_error_pct": {"servo1", "servo2", "servo3", "overall"}, "body_tilt_deg" (max),
        "body_tilt_mean_deg", "eq41_samples"}: eq. 4.1 over the walking samples (mean |%| per
        servo number in the legs, and over all 12), and the tilt the reported angles imply.

    Raises:
        ValueError: the servos faulted or gave no walking samples.
    """
    model = load_robot_quadruped()
    plan = plan_gait(GaitSpec(gait=gait, params=params or SineParams()))
    walker = Walker(plan)
    kw = {"q0": walker.state().q, "dt": SIM_DT} if not realtime else {}
    backend = backend_factory(model, **kw)
    to_servo = getattr(getattr(backend, "map", None), "to_servo", None)
    # servos found folded rise for longer than STAND_UP_S, at the approach speed
    rise_max = max(STAND_UP_S, math.pi / APPROACH_SPEED)
    loop = GaitLoop(walker, backend, period=period, realtime=realtime, speed=speed,
                    to_servo=to_servo, history_s=rise_max + cycles / speed + 5.0)
    try:
        loop.go(plan)
        duration = STAND_UP_S + cycles / speed + 2 * period
        if realtime:
            loop.start()
            end = time.monotonic() + 3 * (rise_max + duration) + 10.0

            def wait(done: Callable[[], bool]) -> None:
                while not done() and not loop.status.fault:
                    if time.monotonic() > end:
                        raise ValueError("the servos did not keep up with the gait loop")
                    time.sleep(0.02)

            # risen from wherever the servos were, then the cycles walked
            wait(lambda: loop.status.t > 3 * period and not loop.status.standing_up)
            walked = loop.status.t + cycles / speed + 2 * period
            wait(lambda: loop.status.t >= walked)
            loop.shutdown(torque_off=True)
        else:
            loop.run_for(duration)
        if loop.status.fault:
            raise ValueError(f"the servos stopped: {loop.status.fault}")
        err = loop.angle_error(None)
        if err is None:
            raise ValueError("no walking samples were read from the servos")
        snap = loop.snapshot()
        tilt = walking_tilts_deg(model, snap)
        if keep is not None:
            keep(run_from_snapshot(
                snap, robot="quadruped", joint_names=joint_names(model),
                source="experiment:seed003-gait",
                params={"gait": gait, **(params or SineParams()).named(), "speed": speed,
                        "period": period},
                commands=({"t": 0.0, "kind": "Gait", "gait": gait, "speed_cycles_s": speed,
                           "cycles": cycles},)))
    finally:
        if loop.status.running:
            loop.shutdown(torque_off=True)
        backend.close()
    per = err["per_servo_pct"]
    return {
        "eq41_error_pct": {"servo1": round(float(per[0]), 4), "servo2": round(float(per[1]), 4),
                           "servo3": round(float(per[2]), 4),
                           "overall": round(float(err["mean_pct"]), 4)},
        "body_tilt_deg": round(float(tilt.max()), 3),
        "body_tilt_mean_deg": round(float(tilt.mean()), 3),
        "eq41_samples": int(err["samples"]),
    }


def load_robot_quadruped() -> Quadruped:
    """The quadruped's model (ValueError if its URDF does not load as one)."""
    model = load_robot("quadruped")
    if not isinstance(model, Quadruped):
        raise ValueError("robot: the quadruped's URDF did not load as a quadruped")
    return model


_D = SineParams()


@dataclass(frozen=True)
class GaitOptions(BackendOptions):
    """Options of ``seed003-gait`` (lengths in cm, as the seed gives them)."""

    gait: Literal["trot", "crawl"] = option("trot", "trot (default) or crawl")
    A: float = option(_D.A * 100, "step length, cm")
    B: float = option(_D.B * 100, "outward offset of the foot from the hip, cm")
    C: float = option(_D.C * 100, "step height, cm")
    D: float = option(_D.D * 100, "body height (hip above the floor), cm")
    alpha: float = option(_D.alpha_deg, "heading alpha, degrees (90 = straight ahead)")
    samples: int = option(36, "samples per cycle")
    right_direction: Literal[0, 1] = option(
        0, "direction index of the right legs (trot; 1 turns right)")
    cycles: float = option(2.0, "gait cycles walked on the servos for eq. 4.1 and the body "
                           "tilt (0: the planned cycle only)")


def _run(options: GaitOptions, *, backend_factory: Any, keep: Keep | None = None
         ) -> dict[str, Any]:
    o = options
    params = SineParams(A=o.A / 100, B=o.B / 100, C=o.C / 100, D=o.D / 100, alpha_deg=o.alpha)
    if not (math.isfinite(o.cycles) and 0.0 <= o.cycles <= 20.0):
        raise ValueError(f"--cycles must be in [0, 20], got {o.cycles}")
    out = gait_cycle(o.gait, params, samples=o.samples, right_direction=o.right_direction,
                     keep=keep)
    if o.cycles > 0:
        out.update(walk_on_servos(backend_factory, o.gait, params, cycles=o.cycles,
                                  realtime=o.backend != "sim", keep=keep))
    return out


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for s in result["rows"]:
        for leg in LEGS:
            x, y, z = s["feet_m"][leg]
            t1, t2, t3 = s["angles_deg"][leg]
            rows.append({"omega_deg": s["omega_deg"], "leg": leg, "stance": s["stance"][leg],
                         "x_m": x, "y_m": y, "z_m": z, "th1_deg": t1, "th2_deg": t2,
                         "th3_deg": t3, "body_x_m": s["body"][0], "margin_m": s["margin_m"]})
    return rows


EXPERIMENTS = (
    Experiment(
        name="seed003-gait",
        help="seed 003: one cycle of the quadruped's trot or crawl (feet, joints, margin), "
             "then walked on servos: eq. 4.1 error and body tilt",
        options=GaitOptions,
        run=_run,
        rows=_rows,
        needs=("backend_factory",),
    ),
)
