"""Run files (armlab.control.runs, docs/runs.md): a round trip gives the identical float64
values, the CSV needs nothing but the csv module, every bad file gets its own message and
nothing is written anywhere while reading, and ``armlab experiment NAME --save-run``
writes what read_run reads back with the experiment's figures."""

import csv
import io
import json
import math
import os
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.control import runs
from armlab.control.recorder import CONTACT_SIGNALS, SIGNALS, Recorder
from armlab.control.runs import (
    MAX_FILE_BYTES,
    Run,
    RunFileError,
    read_run,
    run_bytes,
    run_from_snapshot,
    write_run,
)

JOINTS = ("shoulder", "elbow, left", "wrist")  # a comma: the CSV must quote it


def sample_run(m: int = 50, **over) -> Run:
    """A run whose floats are the hard cases of a decimal round trip."""
    rng = np.random.default_rng(7)
    q = rng.normal(size=(m, 3)) * np.array([1e-12, 1.0, 3e5])
    q[0] = [5e-324, -0.0, np.pi]  # the smallest subnormal, a signed zero
    q[1] = [1.7976931348623157e308, 0.1 + 0.2, -1 / 3]
    err = rng.normal(size=(m, 3))
    err[3, 1] = math.nan  # a missing value in a signal other than q
    err[4, 2] = math.inf
    fields = dict(robot="receptionist_arm", joint_names=JOINTS, source="test:sample",
                  lab_version="0.1.0", created="2026-11-28T03:00:00Z",
                  params={"kp": 20.0, "kv": 5.0, "law": "2.6", "compliance": True},
                  commands=({"t": 0.25, "kind": "RunTrajectory", "name": "line",
                             "q_goal": [0.1, 0.2, 0.3]},),
                  figures={"overshoot_pct": 12.5, "settling_s": None},
                  t=np.arange(m) * 0.016 + 1e-9,
                  signals={"q": q, "q_cmd": q + 1e-3, "error": err},
                  extra={"challenge": {"name": "step", "limits": [10, 1.5]}, "note": "é ✓"})
    fields.update(over)
    return Run(**fields)


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def assert_same_run(a: Run, b: Run) -> None:
    for f in ("robot", "joint_names", "source", "lab_version", "created", "params",
              "commands", "figures", "extra"):
        assert getattr(a, f) == getattr(b, f), f
    assert np.array_equal(bits(a.t), bits(b.t))
    assert list(a.signals) == list(b.signals)
    for name in a.signals:  # bit for bit: -0.0, subnormals and NaN's place included
        assert np.array_equal(bits(a.signals[name]), bits(b.signals[name])), name


def members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {i.filename: zf.read(i) for i in zf.infolist()}


def zip_of(items: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, data in items.items():
            zf.writestr(zipfile.ZipInfo(name), data)
    return buf.getvalue()


def tampered(*, meta=None, csv_text=None, extra_members=None) -> bytes:
    """A good run file with run.json edited by ``meta(dict)`` or signals.csv replaced."""
    items = members(run_bytes(sample_run()))
    if meta is not None:
        doc = json.loads(items["run.json"])
        meta(doc)
        items["run.json"] = json.dumps(doc).encode()
    if csv_text is not None:
        items["signals.csv"] = csv_text(items["signals.csv"].decode()).encode()
    items.update(extra_members or {})
    return zip_of(items)


def csv_cell(text: str, row: int, column: str, value: str) -> str:
    """``text`` with the cell at data row ``row`` of ``column`` set to ``value``."""
    rows = list(csv.reader(io.StringIO(text)))
    rows[1 + row][rows[0].index(column)] = value
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows(rows)
    return out.getvalue()


def raw_zip(name: str, deflated: bytes, *, size: int, crc: int) -> bytes:
    """A one-member zip written by hand, its header declaring ``size`` bytes unpacked."""
    n = name.encode()
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0, crc, len(deflated), size,
                        len(n), 0) + n + deflated
    central = struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0, crc,
                          len(deflated), size, len(n), 0, 0, 0, 0, 0, 0) + n
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 1, 1, len(central), len(local), 0)
    return local + central + end


def zeros_bomb(mib: int) -> tuple[bytes, int]:
    """``mib`` MiB of zeros deflated (about 1 KiB per MiB), and their CRC: small on disk,
    huge unpacked. Fully flushed blocks repeat, so it costs one MiB of compression."""
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    zeros = bytes(2**20)
    block = c.compress(zeros) + c.flush(zlib.Z_FULL_FLUSH)
    crc = 0
    for _ in range(mib):
        crc = zlib.crc32(zeros, crc)
    return block * mib + c.flush(), crc


