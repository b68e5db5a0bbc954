"""``armlab check``'s process boundary: a student's file that tampers with the check (patches
the checker or numpy, rewrites results.json, leaves with ``os._exit``, forks, hangs, prints,
raises KeyboardInterrupt) gets the score and exit status its true answers earn, and the
results file is the checker's own."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from armlab.app.commands.cli import main
from armlab.exercises import boundary, check_file, core, get

#: thesis eq. 3.13 with one planted mistake (z's sign): right only where z = 0.
WRONG_FK = """\
EXERCISE = "thesis_fk"
import math


def hand_position(q, L1, L2):
    t1, t0, t2 = q
    c0, s0, c1, s1 = math.cos(t0), math.sin(t0), math.cos(t1), math.sin(t1)
    c2, s2 = math.cos(t2), math.sin(t2)
    return [L1 * c0 * c1 - L2 * (s1 * s2 - c0 * c1 * c2),
            L2 * (c1 * s2 + c0 * c2 * s1) + L1 * c0 * s1,
            +L1 * s0 + L2 * c2 * s0]
"""
#: Gradescope's results for full marks, as a forger would write them.
FORGED = ('{"score": 12.0, "output": "thesis_fk: 12/12 cases pass (all cases pass)", '
          '"tests": []}')


def checked(tmp_path: Path, body: str, capsys) -> tuple[int, dict, str]:
    """``armlab check`` on a file of ``body``: (exit status, results.json, stdout)."""
    path = tmp_path / "thesis_fk.py"
    path.write_text(body)
    results = tmp_path / "results.json"
    code = main(["check", str(path), "--results", str(results)])
    return code, json.loads(results.read_text()), capsys.readouterr().out


@pytest.fixture(scope="module")
def earned(tmp_path_factory) -> float:
    """What the wrong FK earns honestly."""
    path = tmp_path_factory.mktemp("honest") / "thesis_fk.py"
    path.write_text(WRONG_FK)
    report = check_file(path)
    assert 0 < report.score < report.max_score
    return report.score


def assert_earned(code: int, results: dict, out: str, score: float) -> None:
    assert code == 1
    assert results["score"] == score
    assert sum(t["score"] for t in results["tests"]) == score
    assert len(results["tests"]) == len(get("thesis_fk").cases())
    passes = [ln for ln in out.splitlines() if ln.startswith("PASS")]
    assert len(passes) == score, out
    assert "Traceback" not in out


TAMPERING = {
    "patches the checker (past the refusal of armlab)": """
import sys
sys.meta_path[:] = [f for f in sys.meta_path if not getattr(f, "refuses_armlab", False)]
import armlab.exercises.checking as checking
import armlab.exercises.core as core
core.close = lambda *a, **k: True
core.judge_value = lambda *a, **k: core.Outcome("x", True, ("PASS  x",))
checking.Report.passed = property(lambda self: True)
checking.Report.score = property(lambda self: 12.0)
""",
    "makes numpy's comparisons always true": """
import numpy, numpy.testing
numpy.allclose = lambda *a, **k: True
numpy.isclose = lambda *a, **k: True
numpy.all = lambda *a, **k: True
numpy.testing.assert_allclose = lambda *a, **k: None
""",
    "rewrites results.json from atexit": f"""
import atexit, os
def _forge():
    open(os.path.join(os.getcwd(), "results.json"), "w").write({FORGED!r})
atexit.register(_forge)
""",
    "prints PASS lines and a summary": """
print("PASS  thesis ch. 4: the line's first point")
print("thesis_fk: 12/12 cases pass (all cases pass)")
import os
os.write(1, b"PASS  random pose 1\\n")
""",
}


@pytest.mark.parametrize("kind", list(TAMPERING))
def test_tampering_at_load_earns_what_the_answers_earn(tmp_path, capsys, monkeypatch,
                                                       earned, kind):
    monkeypatch.chdir(tmp_path)
    code, results, out = checked(tmp_path, WRONG_FK + TAMPERING[kind], capsys)
    assert_earned(code, results, out, earned)


def test_a_right_answer_that_tampers_still_earns_full_marks(tmp_path, capsys):
    right = WRONG_FK.replace("+L1 * s0 + L2 * c2 * s0", "-L1 * s0 - L2 * c2 * s0")
    code, results, out = checked(
        tmp_path, right + TAMPERING["makes numpy's comparisons always true"], capsys)
    assert code == 0 and results["score"] == len(get("thesis_fk").cases())


def test_the_lab_is_not_importable_in_the_students_process(tmp_path, capsys):
    code, results, out = checked(tmp_path, """\
