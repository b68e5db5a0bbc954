"""Run files: one recorded run (gains, commands, states at the loop rate, figures) a person keeps.

A run file is a zip of two members (docs/runs.md):

- ``run.json``: format, version, robot, joint names, what made it, the lab's
  version, when, the parameters, the commands, the figures, free ``extra`` JSON,
  each signal's unit and the CSV's header ("columns");
- ``signals.csv``: header ``t,q_cmd.<joint>,...,q.<joint>,...``, one row per loop
  period, SI units, floats written with ``repr`` (a read gives the identical
  float64 values), an empty cell where a value is missing (NaN).

:func:`read_run` never extracts anything to disk: it reads the two members into
memory in bounded chunks, after checking the file's size, every member's name,
the declared sizes and compression ratios, and then every value. Each refusal is
one :class:`RunFileError` that says what is wrong and what to do.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import struct
import tempfile
import zipfile
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from armlab.control.recorder import SIGNALS, UNITS

FORMAT = "armlab-run"
#: The newest version this lab reads. A run is written as version 1 (every reader reads it)
#: unless it holds a lesson's own signals (:attr:`Run.lesson_signals`): then 2, so that a
#: version-1 reader says "written by a newer armlab" rather than refusing a column.
VERSION = 2
#: A lesson signal's name: lower-case letters, digits and ``_``, a letter first, at most 32.
LESSON_SIGNAL_NAME = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
#: The most lesson signals a run may hold, and the longest unit text.
MAX_LESSON_SIGNALS = 32
MAX_UNIT_CHARS = 16
#: A run file larger than this is refused before it is opened.
MAX_FILE_BYTES = 64 * 2**20
#: The most the members read may unpack to, together (bytes).
MAX_UNPACKED_BYTES = 256 * 2**20
#: The most run.json alone may unpack to (bytes).
MAX_JSON_BYTES = 16 * 2**20
#: A member unpacking to more than this many times its packed size (and to more than
#: :data:`RATIO_FLOOR_BYTES`) is taken for a zip bomb.
MAX_RATIO = 200
RATIO_FLOOR_BYTES = 2**20
#: The most members a run file may hold (it needs two; the rest are ignored), and the
#: largest zip directory: both bound what listing the members costs.
MAX_MEMBERS = 64
MAX_DIRECTORY_BYTES = 2**20
#: The suffix a saved run is given (any name is accepted when reading).
SUFFIX = ".armlab-run.zip"

JSON_MEMBER = "run.json"
CSV_MEMBER = "signals.csv"
_CHUNK = 2**20
_DRIVE = re.compile(r"^[A-Za-z]:")


class RunFileError(ValueError):
    """A run file (or a run to write) refused: the message says what is wrong and what to do."""


@dataclass(frozen=True)
class Run:
    """One recorded run.

    Attributes:
        robot: robot model name, e.g. "thesis", "receptionist_arm".
        joint_names: the model's joint names, in its order (n).
        source: what made it, e.g. "page:compliance", "experiment:thesis-line".
        lab_version: armlab's version when written.
        created: ISO 8601 UTC time it was made.
        params: gains and environment (``Params`` fields: kp, kv, m_env, ...): numbers,
            strings or booleans.
        commands: what was commanded, in order: {"t": s, "kind": "...", ...JSON fields}.
        figures: measured figures by name, units in the name ("overshoot_pct",
            "settling_s", "max_error_deg", ...); None where not measured.
        t: (m,) loop time, s, strictly increasing.
        signals: name -> (m, n) array, SI, names from
            :data:`armlab.control.recorder.SIGNALS` or :attr:`lesson_signals`; "q" (measured
            angles, rad) required.
        extra: free JSON kept verbatim (e.g. {"challenge": {...}}).
        lesson_signals: a lesson's own per-joint signals, name -> unit, in the file's
            column order (after the recorder's), e.g. {"current": "A", "force": "N"}: the
            hand's motor currents, what the recorder's SIGNALS have no name for.
    """

    robot: str
    joint_names: tuple[str, ...]
    source: str
    lab_version: str
    created: str
    params: dict[str, float | str]
    commands: tuple[dict, ...]
    figures: dict[str, float | None]
    t: np.ndarray
    signals: dict[str, np.ndarray]
    extra: dict[str, object] = field(default_factory=dict)
    lesson_signals: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "commands", tuple(self.commands))
        object.__setattr__(self, "t", np.asarray(self.t, dtype=np.float64))
        object.__setattr__(self, "lesson_signals", dict(self.lesson_signals))
        known = [*SIGNALS, *self.lesson_signals]
        order = sorted(self.signals, key=lambda k: (known.index(k) if k in known
                                                    else len(known)))
        object.__setattr__(self, "signals", {  # in the file's order: SIGNALS, then the lesson's
            k: np.asarray(self.signals[k], dtype=np.float64) for k in order})

    @property
    def version(self) -> int:
        """The run format version this run is written as: 1, or 2 with lesson signals."""
        return 2 if self.lesson_signals else 1

    def unit(self, signal: str) -> str:
        """The unit of ``signal`` ("t", a recorder signal or a lesson signal)."""
        return "s" if signal == "t" else UNITS.get(signal) or self.lesson_signals[signal]


def lab_version() -> str:
    """armlab's installed version ("unknown" when it is not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("armlab")
    except PackageNotFoundError:
        return "unknown"


def utc_now() -> str:
    """The time now, ISO 8601 UTC to the second, e.g. "2026-11-28T03:20:00Z"."""
    return datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def run_from_snapshot(snap: Mapping[str, np.ndarray], *, robot: str,
                      joint_names: Sequence[str], source: str,
                      params: Mapping[str, Any], commands: Sequence[Mapping[str, Any]] = (),
                      figures: Mapping[str, float | None] | None = None,
                      extra: Mapping[str, object] | None = None,
                      lesson_signals: Mapping[str, str] | None = None) -> Run:
    """A :class:`Run` from a ``Recorder.snapshot()`` (keys t, wall, q_cmd, q, ...).

    Rows at the start where ``q`` is not yet recorded (NaN) are dropped; signals that
    are NaN throughout are left out ("q" and every one of ``lesson_signals``, name ->
    unit, the snapshot's keys of a lesson's own signals, are always kept); "wall" is not
    kept. The arrays are copied. Stamped with this lab's version and the time now.
    """
    t = np.asarray(snap["t"], dtype=np.float64)
    q = np.asarray(snap["q"], dtype=np.float64).reshape(len(t), -1)
    recorded = np.isfinite(q).all(axis=1) & np.isfinite(t)
    start = int(np.argmax(recorded)) if recorded.any() else len(t)
    signals: dict[str, np.ndarray] = {}
    for name in SIGNALS:
        if name not in snap:
            continue
        values = np.array(snap[name], dtype=np.float64).reshape(len(t), -1)[start:]
        if name == "q" or not np.isnan(values).all():
            signals[name] = values
    own = dict(lesson_signals or {})
    for name in own:
        signals[name] = np.array(snap[name], dtype=np.float64).reshape(len(t), -1)[start:]
    return Run(robot=robot, joint_names=tuple(joint_names), source=source,
               lab_version=lab_version(), created=utc_now(), params=dict(params),
               commands=tuple(dict(c) for c in commands),
               figures=dict(figures or {}), t=t[start:].copy(), signals=signals,
               extra=dict(extra or {}), lesson_signals=own)


# --------------------------------------------------------------------------- writing


def run_bytes(run: Run) -> bytes:
    """The run file of ``run`` in memory (what :func:`write_run` writes).

    Raises:
        RunFileError: the run itself is not valid (see :func:`read_run`'s checks).
    """
    _check_run(run, "the run to save")
    columns = ["t"] + [f"{name}.{j}" for name in _ordered(run) for j in run.joint_names]
    meta = {
        "format": FORMAT, "version": run.version, "robot": run.robot,
        "joint_names": list(run.joint_names), "source": run.source,
        "lab_version": run.lab_version, "created": run.created,
        "params": run.params, "commands": list(run.commands),
        "figures": {k: _figure(v) for k, v in run.figures.items()},
        "extra": run.extra,
        "units": {"t": "s", **{name: run.unit(name) for name in _ordered(run)}},
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


def _ordered(run: Run) -> list[str]:
    """The run's signal names in the file's order: :data:`SIGNALS`, then its lesson's."""
    return [name for name in (*SIGNALS, *run.lesson_signals) if name in run.signals]


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
    table = np.column_stack([run.t] + [run.signals[name] for name in _ordered(run)])
    for row in table.tolist():
        buf.write(",".join([_cell(v) for v in row]))
        buf.write("\n")
    return buf.getvalue()


# --------------------------------------------------------------------------- reading


def read_run(source: str | Path | bytes, *, robot: str | None = None,
             name: str | None = None) -> Run:
    """Read and check a run file, from a path or its bytes; writes nothing anywhere.

    Args:
        source: the file's path, or its contents.
        robot: the robot this lab runs; a run of another robot is refused.
        name: what to call the file in messages (default: its path, or "the run file").

    Raises:
        RunFileError: one message per problem: too large, not a zip, truncated or
            damaged, a member with an absolute path, ".." or a backslash, encrypted, a
            zip bomb (unpacking past the limits), missing run.json or signals.csv,
            another format, a newer version, another robot, ragged or empty rows, a
            cell that is not a number, NaN/inf in t or q, t not increasing, columns
            disagreeing with the joint names.
    """
    label = name or (str(source) if not isinstance(source, bytes | bytearray) else "the run file")
    data = _load(source, label)
    members = _members(data, label)
    meta = _meta(members[JSON_MEMBER], label, robot)
    t, signals = _signals(members[CSV_MEMBER], meta, label)
    run = Run(robot=meta["robot"], joint_names=tuple(meta["joint_names"]),
              source=meta["source"], lab_version=meta["lab_version"], created=meta["created"],
              params=meta["params"], commands=tuple(meta["commands"]),
              figures=meta["figures"], t=t, signals=signals, extra=meta["extra"],
              lesson_signals=meta.get("lesson_signals", {}))
    _check_run(run, label)
    return run


def _load(source: str | Path | bytes, label: str) -> bytes:
    """The file's bytes, after refusing a file over :data:`MAX_FILE_BYTES` unopened."""
    if isinstance(source, bytes | bytearray):
        if len(source) > MAX_FILE_BYTES:
            raise _too_large(label, len(source))
        return bytes(source)
    path = Path(source)
    try:
        size = path.stat().st_size
        if path.is_dir():
            raise RunFileError(f"{label} is a folder, not a run file: choose the "
                               f"{SUFFIX} file inside it")
        if size > MAX_FILE_BYTES:
            raise _too_large(label, size)
        with path.open("rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise RunFileError(f"{label}: no such file; check the name and folder") from None
    except PermissionError:
        raise RunFileError(f"{label} cannot be read (permission denied)") from None
    except OSError as e:
        raise RunFileError(f"{label} cannot be read: {e.strerror or e}") from None
    if len(data) > MAX_FILE_BYTES:
        raise _too_large(label, len(data))
    return data


def _too_large(label: str, size: int) -> RunFileError:
    return RunFileError(f"{label} is {size / 2**20:.1f} MiB; a run file may be at most "
                        f"{MAX_FILE_BYTES // 2**20} MiB: record a shorter run")


def _directory(data: bytes) -> tuple[int, int] | None:
    """(members, directory bytes) of the zip's end record (its zip64 one when it points to
    it), or None when there is no end record."""
    at = data.rfind(b"PK\x05\x06", max(0, len(data) - 22 - 0xFFFF))
    if at < 0 or len(data) < at + 22:
        return None
    _, _, _, _, count, size, _, _ = struct.unpack("<IHHHHIIH", data[at:at + 22])
    loc = at - 20
    if (count == 0xFFFF or size == 0xFFFFFFFF) and loc >= 0 and \
            data[loc:loc + 4] == b"PK\x06\x07":
        (offset,) = struct.unpack("<Q", data[loc + 8:loc + 16])
        if data[offset:offset + 4] == b"PK\x06\x06" and len(data) >= offset + 56:
            count, size = struct.unpack("<QQ", data[offset + 32:offset + 48])
    return count, size


def _members(data: bytes, label: str) -> dict[str, bytes]:
    """run.json and signals.csv read from the zip in memory, every member checked."""
    directory = _directory(data)
    if directory is not None and (directory[0] > MAX_MEMBERS
                                  or directory[1] > MAX_DIRECTORY_BYTES):
        raise RunFileError(f"{label} lists {directory[0]} members in a {directory[1]}-byte "
                           f"directory; a run file holds two (at most {MAX_MEMBERS}): "
                           "refused, it was not written by armlab")
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        if data[:4] in (b"PK\x03\x04", b"PK\x05\x06"):
            raise RunFileError(f"{label} is truncated or damaged (its zip directory is "
                               "missing): download or copy it again") from None
        raise RunFileError(f"{label} is not a run file (not a zip archive): open a file "
                           f"saved with Save run or --save-run (*{SUFFIX})") from None
    except (OSError, EOFError, ValueError, NotImplementedError) as e:
        raise RunFileError(f"{label} is a damaged zip archive ({e}): download or copy "
                           "it again") from None
    with zf:
        infos = zf.infolist()
        seen: set[str] = set()
        for info in infos:
            _check_member_name(info.filename, label)
            if info.filename in seen:
                raise RunFileError(f"{label} holds two members named {info.filename!r}; "
                                   "refused: it was not written by armlab")
            seen.add(info.filename)
        wanted = {i.filename: i for i in infos if i.filename in (JSON_MEMBER, CSV_MEMBER)}
        for needed in (JSON_MEMBER, CSV_MEMBER):
            if needed not in wanted:
                raise RunFileError(f"{label} has no {needed}: it is a zip, but not a run "
                                   f"file (a run file holds {JSON_MEMBER} and {CSV_MEMBER})")
        total = 0
        for info in wanted.values():
            _check_member_size(info, label)
            total += info.file_size
        if total > MAX_UNPACKED_BYTES:
            raise _bomb(label, "its members", total)
        return {n: _read_member(zf, info, label) for n, info in wanted.items()}


def _check_member_name(name: str, label: str) -> None:
    parts = name.split("/")
    hostile = (name.startswith("/") or "\\" in name or "\x00" in name
               or _DRIVE.match(name) is not None or ".." in parts
               or any(ord(c) < 32 for c in name))
    if hostile:
        raise RunFileError(f"{label} holds a member named {name!r}, a path that would land "
                           "outside its folder (absolute, '..', a drive or a backslash); "
                           "refused: it was not written by armlab, do not unpack it")


def _check_member_size(info: zipfile.ZipInfo, label: str) -> None:
    if info.flag_bits & 0x1:
        raise RunFileError(f"{label}: {info.filename} is encrypted; run files are never "
                           "encrypted, so it was not written by armlab")
    limit = MAX_JSON_BYTES if info.filename == JSON_MEMBER else MAX_UNPACKED_BYTES
    if info.file_size > limit:
        raise _bomb(label, info.filename, info.file_size)
    if (info.file_size > RATIO_FLOOR_BYTES
            and info.file_size > MAX_RATIO * max(info.compress_size, 1)):
        raise RunFileError(
            f"{label}: {info.filename} would unpack {info.compress_size} bytes to "
            f"{info.file_size / 2**20:.1f} MiB (over {MAX_RATIO}:1), the mark of a zip "
            "bomb; refused")


def _bomb(label: str, what: str, size: int) -> RunFileError:
    return RunFileError(f"{label}: {what} would unpack to {size / 2**20:.1f} MiB, over the "
                        f"{MAX_UNPACKED_BYTES // 2**20} MiB a run may hold (a zip bomb, or "
                        "far too long a run); refused")


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, label: str) -> bytes:
    """The member's bytes, read in chunks and never past its declared size."""
    out = bytearray()
    try:
        with zf.open(info) as f:
            while chunk := f.read(_CHUNK):
                out += chunk
                if len(out) > info.file_size:
                    raise RunFileError(f"{label}: {info.filename} unpacks to more than "
                                       "its declared size; refused (a forged zip)")
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError) as e:
        raise RunFileError(f"{label} is truncated or damaged ({info.filename}: {e}): "
                           "download or copy it again") from None
    except NotImplementedError as e:
        raise RunFileError(f"{label}: {info.filename} is packed in a way armlab does not "
                           f"write ({e}); refused") from None
    if len(out) != info.file_size:
        raise RunFileError(f"{label}: {info.filename} is shorter than its declared size; "
                           "the file is truncated or damaged: download or copy it again")
    return bytes(out)


def _reject_constant(word: str) -> Any:
    raise ValueError(f"{word} is not allowed")


def _meta(raw: bytes, label: str, robot: str | None) -> dict[str, Any]:
    """run.json, parsed and checked (format, version, robot, field types)."""
    try:
        meta = json.loads(raw.decode("utf-8-sig"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise RunFileError(f"{label}: {JSON_MEMBER} is not valid JSON ({e}); the file is "
                           "damaged or was edited by hand") from None
    if not isinstance(meta, dict):
        raise RunFileError(f"{label}: {JSON_MEMBER} is not a JSON object; the file is "
                           "damaged or was not written by armlab")
    if meta.get("format") != FORMAT:
        raise RunFileError(f"{label} is not an armlab run (its format is "
                           f"{meta.get('format')!r}, not {FORMAT!r})")
    version = meta.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise RunFileError(f"{label}: {JSON_MEMBER} has no valid version ({version!r}); "
                           "the file is damaged")
    if version > VERSION:
        raise RunFileError(f"{label} was written by a newer armlab (run format version "
                           f"{version}; this lab reads up to {VERSION}): update armlab "
                           f"(this is {lab_version()}) to open it")
    kinds: dict[str, type | tuple[type, ...]] = {
        "robot": str, "joint_names": list, "source": str, "lab_version": str,
        "created": str, "params": dict, "commands": list, "figures": dict, "extra": dict,
        "columns": list}
    for key, kind in kinds.items():
        if not isinstance(meta.get(key), kind):
            raise RunFileError(f"{label}: {JSON_MEMBER} lacks {key!r} or it has the wrong "
                               "type; the file is damaged or was edited by hand")
    own = meta.get("lesson_signals", {})
    if not isinstance(own, dict):
        raise RunFileError(f"{label}: {JSON_MEMBER}'s 'lesson_signals' is not a JSON object "
                           "(name -> unit); the file is damaged or was edited by hand")
    _check_lesson_signals(own, label)
    if robot is not None and meta["robot"] != robot:
        raise RunFileError(f"{label} is a run of the robot {meta['robot']!r}; this lab runs "
                           f"{robot!r}: open it in a lab started with --robot "
                           f"{meta['robot']}")
    return meta


def _signals(raw: bytes, meta: Mapping[str, Any],
             label: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """t and the signals of signals.csv, its header checked against run.json."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise RunFileError(f"{label}: {CSV_MEMBER} is not UTF-8 text ({e})") from None
    rows = csv.reader(io.StringIO(text, newline=""))
    try:
        header = next(rows, None)
        if header is None:
            raise RunFileError(f"{label}: {CSV_MEMBER} is empty; the run holds no samples")
        if header != meta["columns"]:
            raise RunFileError(f"{label}: {CSV_MEMBER}'s header disagrees with the columns "
                               f"{JSON_MEMBER} lists; the file was edited or damaged")
        layout = _layout(header, [str(j) for j in meta["joint_names"]], label,
                         known=(*SIGNALS, *meta.get("lesson_signals", {})))
        width = len(header)
        lines = max(text.count("\n"), text.count("\r")) + 1  # at least one per row
        table = np.empty((lines, width))
        m = 0
        for line, row in enumerate(rows, start=2):
            if len(row) != width:
                if not row:
                    raise RunFileError(f"{label}: {CSV_MEMBER} line {line} is blank; every "
                                       "line after the header is one sample")
                raise RunFileError(f"{label}: {CSV_MEMBER} line {line} has {len(row)} "
                                   f"cells, the header {width} (ragged rows); the file was "
                                   "cut or edited")
            table[m] = [_number(c, line, header[i], label) for i, c in enumerate(row)]
            m += 1
    except csv.Error as e:
        raise RunFileError(f"{label}: {CSV_MEMBER} is not readable CSV ({e})") from None
    if m == 0:
        raise RunFileError(f"{label}: {CSV_MEMBER} has a header but no samples")
    table = table[:m]
    return table[:, 0].copy(), {name: table[:, cols].copy() for name, cols in layout.items()}


def _layout(header: list[str], joints: list[str], label: str, *,
            known: Sequence[str] = SIGNALS) -> dict[str, list[int]]:
    """signal -> its column indices, checking the header is t then each signal's joints
    (``known``: the recorder's signals and the lesson signals run.json declares)."""
    if not header or header[0] != "t":
        raise RunFileError(f"{label}: {CSV_MEMBER}'s first column is not 't' (loop time, s)")
    if not joints:
        raise RunFileError(f"{label}: {JSON_MEMBER} names no joints")
    layout: dict[str, list[int]] = {}
    for i, col in enumerate(header[1:], start=1):
        signal, _, joint = col.partition(".")
        if signal not in known:
            raise RunFileError(f"{label}: column {col!r} is no signal this lab knows "
                               f"({', '.join(SIGNALS)}) nor one run.json's lesson_signals "
                               "declares; the file is from another program or a newer armlab")
        layout.setdefault(signal, []).append(i)
        cols = layout[signal]
        if len(cols) > len(joints) or joint != joints[len(cols) - 1]:
            raise RunFileError(
                f"{label}: column {col!r} disagrees with the run's {len(joints)} joints "
                f"({', '.join(joints)}); each signal needs one column per joint, in order")
    for signal, cols in layout.items():
        if len(cols) != len(joints) or cols != list(range(cols[0], cols[0] + len(cols))):
            raise RunFileError(
                f"{label}: signal {signal!r} has {len(cols)} columns for "
                f"{len(joints)} joints ({', '.join(joints)}); the file was edited or damaged")
    return layout


def _number(cell: str, line: int, column: str, label: str) -> float:
    if cell == "":
        return math.nan
    try:
        return float(cell)
    except ValueError:
        raise RunFileError(f"{label}: {CSV_MEMBER} line {line}, column {column!r}: "
                           f"{cell[:40]!r} is not a number") from None


# --------------------------------------------------------------------------- checks


def _check_run(run: Run, label: str) -> None:
    """Everything a run must be, whether about to be written or just read."""
    for key in ("robot", "source", "lab_version", "created"):
        if not isinstance(getattr(run, key), str):
            raise RunFileError(f"{label}: {key} must be text, got {getattr(run, key)!r}")
    if not run.robot:
        raise RunFileError(f"{label}: the robot is not named")
    joints = run.joint_names
    if not joints or not all(isinstance(j, str) and j for j in joints):
        raise RunFileError(f"{label}: joint names must be non-empty text, got {joints!r}")
    if len(set(joints)) != len(joints):
        raise RunFileError(f"{label}: joint names repeat: {', '.join(joints)}")
    n = len(joints)
    t = run.t
    if t.ndim != 1 or len(t) == 0:
        raise RunFileError(f"{label}: t must hold at least one sample, shape {t.shape}")
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise RunFileError(f"{label}: t is NaN or infinite at sample {bad[0]}; every "
                           "sample needs its loop time")
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if len(back):
        i = int(back[0]) + 1
        raise RunFileError(f"{label}: t does not increase at sample {i} "
                           f"({t[i - 1]!r} s then {t[i]!r} s); samples must be in time order")
    if "q" not in run.signals:
        raise RunFileError(f"{label}: no 'q' signal (the measured joint angles), which a run "
                           "must hold")
    _check_lesson_signals(run.lesson_signals, label)
    for name in run.lesson_signals:
        if name not in run.signals:
            raise RunFileError(f"{label}: the lesson signal {name!r} is declared but has no "
                               "columns")
    for name, values in run.signals.items():
        if name not in SIGNALS and name not in run.lesson_signals:
            raise RunFileError(f"{label}: {name!r} is no signal this lab knows "
                               f"({', '.join(SIGNALS)}) nor a declared lesson signal")
        if values.shape != (len(t), n):
            raise RunFileError(f"{label}: signal {name!r} has shape {values.shape}, but the "
                               f"run has {len(t)} samples of {n} joints")
    q = run.signals["q"]
    bad_q = np.argwhere(~np.isfinite(q))
    if len(bad_q):
        i, j = bad_q[0]
        raise RunFileError(f"{label}: q (the measured angles) is NaN or infinite at sample "
                           f"{i} (t = {t[i]!r} s), joint {joints[j]}; a run's poses must all "
                           "be known")
    for key, value in run.params.items():
        if not isinstance(key, str) or not (
                isinstance(value, str | bool | int | float) and _finite(value)):
            raise RunFileError(f"{label}: parameter {key!r} = {value!r} is not a finite "
                               "number, text or a boolean")
    for i, command in enumerate(run.commands):
        if (not isinstance(command, Mapping) or not isinstance(command.get("kind"), str)
                or not isinstance(command.get("t"), int | float)
                or not _finite(command["t"])):
            raise RunFileError(f"{label}: command {i} needs a 'kind' (text) and a finite "
                               f"'t' (s), got {command!r}")
    for key, value in run.figures.items():
        if not isinstance(key, str) or not (value is None or (
                isinstance(value, int | float | np.floating | np.integer)
                and not isinstance(value, bool))):
            raise RunFileError(f"{label}: figure {key!r} = {value!r} is not a number or "
                               "null")
    if not isinstance(run.extra, Mapping):
        raise RunFileError(f"{label}: extra must be a JSON object, got {run.extra!r}")


def _check_lesson_signals(own: Mapping[Any, Any], label: str) -> None:
    """A lesson's own signals: at most :data:`MAX_LESSON_SIGNALS`, each named by
    :data:`LESSON_SIGNAL_NAME` (not "t" nor a recorder signal) with a unit of printable
    text of at most :data:`MAX_UNIT_CHARS` characters."""
    if len(own) > MAX_LESSON_SIGNALS:
        raise RunFileError(f"{label}: {len(own)} lesson signals; a run may hold at most "
                           f"{MAX_LESSON_SIGNALS}")
    for name, unit in own.items():
        if (not isinstance(name, str) or LESSON_SIGNAL_NAME.match(name) is None
                or name in SIGNALS or name == "t"):
            raise RunFileError(f"{label}: {name!r} cannot name a lesson signal (lower-case "
                               "letters, digits and _, a letter first, at most 32, none of "
                               f"t, {', '.join(SIGNALS)})")
        if not (isinstance(unit, str) and len(unit) <= MAX_UNIT_CHARS and unit.isprintable()):
            raise RunFileError(f"{label}: the lesson signal {name!r} has no valid unit "
                               f"({unit!r}): printable text of at most {MAX_UNIT_CHARS} "
                               "characters, e.g. \"A\"")


def _finite(value: Any) -> bool:
    return not isinstance(value, float) or math.isfinite(value)