def listing(*folders: Path) -> set[tuple[str, int]]:
    out = set()
    for folder in folders:
        for root, dirs, files in os.walk(folder):
            for name in dirs + files:
                p = Path(root, name)
                out.add((str(p), p.stat().st_size if p.is_file() else -1))
    return out


# ------------------------------------------------------------------------- round trip


def test_a_round_trip_gives_the_identical_run(tmp_path):
    run = sample_run()
    path = write_run(run, tmp_path / "a.armlab-run.zip")
    assert path == tmp_path / "a.armlab-run.zip"
    assert_same_run(run, read_run(path, robot="receptionist_arm"))
    assert_same_run(run, read_run(run_bytes(run)))
    assert os.listdir(tmp_path) == ["a.armlab-run.zip"]  # no temporary file left


def test_run_from_snapshot_keeps_the_recorded_rows_and_signals():
    rec = Recorder(3, 100, JOINTS)
    rec.append(0.0, {})  # before the first reading: q NaN
    rng = np.random.default_rng(1)
    written = []
    for k in range(1, 21):
        row = {"q": rng.normal(size=3), "q_cmd": rng.normal(size=3),
               "error": rng.normal(size=3)}
        written.append(row)
        rec.append(k * 0.016, row, wall=1e9 + k)
    run = run_from_snapshot(rec.snapshot(), robot="r", joint_names=JOINTS, source="test",
                            params={"kp": 1.0}, figures={"x_deg": 2.0})
    assert list(run.signals) == ["q_cmd", "q", "error"]  # never recorded: left out
    assert np.array_equal(run.t, np.arange(1, 21) * 0.016)
    assert np.array_equal(run.signals["q"], np.array([r["q"] for r in written]))
    assert run.lab_version == runs.lab_version() and run.created.endswith("Z")
    assert_same_run(run, read_run(run_bytes(run)))


def test_the_csv_needs_only_the_csv_module():
    run = sample_run(m=5)
    items = members(run_bytes(run))
    meta = json.loads(items["run.json"])
    rows = list(csv.reader(io.StringIO(items["signals.csv"].decode("utf-8"))))
    assert rows[0] == meta["columns"]
    assert rows[0][:4] == ["t", "q_cmd.shoulder", "q_cmd.elbow, left", "q_cmd.wrist"]
    assert meta["units"] == {"t": "s", "q_cmd": "rad", "q": "rad", "error": "rad"}
    assert len(rows) == 6 and all(len(r) == len(rows[0]) for r in rows)
    col = rows[0].index("q.wrist")
    assert [float(r[col]) for r in rows[1:]] == run.signals["q"][:, 2].tolist()
    assert rows[1][rows[0].index("q.shoulder")] == "5e-324"
    assert rows[4][rows[0].index("error.elbow, left")] == ""  # NaN: an empty cell
    assert rows[5][rows[0].index("error.wrist")] == "inf"


def test_a_csv_saved_again_by_a_spreadsheet_still_reads():
    """CRLF or CR line ends and a byte-order mark, as spreadsheets write them."""
    run = sample_run(m=6)
    items = members(run_bytes(run))
    for text in (items["signals.csv"].replace(b"\n", b"\r\n"),
                 items["signals.csv"].replace(b"\n", b"\r"),
                 b"\xef\xbb\xbf" + items["signals.csv"]):
        assert_same_run(run, read_run(zip_of({**items, "signals.csv": text})))


# ------------------------------------------------------------------------- bad files


def _beside_run_json(bomb: bytes) -> bytes:
    """``bomb`` (a zip of signals.csv) with a good run.json added: the bomb is what fails."""
    buf = io.BytesIO(bomb)
    with zipfile.ZipFile(buf, "a") as zf:
        zf.writestr("run.json", members(run_bytes(sample_run()))["run.json"])
    return buf.getvalue()


def _bomb_by_size() -> bytes:
    data, crc = zeros_bomb(300)
    assert len(data) < 400_000  # small on disk
    return _beside_run_json(raw_zip("signals.csv", data, size=300 * 2**20, crc=crc))


def _bomb_by_ratio() -> bytes:
    data, crc = zeros_bomb(8)
    return _beside_run_json(raw_zip("signals.csv", data, size=8 * 2**20, crc=crc))


def _bomb_lying_about_its_size() -> bytes:
    """Declares 1000 bytes and unpacks to 8 MiB: refused at the first chunk past the 1000
    declared (no more than one chunk is ever unpacked)."""
    data, _ = zeros_bomb(8)
    return _beside_run_json(raw_zip("signals.csv", data, size=1000,
                                    crc=zlib.crc32(bytes(1000))))


