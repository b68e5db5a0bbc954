"""One installed name: the wheel built from this repository holds armlab and nothing else,
and installs beside python-control (whose package is also called ``control``) leaving both
working. Built with this venv's setuptools (no build isolation: nothing is downloaded)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a wheel built from a copy of the repository, then installed

ROOT = Path(__file__).resolve().parents[1]
#: the repository's folders the wheel installs, from pyproject's map of armlab's parts
SOURCES = tuple(tomllib.loads((ROOT / "pyproject.toml").read_text())
                ["tool"]["setuptools"]["package-dir"].values())


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    # built from a copy: setuptools leaves build/ in the tree it builds, and a stale file
    # there would land in a later wheel
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for folder in SOURCES:
        shutil.copytree(ROOT / folder, src / folder,
                        ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "--quiet", "--wheel-dir", str(out), str(src)],
                   check=True, capture_output=True, text=True, timeout=300)
    (found,) = out.glob("armlab-*.whl")
    return found


def test_every_file_in_the_wheel_lies_under_armlab_or_its_metadata(wheel: Path):
    names = zipfile.ZipFile(wheel).namelist()
    stray = [n for n in names if not (n.startswith("armlab/") or
                                      (n.startswith("armlab-") and ".dist-info/" in n))]
    assert not stray, f"files outside armlab/: {stray[:10]}"


def test_the_wheel_holds_every_module_and_robot_of_the_repository(wheel: Path):
    """pyproject lists the packages by hand: a new folder left out of it would be lost."""
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {"armlab", "app", "kinematics", "control", "hardware"} <= set(SOURCES)
    for top in SOURCES:
        for path in (ROOT / top).rglob("*"):
            if (path.suffix in {".py", ".urdf", ".svg", ".json", ".toml", ".md"}
                    and "__pycache__" not in path.parts):
                rel = path.relative_to(ROOT).as_posix()
                inside = rel if top == "armlab" else f"armlab/{rel}"
                assert inside in names, f"{rel} is not in the wheel (pyproject's packages?)"


def test_the_wheel_installed_beside_python_control_leaves_both_working(
        wheel: Path, tmp_path: Path):
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--quiet",
                    "--target", str(target), str(wheel)],
                   check=True, capture_output=True, text=True, timeout=300)
    packages = sorted(p.name for p in target.iterdir()
                      if not p.name.endswith(".dist-info") and p.name != "bin")  # the script
    assert packages == ["armlab"]
    assert (target / "bin" / "armlab").is_file()
    code = "\n".join([
        "import control, armlab, armlab.control.loop, armlab.app.cli",
        f"assert armlab.__file__.startswith({str(target)!r}), armlab.__file__",
        "assert not control.__file__.startswith(" + repr(str(target)) + ")",
        "sys_ = control.tf([1.0], [1.0, 2.0, 1.0])",  # python-control's transfer function
        "assert abs(control.dcgain(sys_) - 1.0) < 1e-12",
        "arm = armlab.load_robot('receptionist_arm')",  # the URDFs came along as package data
        "print(arm.n, type(sys_).__name__)",
    ])
    env = {**os.environ, "PYTHONPATH": str(target)}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, check=True,
                         capture_output=True, text=True, timeout=120).stdout
    assert out.split() == ["3", "TransferFunction"]
