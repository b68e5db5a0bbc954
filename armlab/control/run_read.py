"""Reading a run file, whatever it holds (docs/runs.md, "What is refused").

:func:`read_run` never extracts anything to disk and trusts nothing the file declares:

- the file is at most :data:`MAX_FILE_BYTES`, read in memory; its zip is read by
  :mod:`armlab.control.run_zip` (stored and deflated members only, each unpacked in
  chunks under a cap, members counted from the directory read);
- run.json is at most :data:`MAX_JSON_BYTES` unpacked and :data:`MAX_JSON_VALUES` values
  (counted before it is parsed); every number in it is at most
  :data:`MAX_NUMBER_CHARS` characters long, checked before it is converted (a
  4000-digit integer is refused, never made), and finite;
- signals.csv is parsed as it is unpacked: its header at most :data:`MAX_HEADER_CHARS`
  characters, every later line at most :data:`MAX_CELL_CHARS` per cell, every cell at
  most :data:`MAX_NUMBER_CHARS`, and rows × columns at most :data:`MAX_CELLS`, checked
  before a row is stored;
- the run is then checked as a whole (:func:`armlab.control.run_model.check_run`).

So any file of at most 64 MiB is read or refused in bounded memory and time (the bounds
measured are in docs/runs.md). Each refusal is one
:class:`~armlab.control.run_errors.RunFileError` of one line, quoting at most ~200
characters of the file.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from armlab.control.recorder import CONTACT_SIGNALS, SIGNALS
from armlab.control.run_errors import RunFileError, clip, quote
from armlab.control.run_model import (
    CSV_MEMBER,
    FORMAT,
    JSON_MEMBER,
    MAX_JOINTS,
    MAX_LESSON_SIGNALS,
    MAX_NAME_CHARS,
    SUFFIX,
    VERSION,
    Run,
    check_lesson_signals,
    check_run,
    lab_version,
)
from armlab.control.run_zip import Member, iter_member, list_members, read_member

#: What reading and exporting any file of at most :data:`MAX_FILE_BYTES` costs at most, or
#: what refusing it costs (``armlab export``'s peak resident memory, MiB, and CPU, s):
#: about twice the 85 MiB of exporting the longest run the lab saves (docs/runs.md);
#: measured by tests/test_hostile_runs.py.
MEMORY_BOUND_MIB = 170
CPU_BOUND_S = 30.0
#: A run file larger than this is refused before it is opened.
MAX_FILE_BYTES = 64 * 2**20
#: The most signals.csv may unpack to (bytes).
MAX_UNPACKED_BYTES = 256 * 2**20
#: The most run.json may unpack to (bytes).
MAX_JSON_BYTES = 4 * 2**20
#: The most values signals.csv may hold (rows × columns, the header not counted): 4 Mi
#: float64 values, 32 MiB; the lab's longest run (30 s at 1 ms, all ten signals of three
#: joints) holds 0.93 M.
MAX_CELLS = 4 * 2**20
#: The most values run.json may hold, counted as its ``{``, ``[`` and ``,`` before it is
#: parsed (each value past the first of a list or object needs one): a parsed value costs
#: up to ~200 bytes (an object in a list), so 4 MiB of ``[{},{},...]`` would cost 300 MiB.
#: The longest run's run.json (5000 commands) holds about 90 k, an experiment's 8 k.
MAX_JSON_VALUES = 250_000
#: The longest number (characters) in run.json or a cell of signals.csv: a float's
#: ``repr`` is at most 24.
MAX_NUMBER_CHARS = 32
#: The most columns signals.csv may have: t, then every signal of every joint.
MAX_COLUMNS = 1 + (len(SIGNALS) + MAX_LESSON_SIGNALS) * MAX_JOINTS + len(CONTACT_SIGNALS)
#: The longest header line (characters), and the longest data line per column.
MAX_HEADER_CHARS = MAX_COLUMNS * (MAX_NAME_CHARS + 40)
MAX_CELL_CHARS = MAX_NUMBER_CHARS + 8


def read_run(source: str | Path | bytes, *, robot: str | None = None,
             name: str | None = None) -> Run:
    """Read and check a run file, from a path or its bytes; writes nothing anywhere.

    Args:
        source: the file's path, or its contents.
        robot: the robot this lab runs; a run of another robot is refused.
        name: what to call the file in messages (default: its path, or "the run file").

    Raises:
        RunFileError: one message per problem: too large, not a zip, truncated or
            damaged, a member with an absolute path, "..", a backslash or a control
            character, packed otherwise than stored or deflated, encrypted, a zip bomb
            (unpacking past the limits), too many members, missing run.json or
            signals.csv, another format, a newer version, another robot, a number too
            long, too many values, ragged or empty rows, a cell that is not a number,
            NaN/inf in t or q, t not increasing by at least 1 µs, columns disagreeing
            with the joint names.
    """
    if name:
        label = name
    else:
        label = str(source) if not isinstance(source, bytes | bytearray) else "the run file"
    label = clip(label)
    data = _load(source, label)
    members = list_members(data, label)
    for needed in (JSON_MEMBER, CSV_MEMBER):
        if needed not in members:
            raise RunFileError(f"{label} has no {needed}: it is a zip, but not a run "
                               f"file (a run file holds {JSON_MEMBER} and {CSV_MEMBER})")
    meta = _meta(read_member(data, members[JSON_MEMBER], label, limit=MAX_JSON_BYTES),
                 label, robot)
    t, signals = _signals(data, members[CSV_MEMBER], meta, label)
    contact = [name for name in CONTACT_SIGNALS if name in signals]
    if contact and meta["version"] < 3:
        raise RunFileError(f"{label}: a version-{meta['version']} file with the contact "
                           f"signal {contact[0]!r}, which only version 3 holds; the file "
                           "was edited or not written by armlab")
    run = Run(robot=meta["robot"], joint_names=tuple(meta["joint_names"]),
              source=meta["source"], lab_version=meta["lab_version"], created=meta["created"],
              params=meta["params"], commands=tuple(meta["commands"]),
              figures=meta["figures"], t=t, signals=signals, extra=meta["extra"],
              lesson_signals=meta.get("lesson_signals", {}))
    check_run(run, label)
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


# --------------------------------------------------------------------------- run.json


def _number_too_long(literal: str) -> ValueError:
    return ValueError(f"a number of {len(literal)} characters ({quote(literal, 40)}); "
                      f"numbers are at most {MAX_NUMBER_CHARS}")


def _json_int(literal: str) -> int:
    if len(literal) > MAX_NUMBER_CHARS:
        raise _number_too_long(literal)
    return int(literal)


def _json_float(literal: str) -> float:
    if len(literal) > MAX_NUMBER_CHARS:
        raise _number_too_long(literal)
    value = float(literal)
    if not math.isfinite(value):
        raise ValueError(f"{quote(literal, 40)} is out of range (not a finite float64)")
    return value


def _json_constant(word: str) -> Any:
    raise ValueError(f"{word} is not allowed")


def parse_json(raw: bytes, label: str) -> Any:
    """``raw`` (run.json) parsed with every number's length checked before conversion,
    after its values are counted (at most :data:`MAX_JSON_VALUES`)."""
    values = raw.count(b",") + raw.count(b"[") + raw.count(b"{")
    if values > MAX_JSON_VALUES:
        raise RunFileError(f"{label}: {JSON_MEMBER} holds up to {values} values (counted by "
                           f"its commas and brackets); a run's holds at most "
                           f"{MAX_JSON_VALUES}: refused, it was not written by armlab")
    try:
        return json.loads(raw.decode("utf-8-sig"), parse_int=_json_int,
                          parse_float=_json_float, parse_constant=_json_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise RunFileError(f"{label}: {JSON_MEMBER} is not valid JSON "
                           f"({clip(str(e))}); the file is damaged or "
                           "was edited by hand") from None


def _meta(raw: bytes, label: str, robot: str | None) -> dict[str, Any]:
    """run.json, parsed and checked (format, version, robot, field types)."""
    meta = parse_json(raw, label)
    if not isinstance(meta, dict):
        raise RunFileError(f"{label}: {JSON_MEMBER} is not a JSON object; the file is "
                           "damaged or was not written by armlab")
    if meta.get("format") != FORMAT:
        raise RunFileError(f"{label} is not an armlab run (its format is "
                           f"{quote(meta.get('format'))}, not {FORMAT!r})")
    version = meta.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise RunFileError(f"{label}: {JSON_MEMBER} has no valid version ({quote(version)}); "
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
    joints = meta["joint_names"]
    if not 0 < len(joints) <= MAX_JOINTS or not all(
            isinstance(j, str) and 0 < len(j) <= MAX_NAME_CHARS for j in joints):
        raise RunFileError(f"{label}: {JSON_MEMBER}'s joint_names must be 1 to {MAX_JOINTS} "
                           f"texts of 1 to {MAX_NAME_CHARS} characters, got {quote(joints)}")
    own = meta.get("lesson_signals", {})
    if not isinstance(own, dict):
        raise RunFileError(f"{label}: {JSON_MEMBER}'s 'lesson_signals' is not a JSON object "
                           "(name -> unit); the file is damaged or was edited by hand")
    check_lesson_signals(own, label)
    if robot is not None and meta["robot"] != robot:
        named = meta["robot"]
        suggest = named if len(named) <= MAX_NAME_CHARS and named.isprintable() else "NAME"
        raise RunFileError(f"{label} is a run of the robot {quote(named)}; this lab "
                           f"runs {robot!r}: open it in a lab started with --robot "
                           f"{clip(suggest)}")
    return meta


# --------------------------------------------------------------------------- signals.csv


class _Chunks(io.RawIOBase):
    """A readable stream of the chunks an iterator yields (a member being unpacked)."""

    def __init__(self, chunks: Iterator[bytes]) -> None:
        super().__init__()
        self._chunks = chunks
        self._view = memoryview(b"")

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        while not self._view:
            piece = next(self._chunks, None)
            if piece is None:
                return 0
            self._view = memoryview(piece)
        n = min(len(buffer), len(self._view))
        buffer[:n] = self._view[:n]
        self._view = self._view[n:]
        return n


class _Lines:
    """The lines of a text stream, each refused past :attr:`limit` characters."""

    def __init__(self, text: io.TextIOBase, label: str, limit: int) -> None:
        self._text, self._label, self.limit, self.number = text, label, limit, 0

    def __iter__(self) -> Iterator[str]:
        return self

    def __next__(self) -> str:
        line = self._text.readline(self.limit + 1)
        if not line:
            raise StopIteration
        self.number += 1
        if len(line) > self.limit:
            raise RunFileError(f"{self._label}: {CSV_MEMBER} line {self.number} is longer "
                               f"than {self.limit} characters (it starts "
                               f"{clip(line, 60)}); the file was edited or damaged")
        return line


def _signals(data: bytes, member: Member, meta: Mapping[str, Any],
             label: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """t and the signals of signals.csv, parsed as it is unpacked, its header checked
    against run.json, rows × columns bounded before a row is stored."""
    stream = io.BufferedReader(_Chunks(iter_member(data, member, label,
                                                   limit=MAX_UNPACKED_BYTES)), 2**16)
    text = io.TextIOWrapper(stream, encoding="utf-8-sig", newline="")
    lines = _Lines(text, label, MAX_HEADER_CHARS)
    rows = csv.reader(lines)
    try:
        header = next(rows, None)
        if header is None:
            raise RunFileError(f"{label}: {CSV_MEMBER} is empty; the run holds no samples")
        if header != meta["columns"]:
            raise RunFileError(f"{label}: {CSV_MEMBER}'s header disagrees with the columns "
                               f"{JSON_MEMBER} lists; the file was edited or damaged")
        layout = _layout(header, [str(j) for j in meta["joint_names"]], label,
                         known=(*SIGNALS, *CONTACT_SIGNALS, *meta.get("lesson_signals", {})))
        width = len(header)
        lines.limit = width * MAX_CELL_CHARS
        t, signals = _table(rows, header, layout, label)
    except csv.Error as e:
        raise RunFileError(f"{label}: {CSV_MEMBER} is not readable CSV "
                           f"({clip(str(e))})") from None
    except UnicodeDecodeError as e:
        raise RunFileError(f"{label}: {CSV_MEMBER} is not UTF-8 text ({e.reason} at byte "
                           f"{e.start} of a chunk)") from None
    return t, signals


def _table(rows: Iterator[list[str]], header: list[str], layout: Mapping[str, list[int]],
           label: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """t and each signal of the data rows, never past :data:`MAX_CELLS` values: the arrays
    of that bound are made at once but unfilled (their pages cost memory only as rows fill
    them), and a row past it is refused before it is stored."""
    width = len(header)
    most_rows = MAX_CELLS // width
    t = np.empty(most_rows)
    spans = [(cols[0], cols[-1] + 1) for cols in layout.values()]
    arrays = [np.empty((most_rows, b - a)) for a, b in spans]
    fill = list(zip(arrays, spans, strict=True))
    m = 0
    for line, row in enumerate(rows, start=2):
        if len(row) != width:
            if not row:
                raise RunFileError(f"{label}: {CSV_MEMBER} line {line} is blank; every "
                                   "line after the header is one sample")
            raise RunFileError(f"{label}: {CSV_MEMBER} line {line} has {len(row)} "
                               f"cells, the header {width} (ragged rows); the file was "
                               "cut or edited")
        if m == most_rows:
            raise RunFileError(
                f"{label}: {CSV_MEMBER} holds more than {most_rows} rows of {width} "
                f"columns; a run file holds at most {MAX_CELLS} values "
                f"({MAX_CELLS // 2**20} Mi): record a shorter run")
        values = [_number(c, line, header[i], label) for i, c in enumerate(row)]
        t[m] = values[0]
        for array, (a, b) in fill:
            array[m] = values[a:b]
        m += 1
    if m == 0:
        raise RunFileError(f"{label}: {CSV_MEMBER} has a header but no samples")
    return t[:m], {name: array[:m] for name, array in zip(layout, arrays, strict=True)}


def _layout(header: list[str], joints: list[str], label: str, *,
            known: Sequence[str] = SIGNALS) -> dict[str, list[int]]:
    """signal -> its column indices, checking the header is t then each signal's joints
    (``known``: the recorder's signals and the lesson signals run.json declares), or a
    contact signal's one column (named without a joint)."""
    if not header or header[0] != "t":
        raise RunFileError(f"{label}: {CSV_MEMBER}'s first column is not 't' (loop time, s)")
    if not joints:
        raise RunFileError(f"{label}: {JSON_MEMBER} names no joints")
    layout: dict[str, list[int]] = {}
    for i, col in enumerate(header[1:], start=1):
        signal, _, joint = col.partition(".")
        if signal not in known:
            raise RunFileError(f"{label}: column {quote(col)} is no signal this lab knows "
                               f"({', '.join((*SIGNALS, *CONTACT_SIGNALS))}) nor one "
                               "run.json's lesson_signals declares; the file is from another "
                               "program or a newer armlab")
        if signal in CONTACT_SIGNALS:
            if col != signal or signal in layout:
                raise RunFileError(f"{label}: column {quote(col)}: the contact signal "
                                   f"{signal!r} is one column named {signal!r}; the file "
                                   "was edited or damaged")
            layout[signal] = [i]
            continue
        layout.setdefault(signal, []).append(i)
        cols = layout[signal]
        if len(cols) > len(joints) or joint != joints[len(cols) - 1]:
            raise RunFileError(
                f"{label}: column {quote(col)} disagrees with the run's {len(joints)} joints "
                f"({clip(', '.join(joints))}); each signal needs one column "
                "per joint, in order")
    for signal, cols in layout.items():
        if signal in CONTACT_SIGNALS:
            continue
        if len(cols) != len(joints) or cols != list(range(cols[0], cols[0] + len(cols))):
            raise RunFileError(
                f"{label}: signal {quote(signal)} has {len(cols)} columns for "
                f"{len(joints)} joints ({clip(', '.join(joints))}); the file "
                "was edited or damaged")
    return layout


def _number(cell: str, line: int, column: str, label: str) -> float:
    """A cell's value: empty is NaN; refused past :data:`MAX_NUMBER_CHARS` characters
    (before any conversion) or if it is not a number."""
    if cell == "":
        return math.nan
    if len(cell) <= MAX_NUMBER_CHARS:
        try:
            return float(cell)
        except ValueError:
            pass
        why = "is not a number"
    else:
        why = f"is too long: a number is at most {MAX_NUMBER_CHARS} characters"
    raise RunFileError(f"{label}: {CSV_MEMBER} line {line}, column {quote(column, 60)}: "
                       f"{quote(cell, 40)} {why}")
