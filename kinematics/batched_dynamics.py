"""The generated Newton–Euler code of one chain, run over many arms at once (numpy over arms).

:func:`kinematics._rnea_codegen.dynamics_model` writes thesis eq. 2.41–2.50 out as
straight-line float code. That code uses only ``+ - * /``, float constants, tuple
unpacking of its arguments and ``_sin``/``_cos``; compiled again with ``numpy.sin`` and
``numpy.cos`` in their place, the *same source* runs on arrays of shape (N,) (one entry
per arm) instead of floats, element by element with the same IEEE operations in the
same order. Its results therefore equal N separate float calls bit for bit (numpy's
float64 sin/cos equal ``math``'s here; a test checks it).

Arguments are joint-major: ``q`` (n, N), i.e. row i holds joint i of every arm, so the
generated ``q0, q1, q2, = q`` unpacks contiguous rows. Results come back as (m, N)
arrays, constant entries (a structural 0.0 or 1.0 of the model) broadcast to N.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from kinematics._rnea_codegen import dynamics_model
from kinematics.model import SerialChain

_Fn = Callable[..., tuple[object, ...]]

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

    def rnea(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
             g: Sequence[float]) -> np.ndarray:
        return _stack(self._raw["rnea"](q, qd, qdd, g), q.shape[1])

    def bias(self, q: np.ndarray, qd: np.ndarray, g: Sequence[float]) -> np.ndarray:
        return _stack(self._raw["bias"](q, qd, g), q.shape[1])

    def fd(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, g: Sequence[float],
           armature: Sequence[float]) -> np.ndarray:
        n_arms = q.shape[1]
        if n_arms <= FLOAT_ARMS:  # a few arms: the float code per arm is cheaper
            one = self._float_fd
            res = np.empty((n_arms, self.n))
            for k, (qk, vk, tk) in enumerate(zip(q.T.tolist(), qd.T.tolist(), tau.T.tolist(),
                                                 strict=True)):
                res[k] = one(qk, vk, tk, g, armature)
            return res.T
        return _stack(self._raw["fd"](q, qd, tau, g, armature), n_arms)

    def frames(self, q: np.ndarray) -> np.ndarray:
        return _stack(self._raw["frames"](q), q.shape[1])


def _stack(out: tuple[object, ...], n_arms: int) -> np.ndarray:
    """The generated tuple (arrays (N,) and constant floats) as one (m, N) array."""
    res = np.empty((len(out), n_arms))
    for i, x in enumerate(out):
        res[i] = x
    return res


_CACHE_KEY = "_armlab_batched_dynamics"


def batched_dynamics(model: SerialChain) -> BatchedDynamics:
    """The :class:`BatchedDynamics` of ``model``: :func:`dynamics_model`'s source compiled
    with numpy's sin/cos; built on first use and memoised on the model like it."""
    cached = model.__dict__.get(_CACHE_KEY)
    if cached is None:
        dyn = dynamics_model(model)
        namespace: dict[str, object] = {"_sin": np.sin, "_cos": np.cos}
        exec(compile(dyn.source, f"<batched dynamics of {model.name}>", "exec"),  # noqa: S102
             namespace)
        raw = {name: namespace[name] for name in ("rnea", "bias", "fd", "frames")}
        cached = BatchedDynamics(n=dyn.n, source=dyn.source, revolute=dyn.revolute,  # type: ignore[arg-type]
                                 axes=dyn.axes, _raw=raw, _float_fd=dyn.fd)
        model.__dict__[_CACHE_KEY] = cached
    return cached
