"""``armlab exercise list|start`` and ``armlab check``: what a student and a teacher type."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from test_exercises import LEG_IK

from armlab.app.commands.cli import main
from armlab.exercises import EXERCISES, get


def armlab(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """Run the real ``armlab`` command (as ``python -m armlab.app``)."""
    return subprocess.run([sys.executable, "-m", "armlab.app", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=240)


def test_exercise_list_is_one_line_each_name_first(capsys):
    assert main(["exercise", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(EXERCISES)
    for line, ex in zip(lines, EXERCISES, strict=True):
        assert line.split()[0] == ex.name
        assert ex.title in line
        assert "eq." in line and ("thesis" in line or "seed" in line)


def test_start_writes_the_starter_prints_its_path_and_keeps_existing_work(tmp_path, capsys):
    assert main(["exercise", "start", "rmrc_step", "--dir", str(tmp_path / "hw")]) == 0
    path = tmp_path / "hw" / "rmrc_step.py"
    assert capsys.readouterr().out.strip() == str(path)
    assert "raise NotImplementedError" in path.read_text()
    path.write_text("# my work\n")
    assert main(["exercise", "start", "rmrc_step", "--dir", str(tmp_path / "hw")]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--force" in err and path.read_text() == "# my work\n"
    assert main(["exercise", "start", "rmrc_step", "--dir", str(tmp_path / "hw"),
                 "--force"]) == 0
    assert "raise NotImplementedError" in path.read_text()
    assert capsys.readouterr().out.strip() == str(path)
    assert main(["exercise", "start", "rmrc_step", "--dir", str(tmp_path / "hw"),
                 "--notebook"]) == 0
    nb = tmp_path / "hw" / "rmrc_step.ipynb"
    assert capsys.readouterr().out.strip() == str(nb)
    assert json.loads(nb.read_text())["nbformat"] == 4
    assert main(["exercise", "start", "no_such"]) == 2
    assert "known: thesis_fk" in capsys.readouterr().err


@pytest.mark.slow
def test_check_exit_codes_and_results_file_of_the_real_command(tmp_path):
    started = armlab("exercise", "start", "leg_ik", cwd=tmp_path)
    assert started.returncode == 0 and started.stdout.strip() == "leg_ik.py"
    starter = armlab("check", "leg_ik.py", "--results", "out/results.json", cwd=tmp_path)
    assert starter.returncode == 1
    fails = [ln for ln in starter.stdout.splitlines() if ln.startswith("FAIL  ")]
    cases = get("leg_ik").cases()
    assert len(fails) == len(cases)
    assert "Traceback" not in starter.stdout + starter.stderr
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    assert results["score"] == 0 and len(results["tests"]) == len(cases)

    path = tmp_path / "leg_ik.py"
    path.write_text('EXERCISE = "leg_ik"\n' + LEG_IK)
    done = armlab("check", "leg_ik.py", "--results", "results.json", cwd=tmp_path)
    assert done.returncode == 0, done.stdout
    lines = done.stdout.splitlines()
    assert len(lines) == len(cases) + 1 and all(ln.startswith("PASS  ") for ln in lines[:-1])
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["score"] == len(cases)
    assert all(t["score"] == t["max_score"] == 1.0 for t in results["tests"])

    missing = armlab("check", "nope.py", cwd=tmp_path)
    assert missing.returncode == 2 and "no such file" in missing.stderr


def test_check_reports_the_students_error_not_the_checkers_traceback(tmp_path, capsys):
    path = tmp_path / "mine.py"
    path.write_text(textwrap.dedent("""\
        EXERCISE = "null_space_step"
        import numpy as np


        def joint_rate(J, xdot, grad_w, k_a):
            P = np.eye(3) - np.linalg.pinv(J) @ J
            return np.linalg.pinv(J) @ xdot + P @ grad_w[5] * k_a
        """))
    results = tmp_path / "r.json"
    assert main(["check", str(path), "--results", str(results)]) == 1
    out = capsys.readouterr()
    assert f"{path}:7: IndexError" in out.out
    assert "Traceback" not in out.out + out.err and "armlab/exercises/" not in out.out
    data = json.loads(results.read_text())
    assert data["score"] == 0 and all(f"{path}:" in t["output"] for t in data["tests"])
    # the 2 x 4 case breaks a line earlier, on the 3 x 3 identity
    assert any(f"{path}:6: ValueError" in t["output"] for t in data["tests"])


def test_a_file_that_does_not_load_still_writes_every_test_at_zero(tmp_path, capsys):
    path = tmp_path / "thesis_fk.py"
    path.write_text('EXERCISE = "thesis_fk"\nraise SystemError("oops")\n')
    results = tmp_path / "results.json"
    assert main(["check", str(path), "--results", str(results)]) == 1
    out = capsys.readouterr().out
    assert f"{path}:2: SystemError: oops" in out
    data = json.loads(results.read_text())
    assert data["score"] == 0
    assert len(data["tests"]) == len(get("thesis_fk").cases())
    assert all("not run" in t["output"] and t["max_score"] == 1.0 for t in data["tests"])


@pytest.mark.parametrize("flag", [[], ["--exercise", "jacobian"]])
def test_check_finds_the_exercise_by_its_line_or_by_the_option(tmp_path, capsys, flag):
    path = tmp_path / "homework3.py"
    path.write_text("" if flag else 'EXERCISE = "jacobian"\n')
    path.write_text(path.read_text() + "def hand_jacobian(q, L1, L2):\n    return None\n")
    assert main(["check", str(path), *flag]) == 1
    out = capsys.readouterr().out
    assert "jacobian: 0/" in out and "not numbers" in out
