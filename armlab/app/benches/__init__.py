"""Benchmarks for ``armlab bench``.

Each module named in :data:`BENCHES` defines ``run(quick: bool) -> dict[str, float]``
returning named figures (medians, in the unit the name ends with). ``armlab bench
--json`` merges them into one flat object. Timings are medians over repeats; the
machines are shared, so no test ever asserts on them. ``peers`` (armlab beside MuJoCo
and Pinocchio) runs only with ``--peers``: it needs the optional ``bench`` extra.
"""

from __future__ import annotations

import importlib
import statistics
import time
from collections.abc import Callable

#: The bench modules ``armlab bench`` runs (adding one: add its name here).
BENCHES: tuple[str, ...] = ("bus", "classroom", "control", "dynamics", "flood", "hand",
                            "kinematics", "runs", "seeds", "ui")


def median_us(fn: Callable[[], object], *, repeat: int = 2000, warmup: int = 50) -> float:
    """Median wall time of one call of ``fn`` in microseconds."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter_ns()
        fn()
        samples.append(time.perf_counter_ns() - t0)
    return statistics.median(samples) / 1000.0


def run_all(quick: bool = False, only: str | None = None,
            peers: bool = False) -> dict[str, float]:
    """Run every bench of :data:`BENCHES` (or the one named ``only``; with ``peers``, the
    peer comparison too) and merge the figures.

    Raises:
        ValueError: ``only`` names no bench.
    """
    names = list(BENCHES) + (["peers"] if peers else [])
    if only is not None:
        if only not in BENCHES and only != "peers":
            raise ValueError(f"--only: no bench {only!r}; known: {', '.join(BENCHES)}, peers")
        names = [only]
    figures: dict[str, float] = {}
    for name in names:
        module = importlib.import_module(f"{__name__}.{name}")
        figures.update(module.run(quick))
    return figures
