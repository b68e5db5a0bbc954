"""Must-show (issue "Any Dynamixel arm"): on emulated XM430s, the disturbance observer's
estimate of a known applied torque, from the current the servos report, settles within
10 % of it; so does the reaction-torque observer's, absolute, and it reads ~0 before.

``armlab emulate --robot open_manipulator_x --disturb joint2:0.3@T`` hangs 0.3 N·m on the
shoulder T s into the emulator's clock; ``servo_observers`` (what ``armlab experiment
observers --backend serial`` runs) opens the four XM430-W350 over the real
pseudo-terminal, lifts the arm from where it hangs to the zero pose, holds it and reads
Present Current, Velocity and Position every 10 ms; the step of τ̂_dis (thesis eq. 2.36)
must be the applied torque within 10 %. The RTOB (thesis eq. 2.37) on the same readings
subtracts the model's gravity at every reading's pose: within RTOB_ZERO of 0 before the
step (the emulator's plant is moved by the same model; a real arm shows its model error
there) and within 10 % of the applied torque after it. The step is found in the estimate,
so how long the start-up takes on a loaded machine does not matter as long as it is over
before T.
"""

from __future__ import annotations

import numpy as np
import pytest
from _emulator import emulator

from armlab.control.experiments.observers import servo_observers
from armlab.hardware.families.xseries.backend import XSeriesBackend
from armlab.hardware.families.xseries.table import XM430_W350
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

OMX = load_robot("open_manipulator_x")
SHOULDER = 1  # joint2
#: N·m on the shoulder, 7 % of the XM430-W350's stall torque; the servo's P hold gives
#: way 10 counts (0.9°) under it, within the gear friction's reach
APPLIED = 0.3
#: s of the emulator's clock: long after the backend opened and the arm reached its pose
#: (about 3 s here, quiet): a loaded machine may take up to 18 s for that
DISTURB_AT = 20.0
#: s of readings: the step lands in them however long the start took (up to 18 s), with
#: settled readings before and after it
DURATION = 30.0
#: N·m: three counts of Present Current (2.69 mA × 1.78 N·m/A each)
RTOB_ZERO = 3 * XM430_W350.current_unit * XM430_W350.torque_constant


def test_the_dob_and_the_rtob_estimate_a_known_torque_on_emulated_xm430s_within_10_percent():
    with emulator("--robot", "open_manipulator_x",
                  "--disturb", f"joint2:{APPLIED}@{DISTURB_AT}") as emu:
        # generous retries: a stall of the shared machine must show as lateness, not a fault
        fig = servo_observers(
            OMX, lambda model: XSeriesBackend(model, emu.port, timeout_margin=0.1, retries=10),
            joint=SHOULDER, duration=DURATION, applied=APPLIED, pose=np.zeros(OMX.n))
        code, err = emu.stop()
    assert code == 0, err
    assert f"0.3 N·m on joint2 from {DISTURB_AT:g} s" in err
    assert fig["relative_error"] < 0.10, (
        f"applied {APPLIED} N·m, estimated {fig['estimated_nm']:.4f} N·m "
        f"(τ̂_dis {fig['dob_before_nm']:.4f} -> {fig['dob_after_nm']:.4f} N·m at "
        f"{fig['step_at_s']:.2f} s)")
    assert abs(fig["rtob_before_nm"]) < RTOB_ZERO, fig["rtob_before_nm"]
    assert fig["rtob_error_pct"] < 10.0, (
        f"applied {APPLIED} N·m, the RTOB read {fig['rtob_before_nm']:.4f} N·m before and "
        f"{fig['rtob_after_nm']:.4f} N·m after the step at {fig['step_at_s']:.2f} s")
