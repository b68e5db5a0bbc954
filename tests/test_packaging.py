"""One installed name: the wheel built from this repository holds armlab and nothing else,
and installs beside python-control (whose package is also called ``control``) leaving both
working. Built with this venv's setuptools (no build isolation: nothing is downloaded).

Import path = file path: ``armlab/control/loop.py`` is ``armlab.control.loop``, in a clone,
an editable install and a wheel alike."""

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
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    # built from a copy: setuptools leaves build/ in the tree it builds, and a stale file
    # there would land in a later wheel
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "armlab", src / "armlab",
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


def test_the_packages_are_found_not_mapped():
    """No folder is renamed into the package and no package is listed by hand: the only
    entry of package-dir says the checkout's root is where packages are found."""
    tool = PYPROJECT["tool"]["setuptools"]
    assert tool["package-dir"] == {"": "."}
    assert tool["packages"] == {"find": {"include": ["armlab", "armlab.*"]}}


def test_the_editable_install_is_a_plain_path():
    """``pip install -e .`` (make's install) puts the checkout's root on sys.path through a
    .pth file, no import hook: the path an editor or a type checker follows is the file."""
    import importlib.util

    hooks = [type(f).__module__ for f in sys.meta_path if "editable" in type(f).__module__]
    assert hooks == []
    spec = importlib.util.find_spec("armlab.control.loop")
    assert spec is not None and spec.origin == str(ROOT / "armlab" / "control" / "loop.py")


def test_the_wheel_holds_every_module_and_robot_of_the_repository(wheel: Path):
    """Every source file and data file under armlab/ is in the wheel at the same path."""
    names = set(zipfile.ZipFile(wheel).namelist())
    for path in (ROOT / "armlab").rglob("*"):
        if (path.suffix in {".py", ".urdf", ".svg", ".json", ".toml", ".md"}
                and "__pycache__" not in path.parts):
            rel = path.relative_to(ROOT).as_posix()
            assert rel in names, f"{rel} is not in the wheel (an __init__.py or package-data?)"


def test_a_clone_imports_armlab_from_its_root_without_an_install(tmp_path: Path):
    """From the checkout's root, ``import armlab`` is the checkout's package, whatever is
    installed: the folder is the package (no one-file shim shadows an install)."""
    code = ("import armlab, armlab.control.loop, armlab.app.commands.cli\n"
            "print(armlab.__file__)\nprint(armlab.control.loop.__file__)")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-S", "-c",
                          f"import sys; sys.path[1:1] = {_site_paths()!r}\n" + code],
                         cwd=ROOT, env=env, check=True, capture_output=True, text=True,
                         timeout=120).stdout.split()
    assert out == [str(ROOT / "armlab" / "__init__.py"),
                   str(ROOT / "armlab" / "control" / "loop.py")]


def _site_paths() -> list[str]:
    """This interpreter's site-packages without the editable install's path entry (numpy,
    viser, ... but not armlab)."""
    import site
    return [p for p in site.getsitepackages() if Path(p).is_dir()]


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
        "import control, armlab, armlab.control.loop, armlab.app.commands.cli",
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
