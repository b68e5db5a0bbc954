"""The thesis-line compliance experiment end to end through the serial backend + emulator.

The same ``armlab.control.experiments.thesis.run_line`` (ControlLoop, compliance law,
16 ms period) drives once the emulated servos over a real pty and once the
simulated backend; the emulated arm's angles must follow the simulated ones. Two arms:
the thesis's (three RX-24F, protocol 1.0, DynamixelBackend / SimBackend) and the
OpenManipulator-X on its 20 cm line (four XM430-W350, protocol 2.0, XSeriesBackend /
XSimBackend: issue "Any Dynamixel arm", Must-show).
"""

from __future__ import annotations

import contextlib
import os
import re
import time

import numpy as np
import pytest
from _emulator import emulator

from armlab.control.experiments.thesis import line_plan, run_line
from armlab.control.params import preset
from armlab.hardware.families.dynamixel1.backend import DynamixelBackend
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.families.xseries.backend import XSeriesBackend
from armlab.hardware.families.xseries.sim_backend import XSimBackend
from armlab.hardware.families.xseries.table import XM430_W350
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

ARM = load_robot("receptionist_arm")
OMX = load_robot("open_manipulator_x")
#: robot -> (model, emulator arguments, serial backend, simulated backend)
ARMS = {
    "receptionist_arm": (ARM, (), DynamixelBackend, SimBackend),
    "open_manipulator_x": (OMX, ("--robot", "open_manipulator_x"), XSeriesBackend,
                           lambda model, **kw: XSimBackend(model, spec=XM430_W350, **kw)),
}
PRE = 2.0  # s to bring the arm from where it hangs to the line's start before the run
#: thesis-servo counts (RX-24F, 0.29°, for both arms) outside the one-period band. The
#: compliance loop feeds the quantised load back, so two *simulated* runs that differ by
#: one count at the start or 1 ms of actuation delay already leave each other's one-period
#: band by up to 3 counts (measured; the OpenManipulator-X's by up to 1 with reads 2 ms and
#: goals 3 ms late); + 2 here.
TOLERANCE_COUNTS = 5


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


#: runs through the emulator before giving up on a quiet enough machine
ATTEMPTS = 3
#: s: a loop held back this long falls behind its reference past the loop's lag limit
#: (ControlLoop.lag_time) and stops with a tracking fault: the machine's doing, not the code's
STALL_FAULT_S = 0.5


def _emulated_run(robot, params, start):
    """One thesis-line run through a fresh emulator; returns (run, worst stall in s), the
    run None when the loop stopped on a fault after a stall longer than its lag limit
    (the shared machine held it back: the arm fell behind its reference)."""
    model, args, backend, _ = ARMS[robot]
    nice = os.getpriority(os.PRIO_PROCESS, 0)
    with emulator(*args) as emu:
        # generous retries: a stall of the shared machine must show as lateness, not a fault
        serial = backend(model, emu.port, timeout_margin=0.1, retries=10)
        serial.set_torque(True)  # the emulated arm hangs with torque off
        serial.write(start, np.full(model.n, 2.0))
        time.sleep(PRE)
        with contextlib.suppress(OSError):  # a real-time loop, like the lab PC's (needs root)
            os.setpriority(os.PRIO_PROCESS, 0, -10)
        try:
            emu_run = run_line(model, lambda model, **kw: serial, params,
                               controller="compliance")
        except ValueError as exc:  # the loop stopped on a fault
            if serial.late_max > STALL_FAULT_S:
                return None, serial.late_max
            raise AssertionError(f"the run through the emulator failed (loop late by up to "
                                 f"{serial.late_max * 1e3:.0f} ms): {exc}") from None
        finally:
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, 0, nice)
        assert serial.stats.failures == 0
        code, err = emu.stop()
    assert code == 0, err
    slipped = float(re.search(r"plant clock slipped ([0-9.]+) s", err).group(1))
    return emu_run, max(serial.late_max, slipped)


@pytest.mark.parametrize("robot", sorted(ARMS))
def test_thesis_line_through_the_emulator_matches_the_simulator(robot):
    model, _, _, simulated = ARMS[robot]
    plan, t0, t1 = line_plan(model)
    params = preset("well-damped default")
    start = plan.q[0]
    for _ in range(ATTEMPTS):
        emu_run, stall = _emulated_run(robot, params, start)
        if emu_run is not None and stall <= params.period:
            break
    if emu_run is None:
        pytest.skip(f"in {ATTEMPTS} runs the shared machine stalled the real-time loop by at "
                    f"least {stall * 1e3:.0f} ms: it stopped on a tracking fault")
    sim = simulated(model)  # the same pre-positioning in simulated time
    sim.write(start, np.full(model.n, 2.0))
    sim.sync(PRE)
    sim_run = run_line(model, lambda model, **kw: _SimAfter(sim, PRE), params,
                       controller="compliance")
    e, s = emu_run.snapshot, sim_run.snapshot
    n = min(len(e["t"]), len(s["t"]))
    assert n >= int(plan.duration / params.period) - 2  # the whole plan ran on both
    assert np.allclose(e["t"][:n], s["t"][:n])
    qe, qs = e["q"][:n], s["q"][:n]
    assert np.any(np.abs(qs[-1] - qs[0]) > 0.5)  # the arm really travelled the line
    if stall > params.period:
        pytest.skip(f"in {ATTEMPTS} runs the shared machine stalled the real-time loop or the "
                    f"emulator by at least {stall * 1e3:.0f} ms, more than the "
                    f"{params.period * 1e3:.0f} ms period: no fair comparison")
    # band: the simulated angles one period earlier, now and one period later, ± tolerance
    k = 1
    m = n - 2 * k
    window = np.stack([qs[j : j + m] for j in range(2 * k + 1)])
    outside = np.maximum(window.min(axis=0) - qe[k : k + m], qe[k : k + m] - window.max(axis=0))
    counts = outside.max(axis=0) / RX24F.position_unit
    assert np.all(counts <= TOLERANCE_COUNTS + 1e-6), (
        f"emulated angles leave the simulated ones by {counts} thesis-servo counts "
        f"({np.degrees(outside.max(axis=0))}°)")
