"""Run files: writing, reading and exporting one run of the receptionist arm.

The run is the compliance lesson's recorder at its fullest: 30 s at the 1 ms loop
period, every signal of :data:`armlab.control.recorder.SIGNALS` on three joints.

Figures (median milliseconds per call, and ratios against a reference in the same run):
    run_write_ms: the run file in memory (``armlab.control.runs.run_bytes``: CSV text
        with ``repr`` floats, then deflate), what the page's Save run sends.
    run_read_ms: ``read_run`` of those bytes, every check included (what Open run does).
    run_csv_reference_ms: ``numpy.loadtxt`` of the same CSV member, no checks: the
        cost of parsing the numbers alone.
    run_read_over_reference: run_read_ms / run_csv_reference_ms.
    export_html_ms: the hand-in page (``armlab.app.export.html.export_html``).
    run_file_kib: the file's size.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Callable

import numpy as np

from armlab.app.benches import median_us
from armlab.app.export.html import export_html
from armlab.control.recorder import SIGNALS
from armlab.control.runs import Run, read_run, run_bytes
from armlab.kinematics import load_robot

SECONDS = 30.0
PERIOD = 1e-3


def sample_run(seconds: float = SECONDS) -> Run:
    """A run of the receptionist arm with every recorder signal, smooth and seeded."""
    arm = load_robot("receptionist_arm")
    t = np.arange(round(seconds / PERIOD)) * PERIOD
    rng = np.random.default_rng(3)
    phase = rng.uniform(0, np.pi, arm.n)
    base = 0.3 * np.sin(0.5 * t[:, None] + phase)
    signals = {name: base + 1e-3 * rng.standard_normal(base.shape) for name in SIGNALS}
    return Run(robot=arm.name, joint_names=arm.joint_names, source="bench:runs",
               lab_version="bench", created="2026-01-01T00:00:00Z",
               params={"kp": 20.0, "kv": 5.0}, commands=({"t": 0.0, "kind": "Stop"},),
               figures={"max_error_deg": 1.0}, t=t, signals=signals)


def median_ms(fn: Callable[[], object], repeat: int) -> float:
    """Median wall time of one call of ``fn``, ms (one warm-up call first)."""
    return median_us(fn, repeat=repeat, warmup=1) / 1000.0


def run(quick: bool) -> dict[str, float]:
    """Median ms to write, read and export a 30 s, 1 kHz run, and the CSV reference."""
    repeat = 3 if quick else 9
    one = sample_run()
    data = run_bytes(one)
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        csv_text = zf.read("signals.csv").decode()
    read = median_ms(lambda: read_run(data, robot=one.robot), repeat)
    reference = median_ms(lambda: np.loadtxt(io.StringIO(csv_text), delimiter=",",
                                             skiprows=1), repeat)
    return {
        "run_write_ms": median_ms(lambda: run_bytes(one), repeat),
        "run_read_ms": read,
        "run_csv_reference_ms": reference,
        "run_read_over_reference": read / reference,
        "export_html_ms": median_ms(lambda: export_html(one), repeat),
        "run_file_kib": len(data) / 1024.0,
    }
