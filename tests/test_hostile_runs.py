"""Hostile run files (issue 51, "a reader no file can hurt"; docs/runs.md, "What is refused").

Each file is made here, one per kind a review found, and exported by ``armlab export`` in
a child process (tests/_bounded_child.py) whose peak resident memory (VmHWM) and CPU time
are checked against the stated bounds (``armlab.control.run_read.MEMORY_BOUND_MIB``,
``CPU_BOUND_S``): each is refused with its one line (exit status 2, no traceback), or
read and exported. The longest run the lab saves is measured the same way: the bound is
about twice its peak.
"""

from __future__ import annotations

import bz2
import io
import json
import lzma
import math
import os
import resource
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest

from armlab.app.export.charts import MAX_TICKS, nice_ticks
from armlab.app.export.html import export_html
from armlab.control.recorder import SIGNALS
from armlab.control.run_read import CPU_BOUND_S, MEMORY_BOUND_MIB
from armlab.control.runs import (
    MAX_CELLS,
    MAX_JSON_VALUES,
    MAX_MEMBERS,
    Run,
    RunFileError,
    read_run,
    run_bytes,
    write_run,
)
from armlab.kinematics import load_robot

TESTS = Path(__file__).parent
CHILD = TESTS / "_bounded_child.py"
ROBOT = "receptionist_arm"
MODEL = load_robot(ROBOT)
#: Wall time a child may take before it is taken for looping (two shared cores).
WALL_S = 240.0
#: The longest run the lab saves: the compliance lesson's 30 s window at its shortest
#: period (1 ms), every recorder signal of its three joints.
LONGEST_S, LONGEST_PERIOD = 30.0, 0.001


# ------------------------------------------------------------------------- the child


def export_in_child(tmp_path: Path, data: bytes, name: str = "hostile") -> tuple[int, str, dict]:
    """``armlab export`` of ``data`` in a child process: (exit status, stderr, its cost:
    ``peak_kib``, ``cpu_s``). The child's address space is capped far above the bound (a
    runaway allocation fails there instead of taking the machine)."""
    path = tmp_path / f"{name}.armlab-run.zip"
    path.write_bytes(data)
    stats = tmp_path / f"{name}.json"
    cap = 8 * 2**30

    def limits() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        resource.setrlimit(resource.RLIMIT_CPU, (int(CPU_BOUND_S) + 30, int(CPU_BOUND_S) + 30))

    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, str(CHILD), str(stats), "export", str(path),
                           "--html", str(tmp_path / f"{name}.html")],
                          capture_output=True, text=True, timeout=WALL_S, env=env,
                          preexec_fn=limits, check=False)
    cost = json.loads(stats.read_text()) if stats.exists() else {}
    return proc.returncode, proc.stderr, cost


def assert_within_bounds(cost: dict, stderr: str) -> None:
    assert "Traceback" not in stderr, stderr[-3000:]
    assert cost, f"the child wrote no cost: {stderr[-2000:]}"
    assert cost["peak_kib"] / 1024 <= MEMORY_BOUND_MIB, cost
    assert cost["cpu_s"] <= CPU_BOUND_S, cost


def assert_refused(tmp_path: Path, data: bytes, says: str) -> dict:
    """``data`` refused by ``armlab export`` with one line holding ``says``, within the
    bounds; returns the cost."""
    code, stderr, cost = export_in_child(tmp_path, data)
    assert_within_bounds(cost, stderr)
    assert code == 2, stderr
    assert stderr.startswith("armlab export: ") and stderr.count("\n") == 1, stderr[:2000]
    assert says in stderr, stderr[:2000]
    assert len(stderr) < 700, len(stderr)  # at most ~200 characters of the file's text
    return cost


# ------------------------------------------------------------------------- files


def good_run(m: int = 200, **over) -> Run:
    t = over.pop("t", np.arange(m) * 0.016)
    q = 0.3 * np.sin(np.outer(np.arange(len(t)) * 0.016, [1.0, 2.0, 3.0]))
    fields = dict(robot=ROBOT, joint_names=MODEL.joint_names, source="test:hostile",
                  lab_version="0.1.0", created="2026-12-01T00:00:00Z",
                  params={"kp": 20.0, "kv": 5.0}, figures={"overshoot_pct": 3.0},
                  commands=({"t": 0.1, "kind": "RunTrajectory"},), t=t,
                  signals={"q": q, "q_cmd": q + 0.01}, extra={})
    fields.update(over)
    return Run(**fields)


