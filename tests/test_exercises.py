"""Coursework exercises: the lab's own implementation passes every case, the untouched
starter fails every case, planted mistakes fail with their hint, the student's errors are
reported at their file and line, and the Gradescope results match the cases."""

import json
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

import armlab
from armlab.control.params import DEFAULT
from armlab.exercises import EXERCISES, check, check_file, core, get, load_student, write_starter
from armlab.exercises.core import RunCase, ValueCase, judge_run, judge_value
from armlab.exercises.student import StudentError

NAMES = [ex.name for ex in EXERCISES]
MISTAKES = [(ex.name, m.name) for ex in EXERCISES for m in ex.mistakes]


#: The child of ``armlab check`` refuses ``import armlab``; a file can undo the refusal in
#: its own process (docs/teaching.md says so). The reference files below do, on purpose:
#: they are the lab's own implementation, to show that it passes every case.
PAST_THE_REFUSAL = ("import sys\n"
                    "sys.meta_path[:] = [f for f in sys.meta_path "
                    "if not getattr(f, 'refuses_armlab', False)]\n")

#: seed 003's leg IK written by hand, as a student would (numpy and math only).
LEG_IK = """\
import math


def leg_ik(x, y, z, l1, l2):
    t1 = math.atan2(x, y)
    A = (x * x + y * y + z * z - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    A = min(1.0, max(-1.0, A))
    t3 = math.atan2(math.sqrt(max(0.0, 1 - A * A)), A)
    r, h = math.hypot(x, y), -z
    k1, k2 = l1 + l2 * math.cos(t3), l2 * math.sin(t3)
    return t1, math.atan2(h * k1 - r * k2, r * k1 + h * k2), t3
"""


def reference_file(directory: Path, name: str) -> Path:
    """The lab's own implementation of exercise ``name`` wrapped as a student's file."""
    ex = get(name)
    path = directory / f"{name}.py"
    path.write_text(f'EXERCISE = "{name}"\n' + PAST_THE_REFUSAL + textwrap.dedent(f"""\
        from armlab.exercises import get

        _reference = get("{name}").reference


        def {ex.function}(*args, **kwargs):
            return _reference(*args, **kwargs)
        """))
    return path


def student_file(directory: Path, name: str, body: str) -> Path:
    path = directory / f"{name}.py"
    path.write_text(textwrap.dedent(body))
    return path


def line_of(path: Path, text: str) -> int:
    return next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if text in ln)


def test_at_least_eight_exercises_each_with_three_mistakes_and_a_starter():
    assert len(EXERCISES) >= 8
    for ex in EXERCISES:
        assert len(ex.mistakes) >= 3, ex.name
        text = armlab.exercises.starter_text(ex.name)
        assert f"def {ex.function}(" in text and "raise NotImplementedError" in text
        assert "Returns:" in text and "Args:" in text  # units and shapes are stated
        cases = ex.cases()
        assert len(cases) >= 5, ex.name


def test_every_exercise_defined_is_in_the_one_list_once_and_each_starter_is_an_exercise():
    """The catalog's EXERCISES is the one list: an Exercise written in a set but not named
    there, or a starter without its exercise, fails here."""
    from importlib import resources

    from armlab.exercises import control_set, kinematics_set
    from armlab.exercises.core import Exercise

    defined = {id(v) for mod in (kinematics_set, control_set) for v in vars(mod).values()
               if isinstance(v, Exercise)}
    listed = [id(ex) for ex in EXERCISES]
    assert len(set(listed)) == len(listed)
    assert defined == set(listed)
    starters = {f.name.removesuffix(".py") for f in
                resources.files("armlab.exercises").joinpath("starters").iterdir()
                if f.name.endswith(".py") and f.name != "__init__.py"}
    assert starters == {ex.name for ex in EXERCISES}


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.slow
def test_lab_implementation_as_a_student_file_passes_every_case(tmp_path, name):
    report = check_file(reference_file(tmp_path, name))
    assert report.error is None
    assert report.passed, report.text()
    assert report.score == report.max_score == len(report.outcomes)
    assert all(o.lines == (f"PASS  {o.name}",) for o in report.outcomes)


