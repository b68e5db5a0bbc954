"""The thesis-line compliance experiment end to end through DynamixelBackend + emulator.

The same ``control.experiments.thesis.run_line`` (ControlLoop, compliance law,
16 ms period) drives once the emulated servos over a real pty and once the
SimBackend; the emulated arm's angles must follow the simulated ones.
"""

from __future__ import annotations

import contextlib
import os
import re
import time

import numpy as np
import pytest
from _emulator import emulator

from control.experiments.thesis import line_plan, run_line
from control.params import preset
from hardware.dynamixel_backend import DynamixelBackend
from hardware.servo_spec import RX24F
from hardware.sim_backend import SimBackend
from kinematics.model import load_robot

ARM = load_robot("receptionist_arm")
PRE = 2.0  # s to bring the arm from hanging (q = 0) to the line's start before the run
#: counts outside the one-period band: each side's 10-bit reading (±1) plus the count the
#: servo model itself moves by under a 1 ms or 1-count perturbation of the same run
TOLERANCE_COUNTS = 3


class _SimAfter:
    """A SimBackend whose clock goes on from ``offset`` s (the pre-positioning), so the
    simulated arm starts the run in the same state as the emulated one."""

    def __init__(self, sim: SimBackend, offset: float):
        self.sim, self.offset = sim, offset
        self.n, self.lower, self.upper = sim.n, sim.lower, sim.upper

    def sync(self, t: float) -> None:
        self.sim.sync(t + self.offset)

    def read(self):
        return self.sim.read()

    def write(self, position, speed) -> None:
        self.sim.write(position, speed)

    def set_torque(self, on: bool) -> None:
        self.sim.set_torque(on)

    def estop(self) -> None:
        self.sim.estop()

    def close(self) -> None:
        self.sim.close()


def _skip_if_stalled(late: float, period: float) -> None:
    """The comparison assumes both processes kept real time; a shared machine that stalled
    the loop, or made the emulator's plant clock slip, by more than a period voids it."""
    if late > period:
        pytest.skip(f"the machine stalled the real-time loop or the emulator by "
                    f"{late * 1e3:.0f} ms (more than the {period * 1e3:.0f} ms period): "
                    "no fair comparison")


def test_thesis_line_through_the_emulator_matches_the_simulator():
    plan, t0, t1 = line_plan(ARM)
    params = preset("well-damped default")
    start = plan.q[0]
    nice = os.getpriority(os.PRIO_PROCESS, 0)
    with emulator() as emu:
        # generous retries: a stalled shared machine must end in the skip below, not a fault
        serial = DynamixelBackend(ARM, emu.port, timeout_margin=0.1, retries=10)
        serial.set_torque(True)  # the emulated arm hangs at q = 0 with torque off
        serial.write(start, np.full(3, 2.0))
        time.sleep(PRE)
        with contextlib.suppress(OSError):  # a real-time loop, like the lab PC's (needs root)
            os.setpriority(os.PRIO_PROCESS, 0, -10)
        try:
            emu_run = run_line(ARM, lambda model, **kw: serial, params, controller="compliance")
        except ValueError as exc:  # the loop stopped on a fault
            _skip_if_stalled(serial.late_max, params.period)
            raise AssertionError(f"the run through the emulator failed: {exc}") from None
        finally:
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, 0, nice)
        assert serial.stats.failures == 0
        code, err = emu.stop()
    assert code == 0, err
    slipped = float(re.search(r"plant clock slipped ([0-9.]+) s", err).group(1))
    sim = SimBackend(ARM)  # hanging at q = 0, the same pre-positioning in simulated time
    sim.write(start, np.full(3, 2.0))
    sim.sync(PRE)
    sim_run = run_line(ARM, lambda model, **kw: _SimAfter(sim, PRE), params,
                       controller="compliance")
    e, s = emu_run.snapshot, sim_run.snapshot
    n = min(len(e["t"]), len(s["t"]))
    assert n >= int(plan.duration / params.period) - 2  # the whole plan ran on both
    assert np.allclose(e["t"][:n], s["t"][:n])
    qe, qs = e["q"][:n], s["q"][:n]
    assert np.any(np.abs(qs[-1] - qs[0]) > 0.5)  # the arm really travelled the line
    _skip_if_stalled(max(serial.late_max, slipped), params.period)
    # band: the simulated angle one period earlier, now or one period later, ± tolerance
    lo = np.minimum(np.minimum(qs[:-2], qs[1:-1]), qs[2:])
    hi = np.maximum(np.maximum(qs[:-2], qs[1:-1]), qs[2:])
    outside = np.maximum(lo - qe[1:-1], qe[1:-1] - hi)
    counts = outside.max(axis=0) / RX24F.position_unit
    assert np.all(counts <= TOLERANCE_COUNTS + 1e-6), (
        f"emulated angles leave the simulated ones by {counts} counts")
