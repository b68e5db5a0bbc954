"""Writing a run file: :func:`run_bytes` in memory, :func:`write_run` to a path, whole or
absent (docs/runs.md)."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
import zipfile
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from armlab.control.run_errors import RunFileError
from armlab.control.run_model import (
    CSV_MEMBER,
    FORMAT,
    JSON_MEMBER,
    SUFFIX,
    Run,
    check_run,
    ordered_signals,
    signal_columns,
)


def run_bytes(run: Run) -> bytes:
    """The run file of ``run`` in memory (what :func:`write_run` writes).

    Raises:
        RunFileError: the run itself is not valid (see :func:`read_run`'s checks).
    """
    check_run(run, "the run to save")
    columns = ["t"] + [col for name in ordered_signals(run)
                       for col in signal_columns(name, run.joint_names)]
    meta = {
        "format": FORMAT, "version": run.version, "robot": run.robot,
        "joint_names": list(run.joint_names), "source": run.source,
        "lab_version": run.lab_version, "created": run.created,
        "params": run.params, "commands": list(run.commands),
        "figures": {k: _figure(v) for k, v in run.figures.items()},
        "extra": run.extra,
        "units": {"t": "s", **{name: run.unit(name) for name in ordered_signals(run)}},
        "columns": columns,
    }
    if run.lesson_signals:
        meta["lesson_signals"] = dict(run.lesson_signals)
    try:
        text = json.dumps(meta, indent=1, ensure_ascii=False, allow_nan=False,
                          default=_numpy_json)
    except (TypeError, ValueError) as e:
        raise RunFileError(f"the run to save has a value JSON cannot hold ({e}): "
                           "params, commands and extra take numbers, strings, lists, "
                           "dicts, booleans and null, never NaN or infinity") from None
    buf = io.BytesIO()
    # deflate's fastest level: several times faster than the default on a long run's CSV,
    # for a file a little larger (`armlab bench --only runs` measures the write)
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(_member(JSON_MEMBER), text.encode("utf-8"), compresslevel=1)
        zf.writestr(_member(CSV_MEMBER), _csv_text(run, columns).encode("utf-8"),
                    compresslevel=1)
    return buf.getvalue()


def write_run(run: Run, path: str | Path) -> Path:
    """Write ``run`` to ``path`` atomically (a temporary file in the same folder, then a
    rename): the file is either whole or absent. Returns the path written.

    Raises:
        RunFileError: the run is not valid, or the path cannot be written (no such
            folder, a folder of that name, no permission, disk full).
    """
    return save_file(path, run_bytes(run))


def writable_path(path: str | Path, *, what: str = "save the run",
                  example: str = "run" + SUFFIX) -> Path:
    """``path`` if a file can be saved there (its folder exists and can be written, it
    is not a folder itself); checked before a long run so that it fails first.

    Args:
        what: what the message says could not be done ("save the run", "write the page").
        example: a file name the message offers when ``path`` is a folder.

    Raises:
        RunFileError: saying why not and what to do.
    """
    path = Path(path)
    folder = path.parent
    if path.is_dir():
        raise RunFileError(f"cannot {what} to {path}: it is a folder; "
                           f"give a file name, e.g. {path / example}")
    if not folder.is_dir():
        raise RunFileError(f"cannot {what} to {path}: the folder {folder} does not "
                           "exist; create it or choose another")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise RunFileError(f"cannot {what} to {path}: the folder {folder} cannot be "
                           "written to (permission denied); choose a folder you can write to")
    return path


def save_file(path: str | Path, data: bytes, *, what: str = "save the run",
              example: str = "run" + SUFFIX) -> Path:
    """Write ``data`` to ``path`` atomically (a temporary file in the same folder, synced,
    then renamed over it, mode 0644): whole or absent, nothing left behind on a failure.

    Raises:
        RunFileError: as :func:`writable_path`, or the write failed (disk full, ...).
    """
    path = writable_path(path, what=what, example=example)
    tmp: str | None = None
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".part")
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
        tmp = None
    except OSError as e:
        raise RunFileError(f"cannot {what} to {path}: {e.strerror or e}; "
                           "choose a folder you can write to") from None
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    return path


def _member(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=datetime.now(UTC).timetuple()[:6])
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    return info


def _numpy_json(value: Any) -> Any:
    """numpy arrays and scalars in params, commands or extra, as JSON lists and numbers."""
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON")


def _figure(v: Any) -> float | None:
    if v is None:
        return None
    x = float(v)
    return x if math.isfinite(x) else None


def _cell(v: float) -> str:
    return "" if v != v else repr(v)


def _csv_text(run: Run, columns: list[str]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    table = np.column_stack([run.t] + [run.signals[name] for name in ordered_signals(run)])
    for row in table.tolist():
        buf.write(",".join([_cell(v) for v in row]))
        buf.write("\n")
    return buf.getvalue()
