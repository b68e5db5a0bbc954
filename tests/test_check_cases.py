"""The cases see the mistakes they can: the halving count of an RMRC step to the one, a
step given up returns q exactly, a rank-deficient J, a centimetre answer; a hint is only
given when it names every mistake that gives the value; and a right value returned in a
looser type (list, tuple, plain float) is compared, a (3, 1) array refused in one line."""

import json

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.exercises import check_file, get
from armlab.exercises.core import ValueCase, judge_value

#: seed 002 eq. 4 and 6 written by hand, returning a list.
JOINT_RATE_AS_LIST = """\
EXERCISE = "null_space_step"
import numpy as np


def joint_rate(J, xdot, grad_w, k_a):
    J_plus = np.linalg.pinv(J)
    P = np.eye(J.shape[1]) - J_plus @ J
    return (J_plus @ xdot + P @ (k_a * np.asarray(grad_w))).tolist()
"""

#: thesis eq. 3.13 by hand; RETURN is how the three numbers are returned.
FK = """\
EXERCISE = "thesis_fk"
import math
import numpy as np


def hand_position(q, L1, L2):
    t1, t0, t2 = q
    c0, s0, c1, s1 = math.cos(t0), math.sin(t0), math.cos(t1), math.sin(t1)
    c2, s2 = math.cos(t2), math.sin(t2)
    x = L1 * c0 * c1 - L2 * (s1 * s2 - c0 * c1 * c2)
    y = L2 * (c1 * s2 + c0 * c2 * s1) + L1 * c0 * s1
    z = -L1 * s0 - L2 * c2 * s0
    return RETURN
"""


@pytest.mark.slow
def test_a_list_from_null_space_step_is_compared_in_every_case_and_the_closed_loop(
        tmp_path, capsys):
    path = tmp_path / "null_space_step.py"
    path.write_text(JOINT_RATE_AS_LIST)
    results = tmp_path / "results.json"
    assert main(["check", str(path), "--results", str(results)]) == 0
    out = capsys.readouterr()
    assert "Traceback" not in out.out + out.err
    data = json.loads(results.read_text())
    assert data["score"] == len(get("null_space_step").cases())


@pytest.mark.parametrize("ret", ["(x, y, z)", "[x, y, z]", "np.array([x, y, z])",
                                 "[np.float64(x), y, float(np.float64(z))]"])
def test_a_right_value_in_a_looser_type_is_compared(tmp_path, ret):
    path = tmp_path / "thesis_fk.py"
    path.write_text(FK.replace("RETURN", ret))
    report = check_file(path)
    assert report.passed, report.text()


@pytest.mark.parametrize("ret,why", [
    ("np.array([[x], [y], [z]])", "got shape (3, 1), expected shape (3,): the same numbers "
     "in another shape; return shape (3,)"),
    ("{'x': x}", "returned dict {'x':"),
    ("x + 1j * y", "returned complex"),
    ("'x, y, z'", "not numbers"),
    ("[x, [y, z]]", "not numbers"),
    ("10 ** 400", "not numbers"),
])
def test_a_value_that_is_not_the_answers_shape_is_refused_in_one_line(tmp_path, ret, why):
    path = tmp_path / "thesis_fk.py"
    path.write_text(FK.replace("RETURN", ret))
    report = check_file(path)
    assert report.score == 0
    for o in report.outcomes:
        assert len(o.lines) == 2, o.text  # the case's line, then why, one line
        assert why in o.lines[1], o.text


def test_a_wrong_shape_from_the_law_in_the_closed_loop_is_one_line(tmp_path):
    path = tmp_path / "pd_reference.py"
    path.write_text("EXERCISE = 'pd_reference'\nimport numpy as np\n\n\n"
                    "def pd_reference_accel(kp, kv, q_cmd, qd_cmd, q, qd):\n"
                    "    a = kp * (np.asarray(q_cmd) - q) + kv * (np.asarray(qd_cmd) - qd)\n"
                    "    return a.reshape(-1, 1) if np.ndim(a) else a\n")
    run = check_file(path).outcomes[-1]
    assert not run.passed and "closed loop" in run.lines[0]
    assert "returned shape (3, 1), expected (3,)" in run.text and len(run.lines) == 2