@pytest.mark.parametrize("name", NAMES)
def test_untouched_starter_fails_every_case_with_one_clear_line(tmp_path, name):
    path = write_starter(name, tmp_path)
    raise_line = line_of(path, "raise NotImplementedError")
    report = check_file(path)
    assert report.error is None and not report.passed and report.score == 0
    for o in report.outcomes:
        assert not o.passed
        assert o.lines[0].startswith(f"FAIL  {o.name}: ")
        assert f"{path}:{raise_line}: NotImplementedError" in o.text, o.text
        assert "Traceback" not in o.text


@pytest.mark.parametrize("name,mistake", MISTAKES)
def test_planted_mistake_fails_with_the_hint_that_fits(name, mistake):
    ex = get(name)
    planted = next(m for m in ex.mistakes if m.name == mistake)
    outcomes = [judge_value(ex, c, planted.fn) for c in ex.cases() if isinstance(c, ValueCase)]
    failed = [o for o in outcomes if not o.passed]
    assert failed, f"{name}: the mistake {mistake!r} passes every case"
    hinted = [o for o in failed if f"hint ({mistake}): {planted.hint}" in o.text]
    assert hinted, failed[0].text
    for o in failed:  # a failure names its input, the expected and the returned value
        assert f"{ex.function}(" in o.lines[0]
        assert "got" in o.text or "error: " in o.text


@pytest.mark.parametrize("name,mistake", [("pd_reference", "swapped gains"),
                                          ("compliance_law", "a sign"),
                                          ("environment_impedance", "order of the updates"),
                                          ("disturbance_observer", "the filter's gain"),
                                          ("null_space_step", "a transposed matrix")])
def test_planted_mistake_fails_the_closed_loop_run(name, mistake):
    ex = get(name)
    planted = next(m for m in ex.mistakes if m.name == mistake)
    run = next(c for c in ex.cases() if isinstance(c, RunCase))
    outcome = judge_run(run, planted.fn)
    assert not outcome.passed
    assert "closed loop" in outcome.lines[0]


def test_a_law_right_at_every_single_call_case_still_fails_on_the_arm():
    """Wrong only where the value cases never look (the lab's default gains on 3 joints):
    every one-call case passes, the closed-loop run on the simulated arm does not."""
    from armlab.control.compliance import pd_reference_accel

    def pd_reference_accel_student(kp, kv, q_cmd, qd_cmd, q, qd):
        if (kp, kv) == (DEFAULT.kp, DEFAULT.kv) and np.shape(q) == (3,):
            return pd_reference_accel(kp, 0.5 * kv, q_cmd, qd_cmd, q, qd)
        return pd_reference_accel(kp, kv, q_cmd, qd_cmd, q, qd)

    report = check(pd_reference_accel_student, "pd_reference", quiet=True)
    value = [o for o, c in zip(report.outcomes, get("pd_reference").cases(), strict=True)
             if isinstance(c, ValueCase)]
    assert value and all(o.passed for o in value)
    run = report.outcomes[-1]
    assert not run.passed and "left the lab's own run" in run.text, run.text
    assert not report.passed


def test_exception_in_the_students_code_is_their_file_and_line(tmp_path):
    path = student_file(tmp_path, "thesis_fk", """\
        import numpy as np

        EXERCISE = "thesis_fk"


        def _helper(L1):
            return L1 / 0.0 if L1 > 0.18 else 1 / 0


        def hand_position(q, L1, L2):
            return np.array([_helper(L1), 0.0, 0.0])
        """)
    report = check_file(path)
    bad = line_of(path, "return L1 / 0.0")
    for o in report.outcomes:
        assert not o.passed
        assert f"{path}:{bad}: ZeroDivisionError" in o.text, o.text
        assert "Traceback" not in o.text and "armlab/exercises/core.py" not in o.text


