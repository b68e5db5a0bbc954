"""The compliance law on the simulated arm, without the UI (thesis eq. 2.6, 2.15, 2.20).

Run it from the repository's root:  python examples/03_compliance_headless.py

The same ControlLoop the lab runs, on the simulated arm and its three RX-24F servos,
stepped as fast as the computer goes (``realtime=False``). The hand is pushed with
3 N for 3 s, once with compliance on and once with the plain PD loop, and the arm's
give is measured: with compliance the virtual environment (M_env, D_env, K_env) lets
the hand yield by θ_env = C_f τ_ext at rest, C_f = K_f / K_env (eq. 2.15).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

import armlab
from armlab.control import metrics
from armlab.control.commands import Push
from armlab.control.loop import ControlLoop
from armlab.control.params import DEFAULT, Params
from armlab.control.response import Measured, measure_push
from armlab.control.trajectory import thesis_line
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics import SerialChain

FORCE = np.array([0.0, -3.0, 0.0])  # N, base frame: against the line's direction


def push_and_measure(arm: SerialChain, params: Params) -> tuple[float, Measured | None]:
    """Hold at the line's start, push the hand for 3 s: its give (m) and the measured push."""
    home = thesis_line(arm).q[0]  # the start of chapter 4's line
    loop = ControlLoop(arm, SimBackend(arm, q0=home), params, realtime=False, history_s=20.0)
    loop.run_for(1.0)  # settle at home
    q_rest = loop.recorder.snapshot(0.1)["q"][-1]
    t0 = loop.status.t
    loop.post(Push(FORCE, link=arm.n - 1, point=arm.tip[:3, 3], duration=3.0))
    loop.run_for(3.0)
    snap = loop.recorder.snapshot(loop.status.t - t0 + 0.1)
    give = float(np.linalg.norm(arm.fk(snap["q"][-1])[:3, 3] - arm.fk(q_rest)[:3, 3]))
    measured = measure_push(snap, t0=t0, t1=t0 + 3.0, what="push",
                            joint_labels=arm.joint_names) if params.compliance else None
    return give, measured


def main() -> None:
    """Push the compliant arm, then the PD-only one; print the gives and C_f (eq. 2.15)."""
    arm = armlab.load_robot("receptionist_arm")
    p = DEFAULT
    print(f"params: Kp = {p.kp:g}, Kv = {p.kv:g}, M_env = {p.m_env:g}, D_env = {p.d_env:g}, "
          f"K_env = {p.k_env:g}, K_f = {p.k_f:g}")
    give_on, m = push_and_measure(arm, p)
    give_off, _ = push_and_measure(arm, replace(p, compliance=False))
    print(f"hand_give_compliance_cm = {give_on * 100:.3f}")
    print(f"hand_give_pd_only_cm = {give_off * 100:.3f}")
    print(f"static_gain_measured = {m.static_gain:.5f}  ({m.what})")
    print(f"static_gain_formula = {metrics.static_gain(p.k_f, p.k_env):.5f}  "
          "(C_f = K_f / K_env, eq. 2.15)")


if __name__ == "__main__":
    main()
