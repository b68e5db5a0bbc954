"""``armlab experiment seed004-table``: the 24 targets of seed 004 Table 1, recomputed.

For each target on the line X + Y = 23 cm: the exact closed-form angles (elbow-down by
default), the whole-degree commanded angles (servo command truncated, as the paper's
controller does), their forward kinematics (X1, Y1) beside the paper's computed and
measured values, and whether the servos can reach it. Targets outside the servo range
get an in-range alternative (another end-effector orientation) and its position error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from armlab.control.experiments import Experiment, Keep, option
from armlab.control.experiments.seed004_data import TABLE1
from armlab.control.runs import Run, lab_version, utc_now
from armlab.kinematics.planar_ik import ELBOWS, ROUNDINGS, PlanarArm, in_range_alternative, solve

#: The robot model of the seed 004 arm (6.5, 10.5, 6.5 cm links), for its run file.
ROBOT = "planar_servo_arm"
JOINTS = ("theta1", "theta2", "theta3")


def _deg(angles: tuple[float, ...]) -> list[float]:
    return [math.degrees(a) for a in angles]


def _cm(xy: tuple[float, float]) -> list[float]:
    return [xy[0] * 100.0, xy[1] * 100.0]


def table(*, rounding: str = "truncate", elbow: str = "down",
          keep: Keep | None = None) -> dict[str, Any]:
    """Recompute seed 004 Table 1 (see the module docstring); lengths in cm, angles in deg.

    The table has no time series: ``keep`` is handed the 24 poses one per second, t = 0,
    1, ... s (row k at k s): "q_cmd" the exact closed-form angles, "q" the whole-degree
    commanded angles the servos are sent (no angle was measured; the paper measured
    positions, which are in the rows)."""
    arm = PlanarArm()
    rows = []
    exact, sent = [], []
    for no, X, Y, X1, Y1, X2, Y2, _dx, _dy, R in TABLE1:
        r = solve(X / 100.0, Y / 100.0, arm=arm, elbow=elbow, rounding=rounding)
        computed = _cm(r.position)
        exact.append(r.angles)
        sent.append(r.commanded)
        row: dict[str, Any] = {
            "no": int(no),
            "target_cm": [X, Y],
            "angles_deg": _deg(r.angles),
            "commanded_deg": _deg(r.commanded),
            "servo_deg": list(r.servo_deg),
            "computed_cm": computed,
            "in_servo_range": r.in_servo_range,
            "paper_computed_cm": [X1, Y1],
            "paper_measured_cm": [X2, Y2],
            "paper_r_cm": R,
            "r_cm": math.hypot(computed[0] - X2, computed[1] - Y2),
            "computed_vs_paper_cm": math.hypot(computed[0] - X1, computed[1] - Y1),
            "alternative": None,
        }
        if not r.in_servo_range:
            alt = in_range_alternative(X / 100.0, Y / 100.0, arm=arm, elbow=elbow,
                                       rounding=rounding)
            if alt is not None:
                a = alt.result
                row["alternative"] = {
                    "theta0_deg": math.degrees(a.theta0),
                    "theta0_shift_deg": math.degrees(alt.theta0_shift),
                    "elbow": "down" if a.angles[1] <= 0 else "up",
                    "angles_deg": _deg(a.angles),
                    "commanded_deg": _deg(a.commanded),
                    "servo_deg": list(a.servo_deg),
                    "computed_cm": _cm(a.position),
                    "error_cm": alt.error * 100.0,
                }
        rows.append(row)
    if keep is not None:
        keep(Run(robot=ROBOT, joint_names=JOINTS, source="experiment:seed004-table",
                 lab_version=lab_version(), created=utc_now(),
                 params={"rounding": rounding, "elbow": elbow},
                 commands=tuple({"t": float(k), "kind": "Target", "no": row["no"],
                                 "target_cm": row["target_cm"]} for k, row in enumerate(rows)),
                 figures={}, t=np.arange(len(rows), dtype=float),
                 signals={"q_cmd": np.array(exact), "q": np.array(sent)},
                 extra={"t_is": "the row's index in Table 1 (not a time: the table has no "
                                "time series)"}))
    return {
        "rounding": rounding,
        "elbow": elbow,
        "servo_offset_deg": list(arm.servo_offset_deg),
        "paper_mean_r_cm": sum(r["paper_r_cm"] for r in rows) / len(rows),
        "rows": rows,
    }


@dataclass(frozen=True)
class TableOptions:
    """Options of ``seed004-table`` (see :func:`table`)."""

    rounding: str = option("truncate", "whole-degree rounding of the servo command "
                           "(paper: truncate)", choices=ROUNDINGS)
    elbow: str = option("down", "branch of the two-link solution (paper: down)", choices=ELBOWS)


def _run(options: TableOptions, *, keep: Keep | None = None) -> dict[str, Any]:
    return table(rounding=options.rounding, elbow=options.elbow, keep=keep)


def _rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    for r in result["rows"]:
        alt = r["alternative"] or {}
        out.append({
            "no": r["no"],
            "X": r["target_cm"][0], "Y": r["target_cm"][1],
            "th1": r["angles_deg"][0], "th2": r["angles_deg"][1], "th3": r["angles_deg"][2],
            "cmd1": r["commanded_deg"][0], "cmd2": r["commanded_deg"][1],
            "cmd3": r["commanded_deg"][2],
            "X1": r["computed_cm"][0], "Y1": r["computed_cm"][1],
            "paper_X1": r["paper_computed_cm"][0], "paper_Y1": r["paper_computed_cm"][1],
            "in_range": r["in_servo_range"],
            "paper_X2": r["paper_measured_cm"][0], "paper_Y2": r["paper_measured_cm"][1],
            "paper_R": r["paper_r_cm"], "R": r["r_cm"],
            "alt_X1": alt.get("computed_cm", [None])[0],
            "alt_Y1": alt.get("computed_cm", [None, None])[1],
            "alt_error_cm": alt.get("error_cm"),
        })
    return out


EXPERIMENTS = (
    Experiment(
        name="seed004-table",
        help="seed 004 Table 1: closed-form IK, whole-degree servo commands, servo range",
        options=TableOptions,
        run=_run,
        rows=_rows,
    ),
)
