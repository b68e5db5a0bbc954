"""Control-loop figures: period jitter in real time on the simulated arm, controller cost."""

from __future__ import annotations

import time

import numpy as np

from armlab.app.benches import median_us
from armlab.control.backend import JointState
from armlab.control.commands import RunTrajectory
from armlab.control.compliance import ComplianceController, ControllerState
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.trajectory import thesis_line
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import rnea


def run(quick: bool) -> dict[str, float]:
    """``loop_jitter_p99_ms`` (and p50): lateness of period starts at 16 ms while the simulated arm
    runs the thesis line in real time (3 s quick, 10 s otherwise); ``compliance_step_us``:
    one period of controller work (Newton–Euler + compliance law), without the plant."""
    model = load_robot("receptionist_arm")
    line = thesis_line(model)
    loop = ControlLoop(model, SimBackend(model, q0=line.q[0]), Params(period=0.016),
                       realtime=True)
    loop.start()
    seconds = 3.0 if quick else 10.0
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        loop.post(RunTrajectory(line))
        time.sleep(line.duration + 0.5)
    status = loop.status
    loop.shutdown()

    ctl = ComplianceController(model.lower, model.upper, 10.0)
    p = Params()
    q = line.q[0]
    state = ControllerState.at_rest(q)
    meas = JointState(0.0, q, np.zeros(3), np.zeros(3), (0, 0, 0), (True,) * 3)
    zero = np.zeros(3)

    def one_period() -> None:
        tau = rnea(model, meas.position, meas.velocity, state.qdd_ref)
        ctl.step(p, state, q, zero, zero, meas, tau)

    return {
        "loop_jitter_p50_ms": float(status.jitter_p50_ms or 0.0),
        "loop_jitter_p99_ms": float(status.jitter_p99_ms or 0.0),
        "compliance_step_us": median_us(one_period, repeat=500 if quick else 5000),
    }
