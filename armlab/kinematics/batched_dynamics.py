"""The generated Newton–Euler code of one chain, run over many arms at once (numpy over arms).

:func:`armlab.kinematics._rnea_codegen.dynamics_model` writes thesis eq. 2.41–2.50 out as
straight-line float code. That code uses only ``+ - * /``, float constants, tuple
unpacking of its arguments and ``_sin``/``_cos``; compiled again with ``numpy.sin`` and
``numpy.cos`` in their place, the *same source* runs on arrays of shape (N,) (one entry
per arm) instead of floats, element by element with the same IEEE operations in the
same order. Its results therefore equal N separate float calls bit for bit (numpy's
float64 sin/cos equal ``math``'s here; a test checks it).

Two changes to the text before compiling, neither changing an operation or a value (so
not a bit of the results): every float constant becomes a name bound to a 0-d float64
array of its value (:class:`_ConstantsAsArrays`), and in ``fd`` every operation (``+ - *
/``, unary ``-``, ``_sin``, ``_cos``) becomes its numpy ufunc writing into an (N,) array
of its own, allocated once (:class:`_IntoBuffers`). On the (N,) arrays of a class (N ~ 100)
numpy's cost is its per-call overhead: an array times a Python float costs ~1.7 times an
array times a 0-d array (the float is converted at every call), and writing into a buffer
skips an allocation. ``fd`` runs four times per plant step (RK4); the buffers are per thread.

``fd`` and ``frames`` run the same float code compiled to machine code over the arms
(:mod:`armlab.kinematics.compiled_dynamics`, numba) once it is compiled (the first
call past :data:`FLOAT_ARMS` arms starts compiling it, in a thread), and the code above
until then or without numba: equal bit for bit either way.

Arguments are joint-major: ``q`` (n, N), i.e. row i holds joint i of every arm, so the
generated ``q0, q1, q2, = q`` unpacks contiguous rows. Results come back as (m, N)
arrays, constant entries (a structural 0.0 or 1.0 of the model) broadcast to N.
"""

from __future__ import annotations

import ast
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from armlab.kinematics import compiled_dynamics
from armlab.kinematics._rnea_codegen import dynamics_model
from armlab.kinematics.compiled_dynamics import as_input
from armlab.kinematics.machine_code import Kernel, MachineCode
from armlab.kinematics.model import SerialChain

# Any: the generated code returns floats and (N,) arrays
_Fn = Callable[..., tuple[Any, ...]]

#: Up to this many arms :meth:`BatchedDynamics.fd` runs the float code once per arm: a
#: numpy call costs about the same for 1 arm as for 30 (~65 µs for this code on the thesis
#: arm), the float code about 2 µs an arm. Same operations either way: equal bit for bit.
FLOAT_ARMS = 24


