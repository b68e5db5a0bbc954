"""Bus cycles on the emulator at 1 Mbps, one per protocol.

- Protocol 1.0, the thesis arm's three RX-24F: read every servo (36..41) + one
  SYNC_WRITE. The emulator runs in its own process with wire-time pacing, so a cycle
  cannot be faster than the bytes take on a real 1 Mbps line: 3 × (8 + 12) bytes of
  READ and reply plus the 23-byte SYNC_WRITE = 83 bytes = 0.83 ms
  (``bus_wire_bound_ms``). The thesis's period was 16 ms.
- Protocol 2.0, the OpenManipulator-X's five XM430-W350 (the arm's IDs 11..14 and the
  gripper's 15) through the X-series backend: one SYNC_READ of present current, velocity
  and position (19 bytes, then five 21-byte answers) + one SYNC_WRITE of profile
  velocity and goal (59 bytes) = 183 bytes = 1.83 ms (``bus2_wire_bound_ms``).
- Feetech STS, the SO-101's six STS3215 (the arm's IDs 1..5 and the jaw's 6) through the
  STS backend: one SYNC_READ of Present Position .. Present Current (14 bytes, then six
  21-byte answers) + one SYNC_WRITE of goal position, time and speed (50 bytes) = 190
  bytes = 1.90 ms (``bus_sts_wire_bound_ms``; the cycle: ``bus_sts_cycle_median_ms``,
  ``_p99_ms``). Its emulator steps the plant at 2 ms (``--dt 0.002``): five joints and
  the jaw at 1 ms cost most of a core, and the plant is integrated up to each request
  before the servos answer it, which a shared machine would add to every cycle.
- Protocol 1.0, the quadruped's twelve AX-12A (IDs 1..12) carrying its body, standing: the
  gait loop's cycle, twelve READs and one SYNC_WRITE = 12 × (8 + 12) + 68 = 308 bytes =
  3.08 ms (``bus_quadruped_wire_bound_ms``; the gait loop's period is 20 ms). Its emulator
  steps the legs at 4 ms (``--dt 0.004``), as seed 003's test over the emulator does.
"""

from __future__ import annotations

import contextlib
import select
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator

import numpy as np

from armlab.control.walking import GaitSpec, Walker, plan_gait
from armlab.hardware.backends.servo_bus import ServoBusBackend
from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.backend import DynamixelBackend
from armlab.hardware.families.feetech import backend as sts
from armlab.hardware.families.feetech import packets as ft
from armlab.hardware.families.xseries import packets as p2
from armlab.hardware.families.xseries.backend import (
    GOAL_AT,
    GOAL_LEN,
    PRESENT_AT,
    PRESENT_LEN,
    XSeriesBackend,
)
from armlab.hardware.servos.servo_spec import wire_time
from armlab.kinematics.catalog import load_robot

BAUD = 1_000_000
#: protocol 1.0: the backend READs 36..41 (present position, speed, load) of each servo and
#: SYNC_WRITEs 30..33 (goal position, moving speed)
PRESENT_AT_P1, GOAL_AT_P1 = 36, 30
#: the OpenManipulator-X's servos on the bus: four joints and the gripper
OMX_SERVOS = 5
#: their IDs (the shipped map: joints 11..14, the gripper 15)
OMX_IDS = tuple(range(11, 11 + OMX_SERVOS))
#: the SO-101's servos on the bus: five joints and the jaw (IDs 1..6)
SO101_SERVOS = 6
#: the quadruped's servos on the bus: three per leg (IDs 1..12)
QUADRUPED_SERVOS = 12