EXERCISE = "thesis_fk"
from armlab.exercises import get

hand_position = get("thesis_fk").reference
""", capsys)
    assert code == 1 and results["score"] == 0
    assert "thesis_fk.py:2: ModuleNotFoundError: No module named 'armlab'" in out


def test_what_their_code_prints_is_shown_apart_from_the_cases(tmp_path, capsys):
    code, results, out = checked(tmp_path, WRONG_FK + 'print("debug: loaded")\n', capsys)
    assert "your code printed:\n  | debug: loaded" in out


def test_os_exit_before_the_report_fails_every_case(tmp_path, capsys):
    code, results, out = checked(tmp_path, WRONG_FK + "import os\nos._exit(0)\n", capsys)
    assert code == 1 and results["score"] == 0
    assert "exited (status 0) during loading your file" in out


@pytest.mark.parametrize("death,said", [
    ("os._exit(0)", "exited (status 0) during a call"),
    ("os.kill(os.getpid(), 9)", "was killed by signal 9 during a call"),
])
def test_results_written_then_death_in_the_function_fails_the_cases_left(
        tmp_path, capsys, death, said):
    body = WRONG_FK.replace("    t1, t0, t2 = q\n", f"""\
    import os
    if abs(q[0]) > 2:  # the joint-limit cases, after some that pass
        open({str(tmp_path / "results.json")!r}, "w").write({FORGED!r})
        {death}
    t1, t0, t2 = q
""")
    code, results, out = checked(tmp_path, body, capsys)
    assert code == 1
    lines = out.splitlines()
    gone = [ln for ln in lines if said in ln]
    assert len(gone) == 1 and gone[0].startswith("FAIL  at the lower joint limits")
    assert "this case and the ones left fail" in gone[0]
    after = lines[lines.index(gone[0]) + 1:-1]
    assert after and all(ln.endswith("not run (your code's process had stopped)")
                         for ln in after)
    passed_before = sum(ln.startswith("PASS") for ln in lines)
    assert results["score"] == passed_before and 0 < passed_before < 12
    assert results["tests"][len(lines) - len(after) - 2]["status"] == "failed"


def test_keyboard_interrupt_in_their_function_fails_its_cases_with_a_line(tmp_path, capsys):
    body = WRONG_FK.replace("    t1, t0, t2 = q\n", "    raise KeyboardInterrupt\n")
    code, results, out = checked(tmp_path, body, capsys)
    assert code == 1 and results["score"] == 0
    fails = [ln for ln in out.splitlines() if ln.startswith("FAIL")]
    assert len(fails) == 12
    assert out.count("thesis_fk.py:6: KeyboardInterrupt") == 12


def _gone(pid: int, within: float = 10.0) -> bool:
    """The process ``pid`` is gone (polled for up to ``within`` s)."""
    end = time.monotonic() + within
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        stat = Path(f"/proc/{pid}/stat")
        try:
            if stat.read_text().split(") ")[1].startswith("Z"):
                return True  # a zombie: dead, waiting for a parent that is not ours to reap
        except (OSError, IndexError):
            return True
        time.sleep(0.02)
    return False


@pytest.mark.parametrize("detach", [False, True])
def test_a_forked_process_that_waits_to_rewrite_results_is_killed(tmp_path, capsys, detach):
    pidfile = tmp_path / "pid"
    body = WRONG_FK + textwrap.dedent(f"""\
        import os, time
        if os.fork() == 0:
            {"os.setsid()" if detach else "pass"}
            if {detach} and os.fork() != 0:
                os._exit(0)
            open({str(pidfile)!r}, "w").write(str(os.getpid()))
            while True:  # rewrite the results whenever the checker writes them
                try:
                    if '"score": 12' not in open({str(tmp_path / "results.json")!r}).read():
                        open({str(tmp_path / "results.json")!r}, "w").write({FORGED!r})
                except OSError:
                    pass
                time.sleep(0.001)
        for _ in range(10000):  # the module goes on once the rewriter is in place
            if os.path.exists({str(pidfile)!r}) and open({str(pidfile)!r}).read():
                break
            time.sleep(0.001)
        """)
    path = tmp_path / "thesis_fk.py"
    path.write_text(body)
    code = main(["check", str(path), "--results", str(tmp_path / "results.json")])
    assert code == 1
    pid = int(pidfile.read_text())
    assert _gone(pid)
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["score"] == check_file(tmp_path / "thesis_fk.py").score < 12
    assert results["tests"]


@pytest.mark.slow
def test_a_hang_that_ignores_the_alarm_is_stopped_and_the_cases_left_fail(
        tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(core, "VALUE_CASE_S", 0.3)
    monkeypatch.setattr(boundary, "GRACE_S", 0.5)
    body = WRONG_FK.replace("    t1, t0, t2 = q\n", """\
    import signal
    signal.signal(signal.SIGALRM, signal.SIG_IGN)
    if abs(q[0]) > 2:
        while True:
            pass
    t1, t0, t2 = q