def _with_csv(edit):
    return lambda: tampered(csv_text=edit)


def _with_meta(edit):
    return lambda: tampered(meta=edit)


def _truncated() -> bytes:
    data = run_bytes(sample_run())
    return data[: len(data) // 2]


def _missing_csv() -> bytes:
    return zip_of({"run.json": members(run_bytes(sample_run()))["run.json"]})


def _t_back(text: str) -> str:
    return csv_cell(text, 5, "t", "0.0")


def _many_members() -> bytes:
    """A zip whose end record announces 65000 members (the directory itself is left out:
    the count alone is refused, before any member is listed)."""
    good = run_bytes(sample_run())
    at = good.rfind(b"PK\x05\x06")
    return good[:at] + struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 65000, 65000,
                                   46 * 65000, 0, 0)


def _ragged(text: str) -> str:
    lines = text.split("\n")
    lines[3] += ",1.0"
    return "\n".join(lines)


def _wrong_joint_count(doc: dict) -> None:
    doc["joint_names"] = ["shoulder", "elbow, left"]


# (case, how to make it, what its message says)
BAD_FILES = [
    ("not a zip at all", lambda: b"t,q.a\n0,1\n", "not a zip archive"),
    ("a truncated zip", _truncated, "truncated or damaged (its zip directory is missing)"),
    ("another robot", lambda: run_bytes(sample_run(robot="so101")),
     "a run of the robot 'so101'; this lab runs 'receptionist_arm'"),
    ("a newer version", _with_meta(lambda d: d.update(version=runs.VERSION + 1)),
     "written by a newer armlab"),
    ("another format", _with_meta(lambda d: d.update(format="other-run")),
     "is not an armlab run"),
    ("a parent-folder member", lambda: tampered(extra_members={"../escaped.txt": b"x"}),
     "'../escaped.txt', a path that would land outside its folder"),
    ("an absolute member", lambda: tampered(extra_members={"/tmp/escaped.txt": b"x"}),
     "'/tmp/escaped.txt', a path that would land outside its folder"),
    ("a backslash member", lambda: tampered(extra_members={"a\\..\\..\\x.txt": b"x"}),
     "a path that would land outside its folder"),
    ("a drive-letter member", lambda: tampered(extra_members={"C:/x.txt": b"x"}),
     "'C:/x.txt', a path that would land outside its folder"),
    ("a zip bomb (size)", _bomb_by_size, "would unpack to 300.0 MiB, over the 256 MiB"),
    ("a zip bomb (ratio)", _bomb_by_ratio, "the mark of a zip bomb"),
    ("a zip bomb lying about its size", _bomb_lying_about_its_size,
     "signals.csv unpacks to more than its declared 1000 bytes; refused (a forged zip)"),
    ("no signals.csv", _missing_csv, "has no signals.csv"),
    ("a zip of 65000 members", _many_members,
     "lists 65000 members in a 2990000-byte directory; a run file holds two"),
    ("NaN in q", _with_csv(lambda s: csv_cell(s, 7, "q.elbow, left", "nan")),
     "q (the measured angles) is NaN or infinite at sample 7"),
    ("an empty cell in q", _with_csv(lambda s: csv_cell(s, 9, "q.wrist", "")),
     "q (the measured angles) is NaN or infinite at sample 9"),
    ("NaN in t", _with_csv(lambda s: csv_cell(s, 2, "t", "nan")),
     "t is NaN or infinite at sample 2"),
    ("t going back", _with_csv(_t_back), "t does not increase at sample 5"),
    ("a ragged row", _with_csv(_ragged), "line 4 has 11 cells, the header 10 (ragged rows)"),
    ("a word for a number", _with_csv(lambda s: csv_cell(s, 0, "q.shoulder", "oops")),
     "'oops' is not a number"),
    ("no samples", _with_csv(lambda s: s.split("\n")[0] + "\n"), "has a header but no samples"),
    ("a joint count disagreeing", _with_meta(_wrong_joint_count),
     "column 'q_cmd.wrist' disagrees with the run's 2 joints"),
    ("run.json not JSON", lambda: tampered(extra_members={"run.json": b"{nope"}),
     "run.json is not valid JSON"),
    ("NaN in run.json", lambda: tampered(extra_members={
        "run.json": members(run_bytes(sample_run()))["run.json"].replace(
            b'"kp": 20.0', b'"kp": NaN')}), "run.json is not valid JSON (NaN is not allowed"),
]