def test_a_hint_names_every_mistake_that_gives_the_value():
    """On (Kp 20, Kv 5, θ_cmd 0.3, θ̇_cmd 0, θ 0.1, θ̇ 0.2) a sign error and swapped gains
    both give −3: the hint names both, not the first."""
    ex = get("pd_reference")
    case = next(c for c in ex.cases() if c.name == "one joint, plain floats")
    sign = next(m for m in ex.mistakes if m.name == "a sign")
    swapped = next(m for m in ex.mistakes if m.name == "swapped gains")
    o = judge_value(ex, case, sign.fn)
    assert not o.passed and "got      -3" in o.text
    assert "hint: 2 mistakes give this value here; one of them:" in o.text
    assert f"hint (a sign): {sign.hint}" in o.text
    assert f"hint (swapped gains): {swapped.hint}" in o.text
    # where only one of them gives the value, its hint alone
    three = next(c for c in ex.cases() if c.name.startswith("thesis ch. 4 gains"))
    o = judge_value(ex, three, sign.fn)
    hints = [ln for ln in o.lines if "hint" in ln]
    assert hints == [f"      hint (a sign): {sign.hint}"]


def test_the_fk_case_is_named_in_the_units_it_is_compared_in_and_cm_gets_its_hint(tmp_path):
    ex = get("thesis_fk")
    first = ex.cases()[0]
    assert "(-0.11322, 0.07653, 0) m" in first.name
    assert np.allclose(first.expected, [-0.11322, 0.07653, 0.0], atol=2e-4)
    path = tmp_path / "thesis_fk.py"
    path.write_text(FK.replace("RETURN", "100 * np.array([x, y, z])"))
    report = check_file(path)
    assert report.score == 0
    cm = next(m for m in ex.mistakes if m.name == "centimetres for metres")
    assert all(f"hint (centimetres for metres): {cm.hint}" in o.text
               for o in report.outcomes), report.text()


#: Each mistake added for an edge, and the case that must catch it with its hint.
EDGES = [
    ("rmrc_step", "a step taken anyway", "a step that needs exactly 31 halvings"),
    ("rmrc_step", "a step taken anyway", "e too strict: more than 30 halvings"),
    ("rmrc_step", "one halving too many", "a step that needs exactly 31 halvings"),
    ("rmrc_step", "one halving too few", "a step that needs exactly 30 halvings"),
    ("null_space_step", "the full-rank pseudo-inverse", "the stretched arm turned 0.4 rad"),
    ("thesis_fk", "centimetres for metres", "thesis ch. 4: the line's first point"),
]


@pytest.mark.parametrize("name,mistake,case", EDGES)
def test_each_edge_mistake_fails_its_own_case_with_its_hint(name, mistake, case):
    ex = get(name)
    planted = next(m for m in ex.mistakes if m.name == mistake)
    target = next(c for c in ex.cases() if c.name.startswith(case))
    assert isinstance(target, ValueCase)
    o = judge_value(ex, target, planted.fn)
    assert not o.passed and o.lines[0].startswith(f"FAIL  {target.name}: ")
    assert f"hint ({mistake}): {planted.hint}" in o.text, o.text
    assert judge_value(ex, target, ex.reference).passed


def test_the_halving_cases_need_the_halvings_they_name_and_a_given_up_step_is_q_exactly():
    from armlab.kinematics.ik import MAX_HALVINGS, halved_step

    ex = get("rmrc_step")
    for k in (MAX_HALVINGS - 1, MAX_HALVINGS, MAX_HALVINGS + 1):
        case = next(c for c in ex.cases() if c.name.startswith(f"a step that needs exactly {k} "))
        q, J, J_inv, dX, e, lo, hi = case.args
        _, halvings = halved_step(J, J_inv, dX, e, max_halvings=99)
        assert halvings == k
        out = ex.reference(*case.args)
        assert (np.array_equal(out, q) if k > MAX_HALVINGS else not np.array_equal(out, q))
    given_up = [c for c in ex.cases() if "q unchanged (exactly)" in c.name]
    assert len(given_up) == 2 and all(c.atol == c.rtol == 0.0 for c in given_up)
    # a step of 1e-11 rad taken anyway is not "q" within the default tolerance's blur
    assert not judge_value(ex, given_up[0], lambda q, *a: np.asarray(q) + 1e-13).passed


@pytest.mark.slow
def test_a_rank_deficient_jacobian_written_as_the_full_rank_formula_fails_at_its_line(tmp_path):
    path = tmp_path / "null_space_step.py"
    path.write_text(JOINT_RATE_AS_LIST.replace(
        "J_plus = np.linalg.pinv(J)", "J_plus = J.T @ np.linalg.inv(J @ J.T)"))
    report = check_file(path)
    by_name = {o.name: o for o in report.outcomes}
    assert not by_name["the stretched arm along x (J's x row is zero, rank 1)"].passed
    zero_row = by_name["the stretched arm along x (J's x row is zero, rank 1)"].text
    assert f"{path}:6: LinAlgError: Singular matrix" in zero_row, zero_row
    turned = next(o for n, o in by_name.items() if n.startswith("the stretched arm turned"))
    assert not turned.passed
    assert by_name["k_a = 0: the minimum-norm J⁺ẋ alone"].passed