def good_members() -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(run_bytes(good_run()))) as zf:
        return {i.filename: zf.read(i) for i in zf.infolist()}


def good_meta() -> dict:
    return json.loads(good_members()["run.json"])


def deflate(data: bytes) -> bytes:
    c = zlib.compressobj(6, zlib.DEFLATED, -15)
    return c.compress(data) + c.flush()


def repeated_deflate(block: bytes, times: int) -> tuple[bytes, int]:
    """``block`` repeated ``times`` times, deflated (one block's work: each fully flushed
    block compresses alike), and the CRC of the whole."""
    c = zlib.compressobj(1, zlib.DEFLATED, -15)
    packed = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    crc = 0
    for _ in range(times):
        crc = zlib.crc32(block, crc)
    return packed * times + c.flush(), crc


def raw_zip(members: list[tuple[bytes, bytes, int, int, int]], *, end=None) -> bytes:
    """A zip written by hand: members (name, packed bytes, method, declared size, crc);
    ``end(count, directory size, directory offset)`` gives the end record (default the
    true one)."""
    local, central = b"", b""
    for name, packed, method, size, crc in members:
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, method, 0, 0,
                               crc, len(packed), size, len(name), 0, 0, 0, 0, 0,
                               len(local)) + name
        local += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, method, 0, 0, crc,
                             len(packed), size, len(name), 0) + name + packed
    make = end or (lambda n, size, at: struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, n, n,
                                                   size, at, 0))
    return local + central + make(len(members), len(central), len(local))


def with_members(**replace: bytes) -> bytes:
    """A good run file, members replaced (deflated, true sizes)."""
    items = good_members()
    items.update({k.replace("_", "."): v for k, v in replace.items()})
    return raw_zip([(n.encode(), deflate(d), 8, len(d), zlib.crc32(d))
                    for n, d in items.items()])


def run_json_with(edit) -> bytes:
    meta = good_meta()
    edit(meta)
    return with_members(run_json=json.dumps(meta).encode())


def run_json_text(edit) -> bytes:
    return with_members(run_json=edit(json.dumps(good_meta())).encode())


def csv_of(rows: list[list[float]] | str, meta: dict | None = None) -> bytes:
    meta = meta or good_meta()
    body = rows if isinstance(rows, str) else "".join(
        ",".join(repr(v) for v in row) + "\n" for row in rows)
    return (",".join(meta["columns"]) + "\n" + body).encode()


def bzip2_bomb() -> bytes:
    """signals.csv packed with bzip2: 64 MiB of zeros in 79 bytes, its header declaring
    1000 (zipfile unpacks bzip2 in one step, whatever the header says)."""
    packed = bz2.compress(bytes(64 * 2**20))
    assert len(packed) < 800
    items = good_members()
    return raw_zip([(b"run.json", deflate(items["run.json"]), 8, len(items["run.json"]),
                     zlib.crc32(items["run.json"])),
                    (b"signals.csv", packed, 12, 1000, 0)])


def lzma_member() -> bytes:
    packed = lzma.compress(bytes(8 * 2**20), format=lzma.FORMAT_ALONE)
    items = good_members()
    return raw_zip([(b"run.json", deflate(items["run.json"]), 8, len(items["run.json"]),
                     zlib.crc32(items["run.json"])),
                    (b"signals.csv", packed, 14, 1000, 0)])


def _million_entries(count: int) -> tuple[bytes, bytes]:
    """(one empty member "a", a central directory of ``count`` entries of it: 47 bytes
    each)."""
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 0, 0, 0, 0, 0, 0, 1, 0) + b"a"
    one = struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 0, 0, 0, 0, 0, 0, 1, 0,
                      0, 0, 0, 0, 0) + b"a"
    return local, one * count