@pytest.mark.parametrize("case,make,says", BAD_FILES, ids=[c[0] for c in BAD_FILES])
def test_each_bad_file_is_refused_with_its_message(tmp_path, monkeypatch, case, make, says):
    """Refused from a path and from bytes alike, writing nothing anywhere: not in the
    file's folder, not in its parent (where "../" points), not in the working folder."""
    data = make()
    inner = tmp_path / "in"
    inner.mkdir()
    path = inner / "bad.armlab-run.zip"
    path.write_bytes(data)
    monkeypatch.chdir(inner)
    before = listing(tmp_path)
    with pytest.raises(RunFileError) as from_path:
        read_run(path, robot="receptionist_arm")
    with pytest.raises(RunFileError) as from_bytes:
        read_run(data, robot="receptionist_arm", name="upload.zip")
    assert says in str(from_path.value)
    assert str(from_path.value).startswith(str(path))
    assert str(from_bytes.value).startswith("upload.zip")
    assert "\n" not in str(from_path.value)
    assert listing(tmp_path) == before
    assert not Path("/tmp/escaped.txt").exists()


def test_every_bad_file_has_a_message_of_its_own():
    said = set()
    for _case, make, _says in BAD_FILES:
        with pytest.raises(RunFileError) as e:
            read_run(make(), robot="receptionist_arm", name="f")
        said.add(str(e.value))
    assert len(said) == len(BAD_FILES)


def test_a_file_over_the_limit_is_refused_unopened(tmp_path):
    path = tmp_path / "huge.armlab-run.zip"
    with path.open("wb") as f:  # sparse: no disk used
        f.truncate(MAX_FILE_BYTES + 1)
    with pytest.raises(RunFileError, match="is 64.0 MiB; a run file may be at most 64 MiB"):
        read_run(path)
    with pytest.raises(RunFileError, match="at most 64 MiB"):
        read_run(bytes(MAX_FILE_BYTES + 1))


def test_a_missing_file_and_a_folder_are_refused(tmp_path):
    with pytest.raises(RunFileError, match="no such file"):
        read_run(tmp_path / "nope.zip")
    with pytest.raises(RunFileError, match="is a folder, not a run file"):
        read_run(tmp_path)


def test_other_members_are_ignored():
    data = tampered(extra_members={"notes/readme.txt": b"hello", "plot.png": b"\x89PNG"})
    assert_same_run(sample_run(), read_run(data))


# ------------------------------------------------------------------------- writing


def test_an_unwritable_path_is_refused_and_nothing_is_written(tmp_path):
    run = sample_run()
    a_file = tmp_path / "file"
    a_file.write_text("x")
    for target, says in ((tmp_path / "no" / "r.zip", "does not exist"),
                         (a_file / "r.zip", "does not exist"),
                         (tmp_path, "it is a folder")):
        with pytest.raises(RunFileError, match=says):
            write_run(run, target)
    assert os.listdir(tmp_path) == ["file"]


def test_an_invalid_run_is_refused_and_the_old_file_kept(tmp_path):
    path = write_run(sample_run(), tmp_path / "r.zip")
    old = path.read_bytes()
    q = sample_run().signals["q"].copy()
    q[3, 0] = math.nan
    bad = [sample_run(signals={"q": q}),
           sample_run(signals={"q_cmd": q}),
           sample_run(signals={"q": q[:, :2]}),
           sample_run(signals={"q": sample_run().signals["q"], "speed": q}),
           sample_run(params={"kp": math.inf}),
           sample_run(extra={"x": math.nan}),
           sample_run(t=np.zeros(50))]
    said = set()
    for run in bad:
        with pytest.raises(RunFileError) as e:
            write_run(run, path)
        said.add(str(e.value))
    assert len(said) == len(bad)
    assert path.read_bytes() == old and os.listdir(tmp_path) == ["r.zip"]


# ------------------------------------------------------------------------- experiments

