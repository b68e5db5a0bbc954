"""The packages' imports point downwards and no modules import each other in a circle.

The module import graph is read from the source (``ast``, nothing imported) over the
package's layers, ``armlab/app``, ``armlab/exercises``, ``armlab/control``,
``armlab/hardware`` and ``armlab/kinematics``: app → exercises → hardware/control →
kinematics, and only app imports viser. An import inside a function counts as one at the
top (it runs when the function does). An import inside ``if TYPE_CHECKING:`` names a type
for an annotation only; it counts for the layers (an annotation must not point upwards
either) but not for circles of modules (it never runs).

Inside each layer its folders are layers too: no two folders (``hardware/wire``,
``hardware/families/xseries``, ``app/lessons``, a layer's own top folder...) import each
other, directly or round a circle, type-only imports included: a reader can take a
folder's parts as standing on the folders below it.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: the package folder: a file's path under it is its import path
PACKAGE = ROOT / "armlab"
#: the package's folders, each a layer (``armlab.<folder>``)
PACKAGES = ("app", "exercises", "control", "hardware", "kinematics")
#: what each layer must never import (a layer above it, or viser outside app)
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "kinematics": ("armlab.control", "armlab.hardware", "armlab.exercises", "armlab.app",
                   "viser"),
    "control": ("armlab.hardware", "armlab.exercises", "armlab.app", "viser"),
    "hardware": ("armlab.exercises", "armlab.app", "viser"),
    "exercises": ("armlab.app", "viser"),
    "app": (),
}


@dataclass(frozen=True)
class Import:
    """One import of a module: what it names, on which line, and whether it only runs
    for a type checker."""

    target: str
    line: int
    typing_only: bool


def module_name(path: Path) -> str:
    """``armlab/app/classroom/room.py`` -> ``armlab.app.classroom.room`` (a package: its
    name)."""
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(["armlab", *parts])


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports_of(path: Path, known: set[str]) -> list[Import]:
    """Every import in ``path``, resolved to the modules it names (a ``from package import
    name`` names the submodule when ``package.name`` is one of ``known``)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: list[Import] = []

    def visit(node: ast.AST, typing_only: bool) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.body:
                visit(child, True)
            for child in node.orelse:
                visit(child, typing_only)
            return
        if isinstance(node, ast.Import):
            found.extend(Import(a.name, node.lineno, typing_only) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.append(Import(sub if sub in known else base, node.lineno, typing_only))
        for child in ast.iter_child_nodes(node):
            visit(child, typing_only)

    visit(tree, False)
    return found


def sources() -> dict[str, Path]:
    """Module name -> file, for every module of the layers."""
    files = [p for pkg in PACKAGES for p in sorted((PACKAGE / pkg).rglob("*.py"))
             if "__pycache__" not in p.parts]
    return {module_name(p): p for p in files}


@cache
def all_imports() -> dict[str, tuple[Path, list[Import]]]:
    """Module name -> (file, its imports), every module of the layers read once
    for the whole module of tests (the tree does not change while they run)."""
    mods = sources()
    known = set(mods)
    return {name: (path, imports_of(path, known)) for name, path in mods.items()}


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of the layers it imports when it runs (at its top or
    inside a function; a name from a module counts as that module)."""
    found = all_imports()
    graph: dict[str, set[str]] = {}
    for name, (_, imps) in found.items():
        edges = set()
        for imp in imps:
            if imp.typing_only:
                continue
            target = imp.target
            while target and target not in found:
                target = target.rpartition(".")[0]
            if target and target != name:
                edges.add(target)
        graph[name] = edges
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted:
    the modules that import each other in a circle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0

    def strong(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return found


def folder_of(path: Path) -> str:
    """The folder a module's file is in, from the package folder: ``hardware/wire``."""
    return path.relative_to(PACKAGE).parent.as_posix()


def folder_graph() -> dict[str, dict[str, list[str]]]:
    """Folder -> the other folders its modules import (type-only imports too) -> the
    imports that do, ``file:line imports target``."""
    found = all_imports()
    graph: dict[str, dict[str, list[str]]] = {}
    for name, (path, imps) in found.items():
        edges = graph.setdefault(folder_of(path), {})
        for imp in imps:
            target = imp.target
            while target and target not in found:
                target = target.rpartition(".")[0]
            if not target or target == name:
                continue
            to = folder_of(found[target][0])
            if to != folder_of(path):
                edges.setdefault(to, []).append(
                    f"{path.relative_to(ROOT)}:{imp.line} imports {imp.target}")
    return graph


def upward_imports() -> list[str]:
    """Every import (type-only ones too) that points to a layer above its own, or to
    viser outside app: ``file:line imports target``."""
    bad = []
    for name, (path, imps) in all_imports().items():
        layer = name.split(".")[1]
        for imp in imps:
            if any(imp.target == f or imp.target.startswith(f + ".")
                   for f in FORBIDDEN[layer]):
                bad.append(f"{path.relative_to(ROOT)}:{imp.line} imports {imp.target}")
    return bad


@pytest.mark.slow
def test_graph_sees_the_packages():
    """The graph holds every module and the imports between them (a test that read no
    edges would pass whatever the code does)."""
    graph = import_graph()
    assert "armlab.app.lab.server" in graph and "armlab.kinematics.fk" in graph
    # two of the imports it must see (fk -> transforms, model -> fk)
    assert "armlab.kinematics.transforms" in graph["armlab.kinematics.fk"]
    assert "armlab.kinematics.fk" in graph["armlab.kinematics.model"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


@pytest.mark.slow
def test_no_import_circles():
    """No modules of the layers import each other in a circle."""
    found = cycles(import_graph())
    assert not found, "modules importing each other in a circle:\n" + "\n".join(
        " <-> ".join(c) for c in found)


@pytest.mark.slow
def test_imports_point_downwards():
    """kinematics imports no control/hardware/exercises/app; control no
    hardware/exercises/app; hardware no exercises/app; exercises no app; only app imports
    viser."""
    bad = upward_imports()
    assert not bad, "imports pointing upwards:\n" + "\n".join(bad)


@pytest.mark.slow
def test_no_two_folders_import_each_other():
    """The folders of each layer stand on one another: no circle of folders importing
    each other (the imports that close each circle are listed)."""
    graph = folder_graph()
    # the graph sees the folders and an import between two of them (hardware/wire's bus
    # stands on hardware/servos' registry)
    assert "hardware/families/xseries" in graph and "app/lessons" in graph
    assert "hardware/servos" in graph["hardware/wire"]
    found = cycles({a: set(b) for a, b in graph.items()})
    lines = []
    for circle in found:
        lines.append(" <-> ".join(circle))
        lines += [f"    {e}" for a in circle for b in circle if b in graph[a]
                  for e in graph[a][b][:3]]
    assert not found, "folders importing each other:\n" + "\n".join(lines)
