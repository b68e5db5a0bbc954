"""The generated dynamics compiled to machine code, one loop over many arms (numba).

:func:`armlab.kinematics._rnea_codegen.dynamics_model` writes thesis eq. 2.41–2.50 out as
straight-line float code (``+ - * /``, float constants, tuple unpacking, ``_sin`` and
``_cos``). numba compiles that same text, with :func:`math.sin` and :func:`math.cos`, to
machine code, and a loop generated here calls it once per arm: ``fd`` (the forward
dynamics) and ``frames`` (every link's frame, for contact and pushes). Without
``fastmath`` numba keeps every IEEE operation and its order (no fused multiply-adds, no
reassociation), so the results equal the float code's, and numpy's over arms
(:mod:`armlab.kinematics.batched_dynamics`), bit for bit; a test checks it.

Why: on the (n, N) arrays of a class (N ~ 100 arms), the numpy code's cost is numpy's
per-call overhead, over 200 calls a forward dynamics, four a plant step (RK4); the
compiled loop does the same arithmetic without it. It is compiled in a thread, the
numpy code running meanwhile (:class:`armlab.kinematics.machine_code.MachineCode`).
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from armlab.kinematics.machine_code import Kernel, MachineCode

#: numba's types of the loops' arguments: (n, N) and (m, N) C-ordered, (k,) vectors
_SIGNATURES = {
    "fd": "void(f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], f8[:, ::1])",
    "frames": "void(f8[:, ::1], f8[:, ::1])",
}


def _column(name: str, n: int) -> str:
    return "(" + "".join(f"{name}[{i}, k], " for i in range(n)) + ")"


def _written(m: int) -> list[str]:
    return [f"        out[{i}, k] = r{i}" for i in range(m)]


def fd_loop_source(n: int) -> str:
    """``fd_arms(q, qd, tau, g, armature, out)`` for a chain of ``n`` joints: per arm k,
    the generated ``fd`` of its column as tuples, its n results written to ``out[:, k]``."""
    results = "".join(f"r{i}, " for i in range(n))
    return "\n".join([
        "def fd_arms(q, qd, tau, g, armature, out):",
        "    gravity = (g[0], g[1], g[2])",
        "    arm = (" + "".join(f"armature[{i}], " for i in range(n)) + ")",
        "    for k in range(q.shape[1]):",
        f"        {results}= fd({_column('q', n)}, {_column('qd', n)}, "
        f"{_column('tau', n)}, gravity, arm)",
        *_written(n), ""])


def frames_loop_source(n: int) -> str:
    """``frames_arms(q, out)``: per arm k, the generated ``frames`` of its column, its
    12 n results (per link R row-major, then p) written to ``out[:, k]``."""
    results = "".join(f"r{i}, " for i in range(12 * n))
    return "\n".join([
        "def frames_arms(q, out):",
        "    for k in range(q.shape[1]):",
        f"        {results}= frames({_column('q', n)})",
        *_written(12 * n), ""])


def function_source(source: str, name: str) -> str:
    """The function ``name`` of the generated module ``source`` (its text alone)."""
    start = source.index(f"def {name}(")
    end = source.find("\ndef ", start)
    return source[start:] if end < 0 else source[start:end + 1]


def compile_kernels(source: str, n: int, name: str) -> dict[str, Kernel]:
    """The loops over arms of the generated ``fd`` and ``frames`` of ``source``, compiled
    now (raises ImportError without numba, numba's errors when it cannot compile)."""
    import numba

    namespace: dict[str, Any] = {"_sin": math.sin, "_cos": math.cos}
    kernels: dict[str, Kernel] = {}
    for function, loop in (("fd", fd_loop_source(n)), ("frames", frames_loop_source(n))):
        exec(compile(function_source(source, function), name, "exec"), namespace)  # noqa: S102
        namespace[function] = numba.njit(nogil=True)(namespace[function])
        exec(compile(loop, f"{name} over arms", "exec"), namespace)  # noqa: S102
        kernels[function] = numba.njit(_SIGNATURES[function], nogil=True)(
            namespace[f"{function}_arms"])
    return kernels


_SHARED: dict[str, MachineCode] = {}
_SHARED_LOCK = threading.Lock()


def compiled_dynamics(source: str, n: int, name: str) -> MachineCode:
    """The process's compiled ``fd`` and ``frames`` loops of the generated module
    ``source`` (``n`` joints; compiled on :meth:`~MachineCode.start`): every model loaded
    again (``load_robot`` makes a new one each time) with the same code shares one."""
    with _SHARED_LOCK:
        found = _SHARED.get(source)
        if found is None:
            found = _SHARED[source] = MachineCode(
                lambda: compile_kernels(source, n, name), name)
        return found


def as_input(x: Any) -> np.ndarray:
    """``x`` as the compiled loops take it: a C-ordered float64 array (no copy if it is)."""
    return np.ascontiguousarray(x, dtype=float)


def link_points(fr: np.ndarray, links: np.ndarray, points: np.ndarray, axes: np.ndarray,
                p: np.ndarray, cols: np.ndarray) -> None:
    """Base-frame positions ``p`` (3, P) of P link points and their Jacobian columns
    ``cols`` (n, 3, P), written: ``BatchedPlant._points``' arithmetic per point, in its
    order. ``fr`` (n, 12, P): the frames of each point's arm (per link R (9), o (3));
    ``links`` (P,) each point's link, ``points`` (3, P) in its frame; ``axes`` (n, 3) the
    joints' unit axes in their links' frames. Column j of point k is z_j × (p − o_j)
    (thesis eq. 3.17) for j <= links[k], zero beyond."""
    n = fr.shape[0]
    for k in range(links.shape[0]):
        link = links[k]
        px, py, pz = points[0, k], points[1, k], points[2, k]
        x = fr[link, 0, k] * px + fr[link, 1, k] * py + fr[link, 2, k] * pz + fr[link, 9, k]
        y = fr[link, 3, k] * px + fr[link, 4, k] * py + fr[link, 5, k] * pz + fr[link, 10, k]
        z = fr[link, 6, k] * px + fr[link, 7, k] * py + fr[link, 8, k] * pz + fr[link, 11, k]
        p[0, k], p[1, k], p[2, k] = x, y, z
        for j in range(n):
            if j > link:
                cols[j, 0, k], cols[j, 1, k], cols[j, 2, k] = 0.0, 0.0, 0.0
                continue
            a0, a1, a2 = axes[j, 0], axes[j, 1], axes[j, 2]
            z0 = fr[j, 0, k] * a0 + fr[j, 1, k] * a1 + fr[j, 2, k] * a2
            z1 = fr[j, 3, k] * a0 + fr[j, 4, k] * a1 + fr[j, 5, k] * a2
            z2 = fr[j, 6, k] * a0 + fr[j, 7, k] * a1 + fr[j, 8, k] * a2
            rx, ry, rz = x - fr[j, 9, k], y - fr[j, 10, k], z - fr[j, 11, k]
            cols[j, 0, k] = z1 * rz - z2 * ry
            cols[j, 1, k] = z2 * rx - z0 * rz
            cols[j, 2, k] = z0 * ry - z1 * rx


def _build_points() -> dict[str, Kernel]:
    import numba

    signature = "void(f8[:, :, ::1], i8[::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, :, ::1])"
    return {"points": numba.njit(signature, nogil=True, cache=True)(link_points)}


#: the process's compiled :func:`link_points` (any chain, any number of points)
POINTS = MachineCode(_build_points, "link points and their Jacobian columns")