#: Each experiment, with options that keep it quick, and the signals its run file holds.
EXPERIMENT_RUNS = {
    "thesis-line": (["--push", "3"], "receptionist_arm", set(SIGNALS)),
    "step": (["--kp", "20", "--kv", "5", "--period", "0.01"], "ideal_joint",
             {"q_cmd", "q", "error"}),
    "seed002-circle": ([], "redundant_planar", {"q"}),
    "seed003-gait": (["--cycles", "0.5"], "quadruped", {"q_cmd", "q"}),
    "seed004-table": ([], "planar_servo_arm", {"q_cmd", "q"}),
    "hand-grip": (["--duration", "0.5"], "hand", {"q", "voltage", "current", "force",
                                                   "estimate"}),
    "observers": ([], "torque_joint", {"q", "tau_ext"}),
    "thesis-readings": (["--reading", "SI"], "receptionist_arm", set(SIGNALS)),
    "contact": (["--controller", "compliance"], "receptionist_arm",
                set(SIGNALS) | set(CONTACT_SIGNALS)),
    "contact-sweep": (["--stiffness", "2e4", "--periods-ms", "16"], "receptionist_arm",
                      set(SIGNALS) | set(CONTACT_SIGNALS)),
    "contact-compare": ([], "receptionist_arm", set(SIGNALS) | set(CONTACT_SIGNALS)),
}


def test_every_experiment_is_covered():
    from armlab.control.experiments import all_experiments

    assert set(EXPERIMENT_RUNS) == set(all_experiments())


@pytest.mark.parametrize("name", sorted(EXPERIMENT_RUNS))
@pytest.mark.slow
def test_save_run_writes_what_read_run_reads_with_the_figures(tmp_path, capsys, name):
    argv, robot, signals = EXPERIMENT_RUNS[name]
    path = tmp_path / f"{name}.armlab-run.zip"
    assert main(["experiment", name, *argv, "--json", "--save-run", str(path)]) == 0
    out = capsys.readouterr()
    result = json.loads(out.out)  # stdout stays the JSON alone
    assert f"saved the run to {path}" in out.err
    run = read_run(path, robot=robot)
    assert run.source == f"experiment:{name}"
    assert set(run.signals) == signals
    assert json.loads(json.dumps(result, allow_nan=True).replace("Infinity", "null")
                      ) == run.extra["result"]
    for key, value in result.items():  # its numbers are the figures
        if isinstance(value, float) and math.isfinite(value):
            assert run.figures[key] == value
    assert os.listdir(tmp_path) == [path.name]


@pytest.mark.slow
def test_thesis_line_run_holds_the_loop_record_bit_for_bit(tmp_path):
    """The file's poses are the loop's own recording, not a copy rounded on the way."""
    from armlab.app.commands.cli import build_parser
    from armlab.app.commands.experiment import FACTORIES, experiment_run, options_of
    from armlab.control.experiments import all_experiments

    exp = all_experiments()["thesis-line"]
    args = build_parser(["experiment", "thesis-line"]).parse_args(
        ["experiment", "thesis-line", "--push", "3"])
    options = options_of(exp, args)
    kept: list[Run] = []
    result = exp.run(options, keep=kept.append,
                     backend_factory=FACTORIES["backend_factory"](options))
    assert len(kept) == 2  # the free run and the pushed one; the file holds the last
    run = experiment_run(exp, options, result, exp.rows(result), kept)
    back = read_run(write_run(run, tmp_path / "line.zip"))
    assert_same_run(run, back)
    assert back.extra["pushed"] is True
    assert [c["kind"] for c in back.commands] == ["RunTrajectory", "Push"]
    assert back.figures["max_angle_error_pushed_deg.theta2"] == \
        result["max_angle_error_pushed_deg"][2]
    # the figure is the file's own series: max |θ_cmd − θ| while pushed, theta2
    on = (back.t >= back.extra["line_start_s"]) & (back.t <= back.commands[1]["t"] + 1.5)
    assert math.degrees(np.nanmax(np.abs(back.signals["error"][on, 2]))) == \
        pytest.approx(result["max_angle_error_pushed_deg"][2], abs=2e-3)


def test_save_run_to_an_unwritable_path_is_one_line_and_writes_nothing(tmp_path, capsys):
    target = tmp_path / "missing" / "r.zip"
    assert main(["experiment", "seed004-table", "--save-run", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("armlab experiment: cannot save the run to") and err.count("\n") == 1
    assert "does not exist" in err
    assert os.listdir(tmp_path) == []


def test_a_zip64_directory_is_counted_too(monkeypatch):
    """The member count of a zip64 end record (what zipfile writes past its limit)."""
    items = members(run_bytes(sample_run()))
    monkeypatch.setattr(zipfile, "ZIP_FILECOUNT_LIMIT", 1)  # zip64 records from 2 members
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in items.items():
            zf.writestr(name, data)
        for i in range(runs.MAX_MEMBERS):
            zf.writestr(f"pad/{i}", b"")
    assert b"PK\x06\x06" in buf.getvalue()
    with pytest.raises(RunFileError, match=f"lists {runs.MAX_MEMBERS + 2} members"):
        read_run(buf.getvalue())
