"""The scripts in examples/ run as a student runs them and print the library's figures."""

from __future__ import annotations

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from armlab.control import metrics
from armlab.control.params import DEFAULT
from armlab.control.trajectory import THESIS_LINE_END, THESIS_LINE_START, THESIS_Q_GUESS
from armlab.kinematics import load_robot

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p.name for p in (ROOT / "examples").glob("*.py"))
#: the examples whose figures a test below checks (a new example needs its own test)
CHECKED = {"01_fk_ik_thesis_arm.py", "02_step_response.py", "03_compliance_headless.py"}


def _number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def run_example(name: str, *args: str) -> dict[str, list[float]]:
    """Run examples/NAME with this Python; its ``key = numbers`` lines as a dict."""
    out = subprocess.run([sys.executable, str(ROOT / "examples" / name), *args], cwd=ROOT,
                         capture_output=True, text=True, timeout=240, check=True).stdout
    figures = {}
    for line in out.splitlines():
        key, sep, value = line.partition(" = ")
        words = value.split("  (")[0].split()
        if sep and key.isidentifier() and all(w == "—" or _number(w) for w in words):
            figures[key] = [math.nan if w == "—" else float(w) for w in words]
    return figures


def test_fk_ik_example_prints_the_arms_own_fk_and_reaches_the_line_ends():
    f = run_example("01_fk_ik_thesis_arm.py")
    arm = load_robot("receptionist_arm")
    np.testing.assert_allclose(f["fk_hand_cm"], arm.fk(THESIS_Q_GUESS)[:3, 3] * 100, atol=1e-3)
    for name, target in (("start", THESIS_LINE_START), ("end", THESIS_LINE_END)):
        q = np.radians(f[f"ik_{name}_q_deg"])
        assert np.linalg.norm(arm.fk(q)[:3, 3] - target) < 1e-4  # 0.1 mm, from 3 decimals
        assert f[f"ik_{name}_error_mm"][0] < 0.1
    assert f["ik_start_q_deg"][0] == pytest.approx(45.0, abs=0.5)  # the thesis: θ1 = 45°


@pytest.mark.timeout(300)
@pytest.mark.slow
def test_compliance_example_yields_by_the_static_gain_of_eq_2_15():
    f = run_example("03_compliance_headless.py")
    formula = metrics.static_gain(DEFAULT.k_f, DEFAULT.k_env)
    assert f["static_gain_formula"][0] == pytest.approx(formula, abs=1e-5)
    assert f["static_gain_measured"][0] == pytest.approx(formula, rel=0.08)
    assert f["hand_give_compliance_cm"][0] > 1.0  # 3 N moves the compliant hand centimetres
    assert f["hand_give_pd_only_cm"][0] < 0.2 * f["hand_give_compliance_cm"][0]


@pytest.mark.timeout(300)
@pytest.mark.parametrize("kp,kv", [(DEFAULT.kp, DEFAULT.kv), (100.0, 4.0)])
@pytest.mark.slow
def test_step_example_puts_the_formulas_beside_the_ideal_joint_and_the_arm(kp, kv):
    f = run_example("02_step_response.py", str(kp), str(kv))
    wn, z = metrics.pd_natural_frequency(kp), metrics.pd_damping(kp, kv)
    assert f["formula_peak_time_s"][0] == pytest.approx(metrics.peak_time(wn, z), abs=1e-3)
    assert f["formula_overshoot_pct"][0] == pytest.approx(metrics.overshoot_pct(z), abs=1e-3)
    assert f["formula_settling_time_s"][0] == pytest.approx(metrics.settling_time(wn, z),
                                                            abs=1e-3)
    # the ideal joint is the formula's system: peak and overshoot as predicted
    assert f["ideal_peak_time_s"][0] == pytest.approx(f["formula_peak_time_s"][0], rel=0.02)
    assert f["ideal_overshoot_pct"][0] == pytest.approx(f["formula_overshoot_pct"][0], abs=1.0)
    # the arm's servos lag: the same size of figures, not the same figures
    assert f["arm_peak_time_s"][0] == pytest.approx(f["formula_peak_time_s"][0], rel=0.25)
    assert f["arm_overshoot_pct"][0] > 0.5 * f["formula_overshoot_pct"][0]


def test_every_example_is_numbered_has_a_main_and_a_test_of_its_figures():
    assert EXAMPLES, "examples/ is empty"
    for name in EXAMPLES:
        assert name[:2].isdigit() and name[2] == "_", f"{name}: examples are numbered NN_name.py"
        tree = ast.parse((ROOT / "examples" / name).read_text())
        mains = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "main"]
        assert mains, f"{name} has no main()"
        assert ast.get_docstring(tree), f"{name} says nothing of what it shows"
    assert [int(n[:2]) for n in EXAMPLES] == list(range(1, len(EXAMPLES) + 1))
    assert set(EXAMPLES) == CHECKED  # every example is run, and its figures checked, above


def test_an_example_main_runs_when_imported_not_on_import():
    """Importing an example runs nothing (a notebook can import it and call main())."""
    path = str(ROOT / "examples" / "01_fk_ik_thesis_arm.py")
    code = ("import importlib.util, sys; "
            f"s = importlib.util.spec_from_file_location('ex', {path!r}); "
            "m = importlib.util.module_from_spec(s); s.loader.exec_module(m); "
            "print('imported'); m.main()")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         timeout=240, check=True).stdout
    assert out.startswith("imported\n")  # nothing printed before main() was called
    assert "fk_hand_cm =" in out
