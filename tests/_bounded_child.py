"""Run ``armlab ARGS`` in this process and write what it cost (tests/test_hostile_runs.py).

Usage: ``python _bounded_child.py STATS.json ARGS...``. STATS.json gets the exit status,
the peak resident memory (VmHWM, KiB, read from /proc at the end) and the CPU time (s).
"""

import json
import resource
import sys

from armlab.app.commands.cli import main


def peak_kib() -> int:
    """This process's peak resident memory, KiB (VmHWM)."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))


if __name__ == "__main__":
    out, argv = sys.argv[1], sys.argv[2:]
    code = 1
    try:
        code = main(argv)
    finally:
        usage = resource.getrusage(resource.RUSAGE_SELF)
        with open(out, "w") as f:
            json.dump({"code": code, "peak_kib": peak_kib(),
                       "cpu_s": usage.ru_utime + usage.ru_stime}, f)
    sys.exit(code)