@dataclass(frozen=True)
class BatchedDynamics:
    """One chain's generated dynamics over N arms; every argument (n, N) or (3,) / (n,).

    - ``rnea(q, qd, qdd, g) -> (n, N)``: inverse dynamics, eq. 2.41–2.50; g (3,) floats.
    - ``bias(q, qd, g) -> (n, N)``: C(q, qd) qd + g(q).
    - ``fd(q, qd, tau, g, armature) -> (n, N)``: qdd = (M + diag(armature))^-1 (tau - bias),
      armature (n,) floats.
    - ``frames(q) -> (12 n, N)``: per link R (9, row-major) then p (3), base <- link.

    Attributes:
        n: joints. source: the generated code (the float path's, unchanged).
        revolute: per joint, True when revolute. axes: per joint its unit axis (3,), link frame.
    """

    n: int
    source: str
    revolute: tuple[bool, ...]
    axes: tuple[tuple[float, float, float], ...]
    _raw: dict[str, _Fn]
    _float_fd: _Fn
    _fd_buffers: int  #: (N,) arrays the numpy ``fd`` writes into
    #: ``fd`` and ``frames`` over arms in machine code (numba), once compiled
    _machine: MachineCode = field(compare=False, repr=False)
    _work: threading.local = field(default_factory=threading.local, compare=False, repr=False)

    def rnea(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
             g: Sequence[float]) -> np.ndarray:
        return _stack(self._raw["rnea"](q, qd, qdd, g), q.shape[1])

    def bias(self, q: np.ndarray, qd: np.ndarray, g: Sequence[float]) -> np.ndarray:
        return _stack(self._raw["bias"](q, qd, g), q.shape[1])

    def fd(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, g: Sequence[float],
           armature: Sequence[float]) -> np.ndarray:
        n_arms = q.shape[1]
        kernel = self._kernel("fd", n_arms)
        if kernel is not None:
            out = np.empty(q.shape)
            kernel(as_input(q), as_input(qd), as_input(tau), as_input(g), as_input(armature),
                   out)
            return out
        if n_arms <= FLOAT_ARMS:  # a few arms: the float code per arm is cheaper
            one = self._float_fd
            res = np.empty((n_arms, self.n))
            for k, (qk, vk, tk) in enumerate(zip(q.T.tolist(), qd.T.tolist(), tau.T.tolist(),
                                                 strict=True)):
                res[k] = one(qk, vk, tk, g, armature)
            return res.T
        buffers = getattr(self._work, "fd", None)  # this thread's, for this many arms
        if buffers is None or buffers[0].shape[0] != n_arms:
            buffers = self._work.fd = list(np.empty((self._fd_buffers, n_arms)))
        return _stack(self._raw["fd"](q, qd, tau, g, armature, buffers), n_arms)

    def frames(self, q: np.ndarray) -> np.ndarray:
        kernel = self._kernel("frames", q.shape[1])
        if kernel is not None:
            out = np.empty((12 * self.n, q.shape[1]))
            kernel(as_input(q), out)
            return out
        return _stack(self._raw["frames"](q), q.shape[1])

    def compile(self, timeout: float | None = None) -> bool:
        """Compile ``fd`` and ``frames`` over arms now (if not done) and wait up to
        ``timeout`` s: True when the compiled code runs them from now on (False without
        numba: :attr:`compile_error` says why)."""
        return self._machine.wait(timeout)

    @property
    def compile_error(self) -> str | None:
        """Why there is no compiled code (None: there is, or it is being compiled)."""
        return self._machine.error

    def _kernel(self, function: str, n_arms: int) -> Kernel | None:
        """``function``'s compiled loop if ready; past :data:`FLOAT_ARMS` arms, its
        compiling started if it was not."""
        kernel = self._machine.kernel(function)
        if kernel is None and n_arms > FLOAT_ARMS:
            self._machine.start()
        return kernel


def _stack(out: tuple[Any, ...], n_arms: int) -> np.ndarray:
    """The generated tuple (arrays (N,) and constant floats) as one new (m, N) array."""
    res = np.empty((len(out), n_arms))
    for i, x in enumerate(out):
        res[i] = x
    return res


class _ConstantsAsArrays(ast.NodeTransformer):
    """Float constants (a negated one included, ``-0.185``) -> names ``_k0``, ``_k1``, ...
    collected in ``values`` (name -> 0-d float64 array)."""

    def __init__(self) -> None:
        self.values: dict[str, np.ndarray] = {}
        self._names: dict[float, str] = {}

    def _name(self, value: float, like: ast.AST) -> ast.Name:
        name = self._names.get(value)
        if name is None:
            name = self._names[value] = f"_k{len(self._names)}"
            self.values[name] = np.array(value)
        return ast.copy_location(ast.Name(id=name, ctx=ast.Load()), like)

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        if type(node.value) is float:
            return self._name(node.value, node)
        return node

    def visit_UnaryOp(self, node: ast.UnaryOp) -> ast.AST:
        operand = node.operand
        if (isinstance(node.op, ast.USub) and isinstance(operand, ast.Constant)
                and type(operand.value) is float):
            return self._name(-operand.value, node)
        return self.generic_visit(node)


#: The ufunc of each operation of the generated code.
_UFUNCS: dict[type, str] = {ast.Add: "_add", ast.Sub: "_subtract", ast.Mult: "_multiply",
                            ast.Div: "_divide", ast.USub: "_negative"}
