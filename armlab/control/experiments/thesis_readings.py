"""``armlab experiment thesis-readings``: which reading of Table 4.1 reproduces chapter 4?

Thesis 000 prints Kp 3.8, Kv 0.2 (Table 4.1 with K_f 0.3, K_env 12, D_env 5,
M_env 1) without units, and reports three figures on the 20 cm line: no
position controller 6° to over 20°, the PD loop under 6°, compliance under a
push over 15° on servo 3 (all command minus actual, max |θ_cmd − θ|). Read in SI
the PD loop lags 19.5°. This study tries every reading of the gains and units the
firmware could have used, on the lab's simulated arm through the lab's loop
(:func:`armlab.control.experiments.thesis.thesis_line_figures`), and says for each which
of the three figures it reproduces:

- ``SI``: Kp 1/s², Kv 1/s, as the lab reads them.
- ``per control period``: θ̇ += θ̈ and θ += θ̇ each period without T (time in
  periods): Kp/T², Kv/T in SI.
- ``Kv per period``: only the velocity term per period, Kv/T (Kp SI).
- ``servo counts in, degrees out``: error in counts (0.293°), θ̈ in °/s²: Kp/0.293.
- ``degrees in, servo counts out``: the reverse, Kp·0.293.
- ``radians in, degrees out``: Kp·57.3.
- ``torque in kgf·cm``: τ_ext fed to eq. 2.7 in kgf·cm, i.e. K_f·10.2 in SI.
- ``explicit Euler``: θ += T θ̇ before θ̇ += T θ̈ (the other order of the
  firmware listing's two sums) — compared on the ideal joint's poles, since at
  ωp T = 0.03 the order changes the SI loop by under 0.1 %.
- ``line takes N s``: the thesis's 2.5 mm per iteration at a longer real
  iteration time than the 16 ms sample.

Readings whose gains fall outside the lab's parameter ranges are not run: their
ideal-joint pole radius and their pole through the servos' lag
(:func:`armlab.control.params.servo_loop_pole`) are reported instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, cast

import numpy as np

from armlab.control.experiments import BackendOptions, Experiment, Keep, option
from armlab.control.experiments.thesis import BackendFactory, thesis_line_figures
from armlab.control.params import PRESETS, Params, integrated_pd_matrix, servo_loop_pole
from armlab.control.trajectory import THESIS_PERIOD
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.units import KGF_CM_PER_NM

COUNT_DEG = 300.0 / 1023.0  #: degrees per Dynamixel position count (RX-24F, AX-12A)
PUSH_N = 3.0  #: the thesis-line experiment's push, N
#: Chapter 4's three figures as tests on max |θ_cmd − θ| (degrees).
THESIS_FIGURES = {
    "none_6_to_20": "no controller: 6° to over 20°",
    "pd_under_6": "PD loop: under 6°",
    "compliance_pushed_over_15": "compliance under a push: over 15° on servo 3",
}


@dataclass(frozen=True)
class Reading:
    """One way to read Table 4.1's numbers, as SI gains for the lab's loop.

    Attributes:
        name: what the reading assumes.
        kp, kv: Kp (1/s²) and Kv (1/s) in SI under this reading.
        k_f: K_f in SI under this reading.
        line_period: s per 2.5 mm step of the line.
        explicit: True for explicit Euler (θ += T θ̇ first), judged on poles only.
    """

    name: str
    kp: float
    kv: float
    k_f: float = 0.3
    line_period: float = THESIS_PERIOD
    explicit: bool = False


def readings(period: float = THESIS_PERIOD) -> list[Reading]:
    """Every reading the study tries (Table 4.1: Kp 3.8, Kv 0.2, K_f 0.3)."""
    kp, kv, kf, T = 3.8, 0.2, 0.3, period
    return [
        Reading("SI", kp, kv),
        Reading("explicit Euler (SI)", kp, kv, explicit=True),
        Reading("per control period", kp / T**2, kv / T),
        Reading("explicit Euler, per control period", kp / T**2, kv / T, explicit=True),
        Reading("Kv per period", kp, kv / T),
        Reading("servo counts in, degrees out", kp / COUNT_DEG, kv / COUNT_DEG),
        Reading("degrees in, servo counts out", kp * COUNT_DEG, kv * COUNT_DEG),
        Reading("radians in, degrees out", kp * math.degrees(1.0), kv * math.degrees(1.0)),
        Reading("torque in kgf·cm", kp, kv, k_f=kf * KGF_CM_PER_NM),
        Reading("Kv per period, torque in kgf·cm", kp, kv / T, k_f=kf * KGF_CM_PER_NM),
        Reading("line takes 2.56 s", kp, kv, line_period=2 * T),
        Reading("line takes 6.4 s", kp, kv, line_period=5 * T),
    ]


def pole_radius(kp: float, kv: float, period: float, *, explicit: bool) -> float:
    """Spectral radius of the reference loop on an ideal joint (>= 1: it diverges).

    Semi-implicit Euler (the lab's order, :func:`armlab.control.params.integrated_pd_matrix`)
    or explicit Euler, state (θ, θ̇): θ += T θ̇, θ̇ += T (−Kp θ − Kv θ̇).
    """
    T = period
    A = (np.array([[1.0, T], [-T * kp, 1.0 - T * kv]]) if explicit
         else integrated_pd_matrix(kp, kv, T))
    return float(np.max(np.abs(np.linalg.eigvals(A))))


def judge(none: list[float], pd: list[float] | None,
          pushed: list[float] | None) -> dict[str, bool]:
    """Which of chapter 4's three figures a reading's runs reproduce."""
    return {
        "none_6_to_20": max(none) >= 6.0,
        "pd_under_6": pd is not None and max(pd) < 6.0,
        "compliance_pushed_over_15": pushed is not None and pushed[2] > 15.0,
    }


def study(backend_factory: BackendFactory, *, robot: str = "receptionist_arm",
          only: str | None = None, keep: Keep | None = None) -> dict[str, Any]:
    """Run every reading (or the one named ``only``) on the simulated line; ``keep`` is
    handed every line run, in the order they ran.

    Returns:
        {"thesis_figures": what each "reproduces" key checks, "readings": [{"name", "kp",
        "kv", "k_f", "line_s", "pole_radius",
        "servo_zeta", "none", "pd", "compliance_pushed", "refused", "reproduces"}],
        "any_reproduces_all": bool}. Angles are max |θ_cmd − θ| per joint, degrees;
        "compliance_pushed" is the run with the 3 N push; None where not run.
    """
    model = cast(SerialChain, load_robot(robot))  # an arm's name: the study drives an arm
    base = PRESETS["thesis Table 4.1"]
    chosen = [r for r in readings(base.period) if only is None or r.name == only]
    if not chosen:
        raise ValueError(f"unknown reading {only!r}; known: "
                         f"{', '.join(repr(r.name) for r in readings())}")
    none_cache: dict[float, list[float]] = {}
    out = []
    for r in chosen:
        radius = pole_radius(r.kp, r.kv, base.period, explicit=r.explicit)
        servo_zeta, _ = servo_loop_pole(r.kp, r.kv, base.period)
        row: dict[str, Any] = {
            "name": r.name, "kp": round(r.kp, 4), "kv": round(r.kv, 4), "k_f": round(r.k_f, 4),
            "line_s": round(80 * r.line_period, 3), "pole_radius": round(radius, 4),
            "servo_zeta": round(servo_zeta, 3), "none": None, "pd": None,
            "compliance_pushed": None, "refused": None,
        }
        if r.line_period not in none_cache:  # no controller: the gains play no part
            none_cache[r.line_period] = thesis_line_figures(
                model, backend_factory, base, controller="none", push_n=0.0,
                line_period=r.line_period, keep=keep)["max_angle_error_deg"]
        row["none"] = none_cache[r.line_period]
        if radius >= 1.0:
            row["refused"] = f"the reference loop diverges (pole radius {radius:.3f})"
        elif r.explicit:
            twin = pole_radius(r.kp, r.kv, base.period, explicit=False)
            row["refused"] = (f"same loop as its semi-implicit twin to within "
                              f"{abs(radius - twin):.1e} in pole radius")
        else:
            try:
                params: Params | None = replace(base, kp=r.kp, kv=r.kv, k_f=r.k_f)
            except ValueError as exc:
                params, row["refused"] = None, str(exc)
            if params is not None:
                try:
                    row["pd"] = thesis_line_figures(
                        model, backend_factory, params, controller="pd", push_n=0.0,
                        line_period=r.line_period, keep=keep)["max_angle_error_deg"]
                    row["compliance_pushed"] = thesis_line_figures(
                        model, backend_factory, params, controller="compliance",
                        push_n=PUSH_N, line_period=r.line_period,
                        keep=keep)["max_angle_error_pushed_deg"]
                except ValueError as exc:  # the loop stopped on a fault
                    row["refused"] = str(exc)
        row["reproduces"] = judge(row["none"], row["pd"], row["compliance_pushed"])
        out.append(row)
    return {"thesis_figures": dict(THESIS_FIGURES), "readings": out,
            "any_reproduces_all": any(all(r["reproduces"].values()) for r in out)}


@dataclass(frozen=True)
class ReadingOptions(BackendOptions):
    """Options of ``thesis-readings`` (see :func:`study`)."""

    reading: str | None = option(None, "run only this reading (default: all): "
                                 + ", ".join(repr(r.name) for r in readings()), metavar="NAME")
    robot: str = option("receptionist_arm", "robot model", hidden=True)


def _run(options: ReadingOptions, *, backend_factory: BackendFactory,
         keep: Keep | None = None) -> dict[str, Any]:
    return study(backend_factory, robot=options.robot, only=options.reading, keep=keep)


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    def fmt(x: list[float] | None) -> str:
        return "—" if x is None else "/".join(f"{v:.1f}" for v in x)

    return [{"reading": r["name"], "Kp": r["kp"], "Kv": r["kv"], "K_f": r["k_f"],
             "line_s": r["line_s"], "pole_radius": r["pole_radius"],
             "servo_zeta": r["servo_zeta"], "none_deg": fmt(r["none"]), "pd_deg": fmt(r["pd"]),
             "compliance_pushed_deg": fmt(r["compliance_pushed"]),
             "reproduces": ", ".join(k for k, v in r["reproduces"].items() if v) or "none",
             "not_run": r["refused"] or ""} for r in result["readings"]]


EXPERIMENTS = (
    Experiment("thesis-readings", "thesis Table 4.1: every reading of its gains and units on "
               "the simulated line, and which of chapter 4's figures each reproduces",
               ReadingOptions, _run, _rows, needs=("backend_factory",)),
)