@contextlib.contextmanager
def paced_emulator(*args: str, timeout: float = 60.0) -> Iterator[str]:
    """``armlab emulate --pace ARGS`` in a subprocess; yields its port, always stops it."""
    proc = subprocess.Popen([sys.executable, "-m", "armlab.app", "emulate", "--pace", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None  # stdout=PIPE
    try:
        ready, _, _ = select.select([proc.stdout], [], [], timeout)
        line = proc.stdout.readline() if ready else ""
        if not line.startswith("port: "):
            raise RuntimeError(f"the emulator did not start (printed {line!r})")
        yield line.split(" ", 1)[1].strip()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _cycles(backend: ServoBusBackend, goal: np.ndarray, n: int) -> list[float]:
    """s of ``n`` cycles (read every servo, write every goal), after a warm-up."""
    speed = np.full(backend.n, 2.0)
    samples = []
    try:
        backend.set_torque(True)
        for _ in range(50):  # warm-up
            backend.read()
            backend.write(goal, speed)
        for _ in range(n):
            t0 = time.perf_counter()
            backend.read()
            backend.write(goal, speed)
            samples.append(time.perf_counter() - t0)
        backend.set_torque(False)
    finally:
        backend.close()
    return sorted(samples)


def _median_p99_ms(samples: list[float]) -> tuple[float, float]:
    return (statistics.median(samples) * 1e3,
            samples[min(len(samples) - 1, int(0.99 * len(samples)))] * 1e3)


def protocol1_cycle_bytes(n_servos: int) -> int:
    """Bytes on the wire in one protocol-1.0 backend cycle of ``n_servos`` (IDs 1..n): a
    READ of Present Position .. Present Load and its status per servo, one SYNC_WRITE of
    goal position and moving speed."""
    ids = list(range(1, 1 + n_servos))
    return sum(len(p1.read(i, PRESENT_AT_P1, 6)) + len(p1.status(i, 0, bytes(6))) for i in ids) \
        + len(p1.sync_write(GOAL_AT_P1, 4, {i: bytes(4) for i in ids}))


def protocol2_cycle_bytes(n_servos: int) -> int:
    """Bytes on the wire in one X-series backend cycle of ``n_servos``."""
    ids = list(range(11, 11 + n_servos))
    return (len(p2.sync_read(PRESENT_AT, PRESENT_LEN, ids))
            + n_servos * p2.status_length(PRESENT_LEN)
            + len(p2.sync_write(GOAL_AT, GOAL_LEN, {i: bytes(GOAL_LEN) for i in ids})))


def sts_cycle_bytes(n_servos: int) -> int:
    """Bytes on the wire in one STS backend cycle of ``n_servos`` (IDs 1..n)."""
    ids = list(range(1, 1 + n_servos))
    return (len(ft.sync_read(sts.PRESENT_AT, sts.PRESENT_LEN, ids))
            + n_servos * (ft.OVERHEAD + sts.PRESENT_LEN)
            + len(ft.sync_write(sts.GOAL_AT, sts.GOAL_LEN, {i: bytes(sts.GOAL_LEN) for i in ids})))


def run(quick: bool) -> dict[str, float]:
    n = 300 if quick else 3000
    # generous timeouts: a stall of the shared machine must cost a sample, not the run
    with paced_emulator("--baud", str(BAUD)) as port:
        one = _cycles(DynamixelBackend(load_robot("receptionist_arm"), port, baud=BAUD,
                                       timeout_margin=0.1, retries=5),
                      np.array([0.3, 0.2, 0.5]), n)
    with paced_emulator("--robot", "open_manipulator_x", "--baud", str(BAUD)) as port:
        omx = XSeriesBackend(load_robot("open_manipulator_x"), port, baud=BAUD,
                             timeout_margin=0.1, retries=5)
        if omx.gripper is None:  # the gripper's servo is read and written with the arm's
            raise RuntimeError("the OpenManipulator-X's map names no gripper servo")
        two = _cycles(omx, np.array([0.2, 0.3, -0.2, 0.1]), n)
    with paced_emulator("--robot", "so101", "--baud", str(BAUD), "--dt", "0.002") as port:
        so101 = sts.StsBackend(load_robot("so101"), port, baud=BAUD, timeout_margin=0.1,
                               retries=5)
        if so101.gripper is None:  # the jaw's servo is read and written with the arm's
            raise RuntimeError("the SO-101's map names no jaw servo")
        six = _cycles(so101, np.radians([0.0, -30.0, 60.0, 20.0, 0.0]), n)
    with paced_emulator("--robot", "quadruped", "--baud", str(BAUD), "--dt", "0.004") as port:
        quadruped = load_robot("quadruped")
        twelve = _cycles(DynamixelBackend(quadruped, port, baud=BAUD, timeout_margin=0.1,
                                          retries=5),
                         Walker(plan_gait(GaitSpec())).state().q, n)
    median, p99 = _median_p99_ms(one)
    median2, p99_2 = _median_p99_ms(two)
    median_sts, p99_sts = _median_p99_ms(six)
    median_quad, p99_quad = _median_p99_ms(twelve)
    return {
        "bus_cycle_median_ms": median,
        "bus_cycle_p99_ms": p99,
        "bus_wire_bound_ms": wire_time(protocol1_cycle_bytes(3), BAUD) * 1e3,
        "bus2_cycle_median_ms": median2,
        "bus2_cycle_p99_ms": p99_2,
        "bus2_wire_bound_ms": wire_time(protocol2_cycle_bytes(OMX_SERVOS), BAUD) * 1e3,
        "bus_sts_cycle_median_ms": median_sts,
        "bus_sts_cycle_p99_ms": p99_sts,
        "bus_sts_wire_bound_ms": wire_time(sts_cycle_bytes(SO101_SERVOS), BAUD) * 1e3,
        "bus_quadruped_cycle_median_ms": median_quad,
        "bus_quadruped_cycle_p99_ms": p99_quad,
        "bus_quadruped_wire_bound_ms": wire_time(protocol1_cycle_bytes(QUADRUPED_SERVOS),
                                                 BAUD) * 1e3,
    }