def zip64_million() -> bytes:
    """A ZIP64 end record listing 1.2 million members (and a directory of them)."""
    local, central = _million_entries(1_200_000)
    end64_at = len(local) + len(central)
    end64 = struct.pack("<IQHHIIQQQQ", 0x06064B50, 44, 45, 45, 0, 0, 1_200_000, 1_200_000,
                        len(central), len(local))
    locator = struct.pack("<IIQI", 0x07064B50, 0, end64_at, 1)
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF,
                      0xFFFFFFFF, 0xFFFFFFFF, 0)
    data = local + central + end64 + locator + end
    assert len(data) < 64 * 2**20
    return data


def bent_disks() -> bytes:
    """1.2 million members, the end record claiming 2 on this disk out of 2 on a second
    disk, and a directory of 200 bytes (what zipfile lets pass to list them all)."""
    local, central = _million_entries(1_200_000)
    end = struct.pack("<IHHHHIIH", 0x06054B50, 1, 1, 2, 2, 200, len(local), 0)
    return local + central + end


def small_claim() -> bytes:
    """1.2 million members, the end record claiming 2 in a directory of 200 bytes."""
    local, central = _million_entries(1_200_000)
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 2, 2, 200, len(local), 0)
    return local + central + end


def long_integer(where: str) -> bytes:
    digits = "1" * 4000
    edits = {
        "gain": lambda s: s.replace('"kp": 20.0', f'"kp": {digits}'),
        "figure": lambda s: s.replace('"overshoot_pct": 3.0', f'"overshoot_pct": {digits}'),
        "command time": lambda s: s.replace('"t": 0.1', f'"t": {digits}'),
    }
    return run_json_text(edits[where])


def many_joints_newlines() -> bytes:
    """5000 joints and a million newlines in about 1 MB."""
    meta = good_meta()
    joints = [f"j{i}" for i in range(5000)]
    meta["joint_names"] = joints
    meta["columns"] = ["t"] + [f"q.{j}" for j in joints]
    meta["units"] = {"t": "s", "q": "rad"}
    csv_text = (",".join(meta["columns"]) + "\n" + "\n" * 1_000_000).encode()
    data = with_members(run_json=json.dumps(meta).encode(), signals_csv=csv_text)
    assert len(data) < 1_500_000
    return data


def newlines_only() -> bytes:
    """The good run's header, then a million newlines."""
    return with_members(signals_csv=csv_of("\n" * 1_000_000))


def rows_past_the_limit() -> bytes:
    """250 MiB of good rows (t and q of three joints) deflated to about 47 MiB: the
    documented 256 MiB a member may unpack to, far past the values a run may hold."""
    meta = good_meta()
    meta["columns"] = ["t"] + [f"q.{j}" for j in MODEL.joint_names]
    meta["units"] = {"t": "s", "q": "rad"}
    rng = np.random.default_rng(5)
    rows = 2**20 // 20
    block_rows = np.column_stack([np.arange(rows) * 0.25,
                                  rng.integers(-2, 3, size=(rows, 3)) / 4])
    block = "".join(",".join(repr(v) for v in r) + "\n" for r in block_rows.tolist()).encode()
    times = 250 * 2**20 // len(block)
    header = (",".join(meta["columns"]) + "\n").encode()
    c = zlib.compressobj(6, zlib.DEFLATED, -15)
    head = c.compress(header) + c.flush(zlib.Z_FULL_FLUSH)
    body = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    packed = head + body * times + c.flush()
    crc = zlib.crc32(header)
    for _ in range(times):
        crc = zlib.crc32(block, crc)
    size = len(header) + len(block) * times
    assert size > 240 * 2**20 and len(packed) < 64 * 2**20
    meta_bytes = json.dumps(meta).encode()
    return raw_zip([(b"run.json", deflate(meta_bytes), 8, len(meta_bytes),
                     zlib.crc32(meta_bytes)),
                    (b"signals.csv", packed, 8, size, crc)])


def huge_times() -> bytes:
    meta = good_meta()
    rows = [[2.0**53 + 2 * i] + [0.1] * (len(meta["columns"]) - 1) for i in range(2)]
    return with_members(signals_csv=csv_of(rows, meta))


def huge_angle() -> bytes:
    meta = good_meta()
    rows = [[0.016 * i] + [1e308 if i == 3 else 0.1] * (len(meta["columns"]) - 1)
            for i in range(10)]
    return with_members(signals_csv=csv_of(rows, meta))