def test_exception_in_the_students_law_during_the_closed_loop_run(tmp_path):
    path = student_file(tmp_path, "pd_reference", """\
        EXERCISE = "pd_reference"


        def pd_reference_accel(kp, kv, q_cmd, qd_cmd, q, qd):
            if kp == 20.0 and getattr(q, "shape", ()) == (3,):  # only in the run
                raise RuntimeError("my law broke on the arm")
            return kp * (q_cmd - q) + kv * (qd_cmd - qd)
        """)
    report = check_file(path)
    run = report.outcomes[-1]
    assert all(o.passed for o in report.outcomes[:-1])
    bad = line_of(path, "raise RuntimeError")
    assert not run.passed
    assert f"{path}:{bad}: RuntimeError: my law broke on the arm" in run.text, run.text


@pytest.mark.slow
def test_wrong_shape_nan_and_hang_are_reported_at_the_students_function(tmp_path, monkeypatch):
    monkeypatch.setattr(core, "VALUE_CASE_S", 0.5)
    path = student_file(tmp_path, "jacobian", """\
        import numpy as np

        EXERCISE = "jacobian"


        def hand_jacobian(q, L1, L2):
            if L2 < 0.2:
                while True:
                    pass
            if L1 < 0.18:
                return np.full((3, 3), np.nan)
            return np.zeros((3, 1))
        """)
    report = check_file(path)
    texts = [o.text for o in report.outcomes]
    assert not any(o.passed for o in report.outcomes)
    assert any("got      shape (3, 1)" in t and "expected shape (3, 3)" in t for t in texts)
    assert any("NaN" in t for t in texts)
    hang = line_of(path, "while True") + 1
    assert any(f"{path}:{hang}: Hang: still running after 0.5 s" in t or
               f"{path}:{hang - 1}: Hang" in t for t in texts), texts


def test_syntax_error_and_missing_function_are_one_line_each(tmp_path):
    path = student_file(tmp_path, "leg_ik", """\
        EXERCISE = "leg_ik"

        def leg_ik(x, y, z, l1, l2)
            return 0.0, 0.0, 0.0
        """)
    with pytest.raises(StudentError) as err:
        load_student(path)
    assert err.value.line == 3 and "SyntaxError" in err.value.error
    report = check_file(path)
    assert report.error is not None and report.score == 0 and not report.passed
    assert report.outcomes and all(not o.passed for o in report.outcomes)
    assert f"{path}:3: SyntaxError" in report.summary()
    other = student_file(tmp_path, "leg_ik", 'EXERCISE = "leg_ik"\n\ndef leg(x):\n    pass\n')
    with pytest.raises(StudentError, match=r"no function leg_ik\(\)"):
        load_student(other)


def test_gradescope_results_have_the_fields_it_reads_and_the_score_of_the_cases(tmp_path):
    ex = get("thesis_fk")
    sign = next(m for m in ex.mistakes if m.name == "a sign")  # right where z = 0
    report = check(sign.fn, "thesis_fk", quiet=True)
    results = report.gradescope()
    json.dumps(results)  # serialisable
    passed = sum(o.passed for o in report.outcomes)
    assert 0 < passed < len(report.outcomes)
    assert results["score"] == passed == report.score
    assert len(results["tests"]) == len(report.outcomes)
    for test, o in zip(results["tests"], report.outcomes, strict=True):
        assert set(test) >= {"name", "score", "max_score", "output"}
        assert test["max_score"] == 1.0 and test["score"] == (1.0 if o.passed else 0.0)
        assert o.name in test["name"] and test["output"] == o.text
    assert sum(t["max_score"] for t in results["tests"]) == report.max_score


