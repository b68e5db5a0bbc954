"""The one door to viser's insides (armlab/app/viser_ext): every hook is checked when a lab starts,
and the gate fails closed: a lab whose gate cannot be put in place does not serve."""

from __future__ import annotations

import ast
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import viser
import websockets.asyncio.server
from _helpers import wait_for

from armlab.app.viser_ext import HooksMissing, check_hooks, require_hooks


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def accepts(port: int) -> bool:
    """Whether something on 127.0.0.1:``port`` accepts a TCP connection now."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2.0):
            return True
    except OSError:
        return False


def test_every_hook_is_in_place_in_the_installed_viser():
    assert check_hooks() == []
    require_hooks(warn=lambda line: pytest.fail(f"unexpected warning: {line}"))


def test_a_missing_non_security_hook_warns_and_a_missing_gate_hook_refuses(monkeypatch):
    monkeypatch.setattr("armlab.app.viser_ext.urdf.missing", lambda: ["ViserUrdf._meshes"])
    warned: list[str] = []
    require_hooks(warn=warned.append)
    assert len(warned) == 1 and "ViserUrdf._meshes" in warned[0]
    assert viser.__version__ in warned[0]

    from viser.infra import _infra

    monkeypatch.delattr(_infra, "_message_consumer")
    with pytest.raises(HooksMissing) as e:
        require_hooks(warn=lambda line: None)
    text = str(e.value)
    assert f"viser {viser.__version__}" in text and "_message_consumer" in text
    assert "gate" in text


@pytest.mark.slow
def test_serve_refuses_to_start_when_the_gates_hook_target_is_absent():
    """``armlab serve`` on a viser without what the gate patches: one clear message, a
    non-zero exit, and nothing listening on the port it was given."""
    port = free_port()
    script = textwrap.dedent(f"""
        import sys
        from viser.infra import _infra
        del _infra._message_consumer  # as if viser had renamed its receive loop
        from armlab.app.commands.cli import main
        sys.exit(main(["serve", "--http-port", "{port}"]))
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode != 0
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith("armlab serve:")]
    assert len(lines) == 1, done.stderr
    assert f"viser {viser.__version__}" in lines[0]
    assert "_message_consumer" in lines[0]
    assert "url:" not in done.stdout
    assert not accepts(port)


def test_a_lab_whose_server_bypassed_the_gate_stops_it_and_raises(monkeypatch):
    """The hook is there but viser builds its websocket server without going through it
    (as a release that imports ``serve`` by another name would): the lab stops the server
    it got and raises; no port is left accepting."""
    from viser.infra import _infra

    from armlab.app.classroom.gate import Gate, gated, new_token
    from armlab.app.lab.server import Lab, ServeOptions

    with gated(Gate(new_token())) as placed:  # the stand-in is now in viser's module
        pass
    with pytest.raises(HooksMissing):
        placed.confirm()  # nothing was built in that block
    monkeypatch.setattr(_infra.websockets.asyncio.server, "serve",
                        websockets.asyncio.server.serve)  # the real one: no gate
    port = free_port()
    with pytest.raises(HooksMissing) as e:
        Lab(ServeOptions(http_port=port))
    assert f"viser {viser.__version__}" in str(e.value)
    assert "without the gate" in str(e.value)
    wait_for(lambda: not accepts(port), timeout=60.0)


def _private_attrs_assigned(paths) -> set[str]:  # noqa: ANN001
    """Names ``_x`` assigned as ``obj._x = ...`` or defined as ``def _x`` in ``paths``."""
    names: set[str] = set()
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                names.add(node.attr)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                names.add(node.name)
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


@pytest.mark.slow
def test_only_viser_ext_reaches_into_viser():
    """Outside armlab/app/viser_ext no module imports a private viser module or uses an
    underscore attribute that viser (and not the lab itself) defines."""
    root = Path(__file__).resolve().parent.parent / "armlab" / "app"
    outside = [p for p in root.rglob("*.py") if "viser_ext" not in p.parts]
    viser_root = Path(viser.__file__).parent
    ours = _private_attrs_assigned(outside)
    theirs = _private_attrs_assigned(viser_root.rglob("*.py")) - ours
    found = []
    for path in outside:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            where = f"{path.relative_to(root.parent)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(
                    "viser") and any(part.startswith("_") or part == "infra"
                                     for part in node.module.split(".")):
                found.append(f"{where} from {node.module} import ...")
            elif isinstance(node, ast.Import):
                found += [f"{where} import {a.name}" for a in node.names
                          if a.name.startswith("viser.") and "._" in f".{a.name}"]
            elif isinstance(node, ast.Attribute) and node.attr in theirs:
                found.append(f"{where} .{node.attr}")
    assert found == [], "private viser names outside armlab/app/viser_ext:\n" + "\n".join(found)