def long_string(field: str) -> bytes:
    """run.json with 2 MB of random letters in ``field`` (they do not compress 200:1)."""
    letters = np.random.default_rng(3).integers(97, 123, 2_000_000, dtype=np.uint8)
    return run_json_with(lambda d: d.update({field: letters.tobytes().decode()}))


def nul_name() -> bytes:
    items = good_members()
    out = [(n.encode(), deflate(d), 8, len(d), zlib.crc32(d)) for n, d in items.items()]
    out.append((b"signals.csv\x00.exe", deflate(b"x"), 8, 1, zlib.crc32(b"x")))
    return raw_zip(out)


def long_name() -> bytes:
    items = good_members()
    out = [(n.encode(), deflate(d), 8, len(d), zlib.crc32(d)) for n, d in items.items()]
    out.append((b"a" * 300, deflate(b"x"), 8, 1, zlib.crc32(b"x")))
    return raw_zip(out)


def long_cell(digits: int) -> bytes:
    """signals.csv whose third row's first q_cmd cell is a number of ``digits`` digits."""
    meta = good_meta()
    width = len(meta["columns"]) - 1
    rows = "".join(f"{0.016 * i!r}," + ",".join(
        ["1" * digits if i == 2 and k == 0 else "0.1" for k in range(width)]) + "\n"
        for i in range(5))
    return with_members(signals_csv=csv_of(rows, meta))


def data_descriptor_lie() -> bytes:
    """signals.csv with a data descriptor: its directory declares 1000 bytes, its stream
    unpacks to 8 MiB."""
    items = good_members()
    packed, _ = repeated_deflate(b"0," * 2**19, 8)
    name = b"signals.csv"
    json_data = items["run.json"]
    jpacked = deflate(json_data)
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0, zlib.crc32(json_data),
                        len(jpacked), len(json_data), 8, 0) + b"run.json" + jpacked
    at = len(local)
    local += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 8, 8, 0, 0, 0, 0, 0, len(name),
                         0) + name + packed + struct.pack("<IIII", 0x08074B50, 0,
                                                          len(packed), 1000)
    central = struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0,
                          zlib.crc32(json_data), len(jpacked), len(json_data), 8, 0, 0, 0,
                          0, 0, 0) + b"run.json"
    central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 8, 8, 0, 0, 0,
                           len(packed), 1000, len(name), 0, 0, 0, 0, 0, at) + name
    return local + central + struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 2, 2, len(central),
                                         len(local), 0)


def stored_run_json(meta: dict) -> bytes:
    """A run file whose run.json is ``meta``, stored (not deflated: no ratio to refuse)."""
    text = json.dumps(meta, separators=(",", ":")).encode()
    csv_data = good_members()["signals.csv"]
    return raw_zip([(b"run.json", text, 0, len(text), zlib.crc32(text)),
                    (b"signals.csv", deflate(csv_data), 8, len(csv_data),
                     zlib.crc32(csv_data))])


def many_json_values() -> bytes:
    """run.json of a million empty objects in 3 MiB: 300 MiB once parsed."""
    meta = good_meta()
    meta["junk"] = [{}] * 1_000_000
    return stored_run_json(meta)


