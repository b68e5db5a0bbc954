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
per-call overhead, over 200 calls a forward dynamics, four a plant step (RK4). The
compiled loop does the same arithmetic without it (``armlab bench --only classroom``).

Compiling takes seconds (one for the thesis arm on a quiet machine), so
:class:`CompiledDynamics` compiles in a thread of its own, started on first need, while
the numpy code goes on; the two give the same numbers, so the switch changes none.
Without numba (not installed, or a Python it has no wheel for), or when compiling fails,
the numpy code runs, as it did before numba.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

#: False: every :class:`CompiledDynamics` runs the numpy code (``armlab bench`` times both)
ENABLED = True

#: a compiled loop over arms: its arrays, the last one written (its results)
Kernel = Callable[..., None]

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


class CompiledDynamics:
    """The compiled loops of one generated module, once compiled (one per source text in
    a process: :func:`compiled_dynamics`).

    :meth:`kernel` gives a compiled loop, or None while there is none; :meth:`start`
    starts compiling them in a thread of its own; :meth:`wait` compiles and waits
    (benches, tests). :attr:`error` says why there are none (numba missing, a failed
    compile): the numpy code runs then.
    """

    def __init__(self, source: str, n: int, name: str) -> None:
        self._source, self._n, self._name = source, n, name
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._kernels: dict[str, Kernel] = {}
        self.error: str | None = None

    def kernel(self, function: str) -> Kernel | None:
        """The compiled loop of ``function`` ("fd", "frames") when it is ready and
        :data:`ENABLED`; None otherwise."""
        return self._kernels.get(function) if ENABLED else None

    def start(self) -> None:
        """Start compiling in a thread of its own (nothing when started before, or when
        not :data:`ENABLED`)."""
        if not ENABLED:
            return
        with self._lock:
            if self._thread is not None:
                return
            self._thread = threading.Thread(target=self._compile, daemon=True,
                                            name=f"armlab-compile {self._name}")
            self._thread.start()

    def wait(self, timeout: float | None = None) -> bool:
        """Compile (if not done) and wait up to ``timeout`` s; True when compiled."""
        self.start()
        thread = self._thread
        if thread is not None:
            thread.join(timeout)
        return bool(self._kernels)

    def _compile(self) -> None:
        try:
            self._kernels = compile_kernels(self._source, self._n, self._name)
        except ImportError as exc:
            self.error = f"numba is not installed ({exc})"
        except Exception as exc:  # a numba that cannot compile this: numpy goes on
            self.error = f"numba could not compile it ({type(exc).__name__}: {exc})"


_SHARED: dict[str, CompiledDynamics] = {}
_SHARED_LOCK = threading.Lock()


def compiled_dynamics(source: str, n: int, name: str) -> CompiledDynamics:
    """The process's :class:`CompiledDynamics` of the generated module ``source`` (``n``
    joints): every model loaded again (``load_robot`` makes a new one each time) with the
    same code shares one compile."""
    with _SHARED_LOCK:
        found = _SHARED.get(source)
        if found is None:
            found = _SHARED[source] = CompiledDynamics(source, n, name)
        return found


def as_input(x: Any) -> np.ndarray:
    """``x`` as the compiled loops take it: a C-ordered float64 array (no copy if it is)."""
    return np.ascontiguousarray(x, dtype=float)