_UFUNC_NAMES = {"_add": np.add, "_subtract": np.subtract, "_multiply": np.multiply,
                "_divide": np.true_divide, "_negative": np.negative}


class _IntoBuffers(ast.NodeTransformer):
    """In a generated function: each operation ``a * b`` -> ``_multiply(a, b, _b7)`` (its
    ufunc, the result written into buffer ``_b7``; likewise ``+ - /``, unary ``-``,
    ``_sin``, ``_cos``), one buffer per operation; the function takes the buffers as a
    last argument ``_b`` (a sequence of ``count`` (N,) arrays) and unpacks them first."""

    def __init__(self) -> None:
        self.count = 0

    def _into(self, func: str, args: list[ast.expr], like: ast.AST) -> ast.Call:
        out = ast.Name(id=f"_b{self.count}", ctx=ast.Load())
        self.count += 1
        return ast.copy_location(
            ast.Call(func=ast.Name(id=func, ctx=ast.Load()), args=[*args, out], keywords=[]),
            like)

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        return self._into(_UFUNCS[type(node.op)], [node.left, node.right], node)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> ast.AST:
        self.generic_visit(node)
        return self._into(_UFUNCS[type(node.op)], [node.operand], node)

    def visit_Call(self, node: ast.Call) -> ast.AST:  # _sin(x), _cos(x)
        self.generic_visit(node)
        assert isinstance(node.func, ast.Name) and len(node.args) == 1 and not node.keywords
        return self._into(node.func.id, node.args, node)

    def visit_FunctionDef(self, node: ast.FunctionDef) -> ast.AST:
        self.generic_visit(node)
        node.args.args.append(ast.arg(arg="_b"))
        names: list[ast.expr] = [ast.Name(id=f"_b{i}", ctx=ast.Store())
                                 for i in range(self.count)]
        node.body.insert(0, ast.Assign(targets=[ast.Tuple(elts=names, ctx=ast.Store())],
                                       value=ast.Name(id="_b", ctx=ast.Load())))
        return node


def _compiled(source: str, name: str) -> tuple[dict[str, _Fn], int]:
    """``source``'s functions compiled for arrays (the two changes in the module docstring;
    ``name`` names the code in tracebacks), and the number of buffers ``fd`` takes."""
    constants = _ConstantsAsArrays()
    module = constants.visit(ast.parse(source))
    into = _IntoBuffers()
    module.body = [into.visit(f) if isinstance(f, ast.FunctionDef) and f.name == "fd" else f
                   for f in module.body]
    namespace: dict[str, object] = {"_sin": np.sin, "_cos": np.cos, **_UFUNC_NAMES,
                                    **constants.values}
    exec(compile(ast.fix_missing_locations(module), name, "exec"), namespace)  # noqa: S102
    return {f: namespace[f] for f in ("rnea", "bias", "fd", "frames")}, into.count  # type: ignore[misc]  # the generated module's functions, by name


_CACHE_KEY = "_armlab_batched_dynamics"


def batched_dynamics(model: SerialChain) -> BatchedDynamics:
    """The :class:`BatchedDynamics` of ``model``: :func:`dynamics_model`'s source compiled
    for arrays (numpy's sin/cos, constants as 0-d arrays, ``fd`` into buffers); built on
    first use and memoised on the model like it."""
    cached = model.__dict__.get(_CACHE_KEY)
    if cached is None:
        dyn = dynamics_model(model)
        raw, buffers = _compiled(dyn.source, f"<batched dynamics of {model.name}>")
        cached = BatchedDynamics(n=dyn.n, source=dyn.source, revolute=dyn.revolute,
                                 axes=dyn.axes, _raw=raw, _float_fd=dyn.fd,
                                 _fd_buffers=buffers,
                                 _machine=compiled_dynamics.compiled_dynamics(
                                     dyn.source, dyn.n, f"<compiled dynamics of {model.name}>"))
        model.__dict__[_CACHE_KEY] = cached
    return cached