# (case, how to make it, what its one line says)
HOSTILE = [
    ("bzip2 member", bzip2_bomb, "'signals.csv' is packed with bzip2; run files hold only "
     "stored or deflated members"),
    ("LZMA member", lzma_member, "is packed with LZMA"),
    ("ZIP64 end record of 1.2 M members", zip64_million,
     "lists 1200000 members in a 56400000-byte directory; a run file holds two"),
    ("end record with bent disk fields", bent_disks, "one part of a zip split over several"),
    ("end record claiming 2 members", small_claim, "truncated or damaged"),
    ("4000-digit integer in a gain", lambda: long_integer("gain"),
     "a number of 4000 characters"),
    ("4000-digit integer in a figure", lambda: long_integer("figure"),
     "a number of 4000 characters"),
    ("4000-digit integer in a command's time", lambda: long_integer("command time"),
     "a number of 4000 characters"),
    ("5000 joints and a million newlines", many_joints_newlines,
     "joint_names must be 1 to 64 texts"),
    ("a million newlines", newlines_only, "signals.csv line 2 is blank"),
    ("250 MiB of rows in 47 MiB", rows_past_the_limit,
     f"holds more than {MAX_CELLS // 4} rows of 4 columns"),
    ("times of 2^53 and 2^53 + 2", huge_times, "t is 9007199254740992.0 s at sample 0, "
     "beyond the 1e+09 s"),
    ("q = 1e308", huge_angle, "is 1e+308 rad at sample 3, joint 'theta1', beyond the 1e+06"),
    ("2 MB string in the format", lambda: long_string("format"),
     "is not an armlab run (its format is '"),
    ("2 MB string in the robot", lambda: long_string("robot"), "the robot is not named"),
    ("a member name with a NUL", nul_name, "'signals.csv\\x00.exe', with a NUL"),
    ("a member name of 300 bytes", long_name, "a member named with 300 bytes"),
    ("a 200-digit number in a cell", lambda: long_cell(200),
     "signals.csv line 4, column 'q_cmd.theta1': '1111"),
    ("a 4000-digit number in a cell", lambda: long_cell(4000),
     "signals.csv line 4 is longer than 280 characters (it starts 0.032,1111"),
    ("a million values in run.json", many_json_values,
     "run.json holds up to 2000034 values (counted by its commas and brackets)"),
    ("a data descriptor under-declaring", data_descriptor_lie,
     "signals.csv unpacks to more than its declared 1000 bytes"),
]


@pytest.mark.slow
@pytest.mark.parametrize("case,make,says", HOSTILE, ids=[c[0] for c in HOSTILE])
def test_a_hostile_file_is_refused_with_one_line_within_the_bounds(tmp_path, case, make,
                                                                   says):
    assert_refused(tmp_path, make(), says)


@pytest.mark.slow
def test_every_hostile_file_is_refused_in_process_too():
    """The same files through read_run (and export_html, for what it reads), named as
    an upload is: each one RunFileError of one short line; none goes past the reader
    with a crash of another kind."""
    wrong = []
    for case, make, says in HOSTILE:
        if case in ("ZIP64 end record of 1.2 M members", "end record with bent disk fields",
                    "end record claiming 2 members", "250 MiB of rows in 47 MiB"):
            continue  # the slow test above; these take a while to build
        try:
            export_html(read_run(make(), name="upload.zip"), model=MODEL)
        except RunFileError as e:
            message = str(e)
            if "\n" in message or len(message) > 600 or says not in message:
                wrong.append((case, message[:1000]))
        else:
            wrong.append((case, "read and exported"))
    assert not wrong


# ------------------------------------------------------------------------- legitimate


def longest_run() -> Run:
    """The longest run the lab saves (compliance lesson, 30 s at 1 ms, every recorder
    signal of three joints, the 5000 commands a page keeps)."""
    m = int(round(LONGEST_S / LONGEST_PERIOD)) + 1
    rng = np.random.default_rng(1)
    t = 1234.5 + np.arange(m) * LONGEST_PERIOD
    signals = {name: rng.normal(size=(m, MODEL.n)) * 0.3 for name in SIGNALS}
    commands = [{"t": float(t[0] + 0.006 * i), "kind": "RunTrajectory",
                 "trajectory": {"name": "hold", "times": [0.0, 0.5], "q": [[0.1, 0.2, 0.3]] * 2}}
                for i in range(5000)]
    return good_run(t=t, signals=signals, commands=commands,
                    params={"kp": 20.0, "kv": 5.0, "period": LONGEST_PERIOD})


@pytest.mark.slow
def test_the_longest_run_exports_within_half_the_bound(tmp_path):
    """The bound is about twice what the longest legitimate run costs."""
    path = write_run(longest_run(), tmp_path / "longest.armlab-run.zip")
    code, stderr, cost = export_in_child(tmp_path, path.read_bytes(), "longest")
    assert code == 0, stderr
    assert_within_bounds(cost, stderr)
    assert cost["peak_kib"] / 1024 <= MEMORY_BOUND_MIB * 0.6, cost


