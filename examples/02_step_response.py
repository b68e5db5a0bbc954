"""A step response of the PD loop beside the design formulas (thesis eq. 2.11–2.20).

Run it from the repository's root:  python examples/02_step_response.py [Kp Kv]

The PD loop θ̈_ref = Kp (θ_cmd − θ) − Kv θ̇ (eq. 2.20) is a second-order system with
ωn = √Kp (eq. 2.11) and ζ = Kv / (2√Kp) (eq. 2.12), so its step response should show
Tp (2.16), %OS (2.17), Ts (2.18) and Tr (2.19). Three columns:

- formula: the equations;
- ideal joint: the law on a joint that does exactly what it is told (no servo);
- simulated arm: a 20° step of the elbow (θ2) on the simulated arm, its three RX-24F
  servos in the loop; the servos' own lag is what makes this column differ.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import armlab
from armlab.control.commands import RunTrajectory
from armlab.control.loop import ControlLoop
from armlab.control.params import DEFAULT
from armlab.control.response import measure_step, plan_step, step_report
from armlab.control.trajectory import thesis_line
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend

FIGURES = (("peak_time_s", "Tp, s (2.16)"), ("overshoot_pct", "%OS (2.17)"),
           ("settling_time_s", "Ts, s (2.18)"), ("rise_time_s", "Tr, s (2.19)"))


def fmt(x: float | None) -> str:
    """A figure with 3 decimals, or "—" where the response has none (no overshoot)."""
    return "—" if x is None or not math.isfinite(x) else f"{x:.3f}"


def main(argv: list[str] | None = None) -> None:
    """Step θ2 by 20° with gains ``[Kp Kv]`` (the lab's defaults without them); print a table."""
    args = sys.argv[1:] if argv is None else argv
    kp, kv = (float(args[0]), float(args[1])) if len(args) == 2 else (DEFAULT.kp, DEFAULT.kv)
    params = replace(DEFAULT, kp=kp, kv=kv, compliance=False)  # the plain PD loop, eq. 2.20
    report = step_report(kp, kv)  # formula (2.11-2.19) and the ideal joint, simulated

    arm = armlab.load_robot("receptionist_arm")
    loop = ControlLoop(arm, SimBackend(arm, q0=thesis_line(arm).q[0]), params, realtime=False,
                       history_s=30.0)
    loop.run_for(1.0)  # settle
    plan = plan_step(loop.recorder.snapshot(0.2), joint=2, step=math.radians(-20),
                     lower=loop.lower, upper=loop.upper, params=loop.params, label="θ2")
    t0 = loop.status.t
    loop.post(RunTrajectory(plan.trajectory, approach=False))
    loop.run_for(plan.wait_s)
    arm_step = measure_step(loop.recorder.snapshot(loop.status.t - t0 + 0.2), t0=t0, joint=2,
                            q0=plan.q0, q1=plan.q1, what="step of θ2")

    print(f"Kp = {kp:g} 1/s², Kv = {kv:g} 1/s: ωn = {report['omega_n']:.3f} rad/s, "
          f"ζ = {report['zeta']:.3f}")
    print(f"{'figure':<22}{'formula':>10}{'ideal joint':>14}{'simulated arm':>16}")
    for key, label in FIGURES:
        print(f"{label:<22}{fmt(report['formula'][key]):>10}{fmt(report['measured'][key]):>14}"
              f"{fmt(getattr(arm_step, key)):>16}")
    for key, _ in FIGURES:
        print(f"formula_{key} = {fmt(report['formula'][key])}")
        print(f"ideal_{key} = {fmt(report['measured'][key])}")
        print(f"arm_{key} = {fmt(getattr(arm_step, key))}")


if __name__ == "__main__":
    main()
