"""Bus cycle on the emulator: read every servo (36..41) + one SYNC_WRITE, three servos, 1 Mbps.

The emulator runs in its own process with wire-time pacing, so a cycle cannot be
faster than the bytes take on a real 1 Mbps line: 3 × (8 + 12) bytes of READ and
reply plus the 23-byte SYNC_WRITE = 83 bytes = 0.83 ms (``bus_wire_bound_ms``).
The thesis's period was 16 ms.
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

from hardware.dynamixel_backend import DynamixelBackend
from hardware.protocol1 import wire_time
from kinematics.model import load_robot

BAUD = 1_000_000
#: bytes per cycle for three servos: READ 36..41 (8) + its status (12), three times; SYNC_WRITE
CYCLE_BYTES = 3 * (8 + 12) + 23


@contextlib.contextmanager
def paced_emulator(*args: str, timeout: float = 60.0) -> Iterator[str]:
    """``armlab emulate --pace ARGS`` in a subprocess; yields its port, always stops it."""
    proc = subprocess.Popen([sys.executable, "-m", "app", "emulate", "--pace", *args],
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


def run(quick: bool) -> dict[str, float]:
    n = 300 if quick else 3000
    arm = load_robot("receptionist_arm")
    goal = np.array([0.3, 0.2, 0.5])
    speed = np.full(3, 2.0)
    samples = []
    with paced_emulator("--baud", str(BAUD)) as port:
        # generous timeouts: a stall of the shared machine must cost a sample, not the run
        backend = DynamixelBackend(arm, port, baud=BAUD, timeout_margin=0.1, retries=5)
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
    samples.sort()
    return {
        "bus_cycle_median_ms": statistics.median(samples) * 1e3,
        "bus_cycle_p99_ms": samples[min(len(samples) - 1, int(0.99 * len(samples)))] * 1e3,
        "bus_wire_bound_ms": wire_time(CYCLE_BYTES, BAUD) * 1e3,
    }
