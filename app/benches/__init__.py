"""Benchmarks for ``armlab bench``.

Each module here defines ``run(quick: bool) -> dict[str, float]`` returning
named figures (medians, in the unit the name ends with). ``armlab bench --json``
merges them into one flat object. Timings are medians over repeats; the
machines are shared, so no test ever asserts on them.
"""

from __future__ import annotations

import importlib
import pkgutil
import statistics
import time
from collections.abc import Callable


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


def run_all(quick: bool = False, only: str | None = None) -> dict[str, float]:
    """Run every bench module (or the one named ``only``) and merge the figures."""
    figures: dict[str, float] = {}
    for info in pkgutil.iter_modules(__path__):
        if only and info.name != only:
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        figures.update(module.run(quick))
    return figures