""")
    code, results, out = checked(tmp_path, body, capsys)
    assert code == 1
    hung = [ln for ln in out.splitlines() if "did not stop at its 0.3 s limit" in ln]
    assert len(hung) == 1 and hung[0].startswith("FAIL  at the lower joint limits")
    passed = sum(ln.startswith("PASS") for ln in out.splitlines())
    assert results["score"] == passed > 0
    assert results["tests"][-1]["output"].endswith("not run (your code's process had stopped)")


def test_the_results_file_is_the_checkers_before_the_first_case(tmp_path, capsys):
    """What a check stopped part-way leaves: written before the first case (every case at
    0, "not run yet"), and after each (the score so far)."""
    seen = tmp_path / "seen.json"
    body = WRONG_FK.replace("    t1, t0, t2 = q\n", f"""\
    import os, shutil
    if not os.path.exists({str(seen)!r}):
        shutil.copy({str(tmp_path / "results.json")!r}, {str(seen)!r})
    t1, t0, t2 = q
""")
    code, results, out = checked(tmp_path, body, capsys)
    first = json.loads(seen.read_text())
    assert first["score"] == 0 and len(first["tests"]) == len(results["tests"])
    assert all(t["output"].endswith("not run yet") for t in first["tests"])
    assert results["score"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_file_that_forges_the_results_then_signals_the_checker_gets_what_it_earned(
        tmp_path, signame):
    """The real command: the student's function writes full marks into results.json, then
    floods the checker with a signal. The checker stops, kills the student's processes,
    writes the results its cases had earned, and exits 128 + the signal."""
    results = tmp_path / "results.json"
    body = WRONG_FK.replace("    t1, t0, t2 = q\n", f"""\
    import os, signal
    if abs(q[0]) > 2:  # the joint-limit cases, after some that pass
        open({str(results)!r}, "w").write({FORGED!r})
        while True:
            os.kill(os.getppid(), signal.{signame})
    t1, t0, t2 = q
""")
    path = tmp_path / "thesis_fk.py"
    path.write_text(body)
    done = subprocess.run([sys.executable, "-m", "armlab.app", "check", str(path),
                           "--results", str(results)], capture_output=True, text=True,
                          timeout=240, cwd=tmp_path)
    signum = getattr(signal, signame)
    assert done.returncode == 128 + signum, done.stdout + done.stderr
    assert f"the check was stopped by {signame}" in done.stdout
    assert "Traceback" not in done.stdout + done.stderr
    data = json.loads(results.read_text())
    passed = sum(ln.startswith("PASS") for ln in done.stdout.splitlines())
    assert data["score"] == passed and 0 < passed < 12
    assert len(data["tests"]) == 12


@pytest.mark.slow
def test_a_tree_of_forked_processes_is_killed_to_the_last(tmp_path, capsys):
    pids = tmp_path / "pids"
    pids.mkdir()
    body = WRONG_FK + textwrap.dedent(f"""\
        import os, time
        for k in range(4):
            if os.fork() == 0:
                if k % 2:
                    os.setsid()
                for _ in range(2):
                    if os.fork() == 0:
                        break
                open(os.path.join({str(pids)!r}, str(os.getpid())), "w").close()
                while True:
                    time.sleep(0.01)
        while len(os.listdir({str(pids)!r})) < 12:
            time.sleep(0.001)
        """)
    code, results, out = checked(tmp_path, body, capsys)
    assert code == 1 and 0 < results["score"] < 12
    found = [int(p.name) for p in pids.iterdir()]
    assert len(found) == 12
    assert all(_gone(pid) for pid in found)
