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

from armlab.hardware.backends.dynamixel import DynamixelBackend
from armlab.hardware.backends.xseries import (
    GOAL_AT,
    GOAL_LEN,
    PRESENT_AT,
    PRESENT_LEN,
    XSeriesBackend,
)
from armlab.hardware.wire import protocol2 as p2
from armlab.hardware.wire.protocol1 import wire_time
from armlab.kinematics.model import load_robot

BAUD = 1_000_000
#: bytes per cycle for three servos: READ 36..41 (8) + its status (12), three times; SYNC_WRITE
CYCLE_BYTES = 3 * (8 + 12) + 23
#: the OpenManipulator-X's servos on the bus: four joints and the gripper
OMX_SERVOS = 5
#: their IDs (the shipped map: joints 11..14, the gripper 15)
OMX_IDS = tuple(range(11, 11 + OMX_SERVOS))


@contextlib.contextmanager
def paced_emulator(*args: str, timeout: float = 60.0) -> Iterator[str]:
    """``armlab emulate --pace ARGS`` in a subprocess; yields its port, always stops it."""
    proc = subprocess.Popen([sys.executable, "-m", "armlab.app", "emulate", "--pace", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
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


def _cycles(backend: DynamixelBackend, goal: np.ndarray, n: int) -> list[float]:
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


def protocol2_cycle_bytes(n_servos: int) -> int:
    """Bytes on the wire in one X-series backend cycle of ``n_servos``."""
    ids = list(range(11, 11 + n_servos))
    return (len(p2.sync_read(PRESENT_AT, PRESENT_LEN, ids))
            + n_servos * p2.status_length(PRESENT_LEN)
            + len(p2.sync_write(GOAL_AT, GOAL_LEN, {i: bytes(GOAL_LEN) for i in ids})))


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
    median, p99 = _median_p99_ms(one)
    median2, p99_2 = _median_p99_ms(two)
    return {
        "bus_cycle_median_ms": median,
        "bus_cycle_p99_ms": p99,
        "bus_wire_bound_ms": wire_time(CYCLE_BYTES, BAUD) * 1e3,
        "bus2_cycle_median_ms": median2,
        "bus2_cycle_p99_ms": p99_2,
        "bus2_wire_bound_ms": wire_time(protocol2_cycle_bytes(OMX_SERVOS), BAUD) * 1e3,
    }
