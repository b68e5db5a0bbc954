"""The package type-checks (mypy, configured in pyproject.toml's [tool.mypy]) and every
``# type: ignore`` in it names its error code and says why."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "armlab"
#: an ignore as mypy reads it: ``# type: ignore``, maybe ``[code, ...]`` after it
IGNORE = re.compile(r"#\s*type:\s*ignore(?P<codes>\[[^\]]*\])?(?P<rest>.*)$")


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy is not installed")
def test_mypy_passes_on_the_package() -> None:
    done = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, f"mypy failed:\n{done.stdout}{done.stderr}"


def unexplained_ignores(text: str) -> list[tuple[int, str]]:
    """(line number, line) of every ``type: ignore`` in ``text`` without a bracketed error
    code, or without a ``# reason`` after it."""
    bad = []
    for n, line in enumerate(text.splitlines(), start=1):
        m = IGNORE.search(line)
        if m is None:
            continue
        codes, rest = m["codes"], m["rest"].strip()
        if not codes or codes == "[]" or not rest.startswith("#") or not rest.lstrip("#").strip():
            bad.append((n, line.strip()))
    return bad


def test_unexplained_ignores_are_found() -> None:
    assert unexplained_ignores("x = f()  # type: ignore\n") == [(1, "x = f()  # type: ignore")]
    assert unexplained_ignores("x = f()  # type: ignore[arg-type]\n")
    assert unexplained_ignores("x = f()  # type: ignore[arg-type]  #\n")
    assert not unexplained_ignores("x = f()  # type: ignore[arg-type]  # f takes any object\n")


def test_every_type_ignore_names_its_code_and_reason() -> None:
    bad = [f"{path.relative_to(ROOT)}:{n}: {line}"
           for path in sorted(PACKAGE.rglob("*.py"))
           for n, line in unexplained_ignores(path.read_text(encoding="utf-8"))]
    assert not bad, ("a `# type: ignore[code]  # why` names its error code and why it is "
                     "needed:\n" + "\n".join(bad))