def test_notebook_check_is_one_call_on_the_function(capsys):
    from armlab.kinematics.leg_ik import LegGeometry
    from armlab.kinematics.leg_ik import leg_ik as lab_leg_ik

    def leg_ik(x, y, z, l1, l2):
        return lab_leg_ik((x, y, z), LegGeometry(l1, l2)).angles

    report = armlab.check(leg_ik)
    out = capsys.readouterr().out.splitlines()
    assert report.passed
    assert len(out) == len(report.outcomes) + 1 and out[-1] == report.summary()
    assert all(line.startswith("PASS  ") for line in out[:-1])

    def my_function(x):
        return x

    with pytest.raises(ValueError, match="which exercise"):
        armlab.check(my_function)


@pytest.mark.slow
def test_notebook_starter_is_nbformat_4_and_its_cells_check_the_function(tmp_path, capsys):
    path = write_starter("planar_ik", tmp_path, notebook=True)
    nb = json.loads(path.read_text())
    assert nb["nbformat"] == 4 and nb["nbformat_minor"] >= 4
    kinds = [c["cell_type"] for c in nb["cells"]]
    assert kinds == ["markdown", "code", "code"]
    code = "".join(nb["cells"][1]["source"])
    assert "def planar_ik(" in code and "raise NotImplementedError" in code
    assert "armlab.check(planar_ik)" in "".join(nb["cells"][2]["source"])
    nbformat = pytest.importorskip("nbformat")  # jupyter_server's: in the dev extras
    nbformat.validate(nbformat.reads(path.read_text(), as_version=4))
    for c in nb["cells"]:
        assert isinstance(c["source"], list) and "id" in c
        if c["cell_type"] == "code":
            assert c["outputs"] == [] and c["execution_count"] is None
    # Filled in, the cells run as a kernel runs them: the last one checks the function.
    nb["cells"][1]["source"] = [code.replace(
        'raise NotImplementedError("fill in planar_ik (seed 004)")',
        textwrap.indent(PAST_THE_REFUSAL, "    ").lstrip() +
        "    from armlab.kinematics import planar_ik as p4\n"
        "    return p4.solve(X, Y, arm=p4.PlanarArm(l1, l2, l3)).angles")]
    path.write_text(json.dumps(nb))
    namespace: dict = {}
    for c in nb["cells"]:
        if c["cell_type"] == "code":
            exec(compile("".join(c["source"]), "<cell>", "exec"), namespace)
    assert "planar_ik: 17/17 cases pass" in capsys.readouterr().out
    # and `armlab check` reads the notebook itself (the check cell is not run again)
    assert check_file(path).passed


def test_error_in_a_notebook_cell_names_the_cell_and_its_line(tmp_path):
    path = write_starter("leg_ik", tmp_path, notebook=True)
    nb = json.loads(path.read_text())
    nb["cells"][1]["source"] = ["import math\n", "\n", "def leg_ik(x, y, z, l1, l2):\n",
                                "    return math.acos(2.0), 0.0, 0.0\n"]
    path.write_text(json.dumps(nb))
    report = check_file(path)
    assert not report.passed
    assert f"{path} [cell 2]:4: ValueError: math domain error" in report.outcomes[0].text


def test_reference_angles_compare_modulo_a_turn():
    case = ValueCase("a", (0.0,), angles=True, atol=1e-9)
    assert core.close(np.array([math.pi - 1e-12]), np.array([-math.pi + 1e-12]), case)
    assert not core.close(np.array([0.1]), np.array([0.0]), case)


def test_a_students_own_helper_module_next_to_the_file_is_found(tmp_path):
    (tmp_path / "my_trig.py").write_text("import math\n\n\ndef wrap(a):\n"
                                          "    return math.atan2(math.sin(a), math.cos(a))\n")
    (tmp_path / "my_leg.py").write_text(LEG_IK)
    path = student_file(tmp_path, "leg_ik", """\
        from my_trig import wrap

        from my_leg import leg_ik as mine


        def leg_ik(x, y, z, l1, l2):
            return tuple(wrap(a) for a in mine(x, y, z, l1, l2))
        """)
    student = load_student(path)
    assert student.exercise.name == "leg_ik"  # found by its function's name
    assert check_file(path).passed