@pytest.mark.slow
@pytest.mark.parametrize("signals", [("q",), SIGNALS], ids=["t and q", "every signal"])
def test_a_run_of_as_many_values_as_a_file_may_hold_exports_within_the_bound(tmp_path,
                                                                             signals):
    """The most a run may hold (MAX_CELLS values), as few or as many columns as can be."""
    width = 1 + len(signals) * MODEL.n
    m = MAX_CELLS // width
    rng = np.random.default_rng(2)
    run = good_run(t=np.arange(m) * 1e-3,
                   signals={name: rng.normal(size=(m, MODEL.n)) for name in signals})
    path = write_run(run, tmp_path / "most.armlab-run.zip")
    code, stderr, cost = export_in_child(tmp_path, path.read_bytes(), "most")
    assert code == 0, stderr
    assert_within_bounds(cost, stderr)


@pytest.mark.slow
@pytest.mark.parametrize("field", ["params", "figures", "extra"])
def test_a_run_json_of_as_many_values_as_it_may_hold_exports_within_the_bound(tmp_path,
                                                                               field):
    """MAX_JSON_VALUES values (keys of one object) in the field the page lists."""
    meta = good_meta()
    meta[field] = {f"{i:x}": 0 for i in range(MAX_JSON_VALUES - 100)}
    code, stderr, cost = export_in_child(tmp_path, stored_run_json(meta), field)
    assert code == 0, stderr
    assert_within_bounds(cost, stderr)
    html = (tmp_path / f"{field}.html").read_text()
    assert "in the run file" in html and len(html) < 2_000_000  # the rest is counted


def test_a_zip64_member_with_a_data_descriptor_reads_as_before():
    """What other zip tools write (ZIP64 sizes, data descriptors on a stream that cannot
    seek, a stored member) reads exactly as the lab's own file."""
    run = good_run()
    items = good_members()

    class Unseekable(io.RawIOBase):
        def __init__(self) -> None:
            self.buf = bytearray()

        def writable(self) -> bool:
            return True

        def write(self, b) -> int:
            self.buf += b
            return len(b)

    for how in ("zip64", "descriptor", "stored"):
        out = Unseekable() if how == "descriptor" else io.BytesIO()
        with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_STORED if how == "stored"
                             else zipfile.ZIP_DEFLATED) as zf:
            for name, data in items.items():
                with zf.open(name, "w", force_zip64=how == "zip64") as f:
                    f.write(data)
        data = bytes(out.buf) if how == "descriptor" else out.getvalue()
        if how == "descriptor":
            assert struct.pack("<I", 0x08074B50) in data
        got = read_run(data)
        assert np.array_equal(got.t, run.t) and got.params == run.params, how
        assert np.array_equal(got.signals["q"], run.signals["q"]), how


def test_members_past_the_limit_are_counted_from_the_directory_read():
    """An end record claiming 2 members over a directory of 70: refused at the 65th."""
    items = good_members()
    members = [(n.encode(), deflate(d), 8, len(d), zlib.crc32(d)) for n, d in items.items()]
    members += [(f"pad/{i}".encode(), b"", 0, 0, 0) for i in range(68)]

    def claim_two(n: int, size: int, at: int) -> bytes:
        return struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 2, 2, size, at, 0)

    with pytest.raises(RunFileError, match=f"holds more than {MAX_MEMBERS} members"):
        read_run(raw_zip(members, end=claim_two))


# ------------------------------------------------------------------------- the axes


def test_axis_ticks_are_bounded_whatever_the_range():
    started = time.process_time()
    for lo, hi in ((2.0**53, 2.0**53 + 2), (0.0, 1e308), (-1e308, 1e308), (1e300, 1e300 * 2),
                   (5e-324, 1e-323), (0.0, 5e-324), (1.0, math.nextafter(1.0, 2.0))):
        ticks = nice_ticks(lo, hi, count=6)
        assert 1 <= len(ticks) <= MAX_TICKS, (lo, hi, ticks)
        assert len(set(ticks)) == len(ticks)
    assert nice_ticks(0.0, 1.0) == [0.0, 0.5, 1.0]
    assert time.process_time() - started < 1.0


def test_a_run_at_float_spacing_exports_in_process():
    """A run made in Python (not read) whose times are 2⁵³ and 2⁵³ + 2 exports: its axis
    has its two ends as ticks."""
    run = good_run(m=2, t=np.array([2.0**53, 2.0**53 + 2]))
    html = export_html(run, model=MODEL)
    assert "9007199254740992" in html
