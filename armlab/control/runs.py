"""Run files: one recorded run (gains, commands, states at the loop rate, figures) a person keeps.

A run file is a zip of two members (docs/runs.md):

- ``run.json``: format, version, robot, joint names, what made it, the lab's
  version, when, the parameters, the commands, the figures, free ``extra`` JSON,
  each signal's unit and the CSV's header ("columns");
- ``signals.csv``: header ``t,q_cmd.<joint>,...,q.<joint>,...``, one row per loop
  period, SI units, floats written with ``repr`` (a read gives the identical
  float64 values), an empty cell where a value is missing (NaN).

This module offers the whole of it; the parts live in small modules:

- :mod:`armlab.control.run_model`: :class:`Run`, what every run must be, the format's
  constants, :func:`run_from_snapshot`;
- :mod:`armlab.control.run_save`: :func:`run_bytes`, :func:`write_run` (whole or absent);
- :mod:`armlab.control.run_read`: :func:`read_run`, which never extracts anything to
  disk and reads any file in bounded memory and time, or refuses it with one
  :class:`RunFileError` that says what is wrong and what to do;
- :mod:`armlab.control.run_zip`: the zip read in memory, trusting none of its claims;
- :mod:`armlab.control.run_errors`: :class:`RunFileError` and :func:`quote`, the one way
  a file's text enters a message (at most ~200 characters of it).
"""

from __future__ import annotations

from armlab.control.run_errors import QUOTE_CHARS, RunFileError, clip, quote
from armlab.control.run_model import (
    CSV_MEMBER,
    FORMAT,
    JSON_MEMBER,
    LESSON_SIGNAL_NAME,
    MAX_DRAWN_VALUE,
    MAX_JOINTS,
    MAX_LESSON_SIGNALS,
    MAX_NAME_CHARS,
    MAX_TIME_S,
    MAX_UNIT_CHARS,
    MIN_STEP_S,
    SUFFIX,
    VERSION,
    Run,
    check_drawable,
    lab_version,
    run_from_snapshot,
    utc_now,
)
from armlab.control.run_read import (
    MAX_CELLS,
    MAX_COLUMNS,
    MAX_FILE_BYTES,
    MAX_JSON_BYTES,
    MAX_JSON_VALUES,
    MAX_NUMBER_CHARS,
    MAX_UNPACKED_BYTES,
    read_run,
)
from armlab.control.run_save import run_bytes, save_file, writable_path, write_run
from armlab.control.run_zip import (
    MAX_DIRECTORY_BYTES,
    MAX_MEMBERS,
    MAX_NAME_BYTES,
    MAX_RATIO,
    RATIO_FLOOR_BYTES,
)

__all__ = [
    "CSV_MEMBER", "FORMAT", "JSON_MEMBER", "LESSON_SIGNAL_NAME", "MAX_CELLS", "MAX_COLUMNS",
    "MAX_DIRECTORY_BYTES", "MAX_DRAWN_VALUE", "MAX_FILE_BYTES", "MAX_JOINTS", "MAX_JSON_BYTES",
    "MAX_JSON_VALUES",
    "MAX_LESSON_SIGNALS", "MAX_MEMBERS", "MAX_NAME_BYTES", "MAX_NAME_CHARS",
    "MAX_NUMBER_CHARS", "MAX_RATIO", "MAX_TIME_S", "MAX_UNIT_CHARS", "MAX_UNPACKED_BYTES",
    "MIN_STEP_S", "QUOTE_CHARS", "RATIO_FLOOR_BYTES", "SUFFIX", "VERSION", "Run",
    "RunFileError", "check_drawable", "clip", "lab_version", "quote", "read_run", "run_bytes",
    "run_from_snapshot", "save_file", "utc_now", "writable_path", "write_run",
]
