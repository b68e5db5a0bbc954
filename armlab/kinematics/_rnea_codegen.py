"""Straight-line code for one chain's Newton–Euler recursion (private: the plant's fast path).

:func:`dynamics_model` unrolls the recursion of thesis eq. 2.41–2.50 joint by joint for
one :class:`~armlab.kinematics.model.SerialChain` into plain Python float code, with every
product by a structural zero or one of the model (axis components, frame offsets,
inertia entries) folded away. That keeps one RNEA call on a 3-joint arm in the
microseconds without numpy overhead on tiny arrays. The equations are read in
:func:`armlab.kinematics.dynamics.newton_euler`, the readable recursion that a test compares
this code with on every shipped robot; this module only writes them out as code.

Model/data separation follows Pinocchio: the chain is never changed; the per-model
constants live in a :class:`DynamicsModel`, built once and memoised in the model
instance's ``__dict__`` (the way ``functools.cached_property`` does). The generated
source is kept in ``DynamicsModel.source`` for inspection.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:  # annotations only: the model's fk() runs this module's code
    from armlab.kinematics.model import SerialChain

Sym = float | str | tuple[float, str]  # generated-code scalar: constant, name, or k * name
Vec = list[Sym]

_ZERO_TOL = 1e-14


# ---------------------------------------------------------------------------
# A tiny straight-line code emitter with constant folding


class _Emitter:
    """Emits Python assignments; folds constants so structural zeros cost nothing."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._count = 0

    def new(self, expr: str, prefix: str = "t") -> str:
        name = f"{prefix}{self._count}"
        self._count += 1
        self.lines.append(f"{name} = {expr}")
        return name

    def lin(self, terms: Sequence[tuple[float, Sym, Sym]]) -> Sym:
        """Sum of k * x * y over ``terms`` (k constant), folded; emits at most one line.

        A lone scaled variable k * x is returned unemitted as ``(k, x)`` and folded into
        whatever uses it (so a sign or a constant factor costs no statement of its own).
        """
        const = 0.0
        parts: dict[str, float] = {}
        for k, x, y in terms:
            k = float(k)
            names = []
            for f in (x, y):
                if isinstance(f, tuple):
                    k *= f[0]
                    names.append(f[1])
                elif isinstance(f, str):
                    names.append(f)
                else:
                    k *= f
            if abs(k) < _ZERO_TOL:
                continue
            if not names:
                const += k
            else:
                key = "*".join(sorted(names))
                parts[key] = parts.get(key, 0.0) + k
        parts = {f: k for f, k in parts.items() if abs(k) >= _ZERO_TOL}
        if abs(const) < _ZERO_TOL:
            const = 0.0
        if not parts:
            return const
        if len(parts) == 1 and const == 0.0:
            ((f, k),) = parts.items()
            if "*" not in f:
                return f if k == 1.0 else (k, f)
        text = ""
        for f, k in parts.items():
            if k == 1.0:
                term = f"+ {f}"
            elif k == -1.0:
                term = f"- {f}"
            elif k < 0:
                term = f"- {-k!r}*{f}"
            else:
                term = f"+ {k!r}*{f}"
            text += " " + term
        if const:
            text += f" + {const!r}" if const > 0 else f" - {-const!r}"
        text = text.strip()
        if text.startswith("+ "):
            text = text[2:]
        elif text.startswith("- "):
            text = "-" + text[2:]
        return self.new(text)

    def add(self, *xs: Sym) -> Sym:
        return self.lin([(1.0, x, 1.0) for x in xs])

    def mul(self, x: Sym, y: Sym) -> Sym:
        return self.lin([(1.0, x, y)])

    def vadd(self, *vs: Vec) -> Vec:
        return [self.add(*(v[i] for v in vs)) for i in range(3)]

    def vscale(self, s: Sym, v: Vec) -> Vec:
        return [self.mul(s, v[i]) for i in range(3)]

    def cross(self, a: Vec, b: Vec) -> Vec:
        return [
            self.lin([(1.0, a[1], b[2]), (-1.0, a[2], b[1])]),
            self.lin([(1.0, a[2], b[0]), (-1.0, a[0], b[2])]),
            self.lin([(1.0, a[0], b[1]), (-1.0, a[1], b[0])]),
        ]

    def dot(self, a: Vec, b: Vec) -> Sym:
        return self.lin([(1.0, a[i], b[i]) for i in range(3)])

    def matvec(self, R: list[Vec], v: Vec) -> Vec:
        return [self.lin([(1.0, R[i][j], v[j]) for j in range(3)]) for i in range(3)]

    def matTvec(self, R: list[Vec], v: Vec) -> Vec:
        return [self.lin([(1.0, R[j][i], v[j]) for j in range(3)]) for i in range(3)]

    def const_matvec(self, A: np.ndarray, v: Vec) -> Vec:
        return [self.lin([(A[i, j], v[j], 1.0) for j in range(3)]) for i in range(3)]


def _snap(x: float) -> float:
    x = float(x)
    if abs(x) < _ZERO_TOL:
        return 0.0
    for one in (1.0, -1.0):
        if abs(x - one) < _ZERO_TOL:
            return one
    return x


def _cvec(v: np.ndarray) -> Vec:
    return [_snap(x) for x in v]


@dataclass
class _Joints:
    """Symbolic joint transforms: R[i] (parent <- child rotation), P[i] (child origin in parent)."""

    R: list[list[Vec]]
    P: list[Vec]


def _emit_transforms(em: _Emitter, model: SerialChain, q: list[str]) -> _Joints:
    """Joint transforms origin_i · motion_i(q_i) as symbols (sin/cos emitted once per joint)."""
    Rs: list[list[Vec]] = []
    Ps: list[Vec] = []
    for i, joint in enumerate(model.joints):
        R0 = joint.origin[:3, :3]
        p0 = joint.origin[:3, 3]
        a = joint.axis
        if joint.kind == "prismatic":
            Rs.append([_cvec(R0[r]) for r in range(3)])
            ra = R0 @ a
            Ps.append([em.lin([(p0[r], 1.0, 1.0), (ra[r], q[i], 1.0)]) for r in range(3)])
            continue
        # Rot(a, q) = c (I - a a^T) + s [a]x + a a^T  (Rodrigues), premultiplied by R0.
        K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        A = R0 @ (np.eye(3) - np.outer(a, a))
        B = R0 @ K
        C = R0 @ np.outer(a, a)
        s = em.new(f"_sin({q[i]})", "s")
        c = em.new(f"_cos({q[i]})", "c")
        Rs.append([[em.lin([(_snap(A[r, k]), c, 1.0), (_snap(B[r, k]), s, 1.0),
                            (_snap(C[r, k]), 1.0, 1.0)]) for k in range(3)] for r in range(3)])
        Ps.append(_cvec(p0))
    return _Joints(Rs, Ps)


def _emit_rnea(em: _Emitter, model: SerialChain, tf: _Joints, qd: Sequence[Sym],
               qdd: Sequence[Sym], g: Sequence[Sym]) -> list[Sym]:
    """Thesis eq. 2.41–2.50 unrolled: forward velocity/acceleration pass, backward force pass.

    Quantities are in each link's own frame. Gravity enters as a base acceleration -g.
    Constant inputs (0.0, 1.0) fold away. Returns the n joint torques.
    """
    n = model.n
    zero: Vec = [0.0, 0.0, 0.0]
    w, dw, a = zero, zero, [em.lin([(-1.0, gi, 1.0)]) for gi in g]
    W: list[Vec] = []
    F: list[Vec] = []
    N: list[Vec] = []
    for i in range(n):
        joint, link = model.joints[i], model.links[i]
        R, P = tf.R[i], tf.P[i]
        ax = _cvec(joint.axis)
        # Eq. 2.46 (revolute) / 2.47 (prismatic): acceleration of this joint's origin,
        # first in the parent frame, then rotated into the child frame.
        a_par = em.vadd(a, em.cross(dw, P), em.cross(w, em.cross(w, P)))
        w_par = em.matTvec(R, w)  # parent omega in child frame
        if joint.kind == "prismatic":
            w_i = w_par  # eq. 2.42
            dw_i = em.matTvec(R, dw)  # eq. 2.44
            a_i = em.vadd(em.matTvec(R, a_par), em.vscale(qdd[i], ax),
                          em.vscale(em.mul(2.0, qd[i]), em.cross(w_i, ax)))
        else:
            w_i = em.vadd(w_par, em.vscale(qd[i], ax))  # eq. 2.41
            dw_i = em.vadd(em.matTvec(R, dw), em.cross(w_par, em.vscale(qd[i], ax)),
                           em.vscale(qdd[i], ax))  # eq. 2.43
            a_i = em.matTvec(R, a_par)
        w, dw, a = w_i, dw_i, a_i
        W.append(w)
        if link.mass == 0.0 and not np.any(link.inertia):
            F.append(zero)
            N.append(zero)
            continue
        c = _cvec(link.com)
        # Eq. 2.48: acceleration of the centre of mass; eq. 2.49-2.50: Newton and Euler.
        a_c = em.vadd(a, em.cross(dw, c), em.cross(w, em.cross(w, c)))
        F.append(em.vscale(_snap(link.mass), a_c))
        Ic = link.inertia
        Iw = em.const_matvec(Ic, w)
        N.append(em.vadd(em.const_matvec(Ic, dw), em.cross(w, Iw)))
    # Backward pass: force f_i and moment n_i that link i-1 exerts on link i (at its origin).
    tau: list[Sym] = [0.0] * n
    f_next: Vec = zero
    n_next: Vec = zero
    for i in range(n - 1, -1, -1):
        c = _cvec(model.links[i].com)
        if i + 1 < n:
            Rn, Pn = tf.R[i + 1], tf.P[i + 1]
            f_par = em.matvec(Rn, f_next)
            n_par = em.matvec(Rn, n_next)
            f_i = em.vadd(F[i], f_par)
            n_i = em.vadd(N[i], n_par, em.cross(c, F[i]), em.cross(Pn, f_par))
        else:
            f_i = F[i]
            n_i = em.vadd(N[i], em.cross(c, F[i]))
        ax = _cvec(model.joints[i].axis)
        tau[i] = em.dot(f_i if model.joints[i].kind == "prismatic" else n_i, ax)
        f_next, n_next = f_i, n_i
    return tau


def _fmt(x: Sym) -> str:
    if isinstance(x, tuple):
        return f"({x[0]!r}*{x[1]})"
    return repr(x) if isinstance(x, float) else x


def _prune(lines: list[str], out: Sequence[Sym]) -> list[str]:
    """Drop assignments whose target nothing later reads (dead code)."""
    live = set()
    for x in out:
        live |= set(re.findall(r"[A-Za-z_]\w*", _fmt(x)))
    kept = []
    for line in reversed(lines):
        target, expr = line.split(" = ", 1)
        if target in live:
            kept.append(line)
            live |= set(re.findall(r"[A-Za-z_]\w*", expr))
    return kept[::-1]


def _ldl_solve(em: _Emitter, Mx: list[list[Sym]], b: list[Sym]) -> list[Sym]:
    """Unrolled LDL^T solve of the symmetric positive definite M x = b."""
    n = len(b)
    L: list[list[Sym]] = [[0.0] * n for _ in range(n)]
    D: list[Sym] = [0.0] * n
    rD: list[Sym] = [0.0] * n
    for j in range(n):
        D[j] = em.lin([(1.0, Mx[j][j], 1.0)]
                      + [(-1.0, em.mul(L[j][k], L[j][k]), D[k]) for k in range(j)])
        d = D[j]
        if isinstance(d, float) and d <= 0.0:
            raise ValueError("mass matrix is singular: a joint moves no mass")
        rD[j] = em.new(f"1.0 / {_fmt(D[j])}")
        for i in range(j + 1, n):
            s = em.lin([(1.0, Mx[i][j], 1.0)]
                       + [(-1.0, em.mul(L[i][k], L[j][k]), D[k]) for k in range(j)])
            L[i][j] = em.mul(s, rD[j])
    y: list[Sym] = [0.0] * n
    for i in range(n):
        y[i] = em.lin([(1.0, b[i], 1.0)] + [(-1.0, L[i][k], y[k]) for k in range(i)])
    z = [em.mul(y[i], rD[i]) for i in range(n)]
    x: list[Sym] = [0.0] * n
    for i in range(n - 1, -1, -1):
        x[i] = em.lin([(1.0, z[i], 1.0)] + [(-1.0, L[k][i], x[k]) for k in range(i + 1, n)])
    return x


def _function(name: str, args: list[str], em: _Emitter, unpack: dict[str, list[str]],
              out: Sequence[Sym]) -> str:
    lines = [f"def {name}({', '.join(args)}):"]
    for arg, names in unpack.items():
        if names:
            lines.append(f"    {', '.join(names)}, = {arg}")
    lines += [f"    {line}" for line in _prune(em.lines, out)]
    lines.append(f"    return ({', '.join(_fmt(x) for x in out)}{',' if len(out) == 1 else ''})")
    return "\n".join(lines)


@dataclass(frozen=True)
class DynamicsModel:
    """Compiled per-model constants (the "model" half of Pinocchio's model/data pair).

    Every function takes and returns plain float sequences (no validation; the public
    functions below validate):

    - ``rnea(q, qd, qdd, g) -> (n,)``: inverse dynamics, gravity g (3,) base frame.
    - ``bias(q, qd, g) -> (n,)``: C(q, qd) qd + g(q).
    - ``mass(q) -> (n*n,)``: M(q) row-major.
    - ``fd(q, qd, tau, g, armature) -> (n,)``: qdd = (M + diag(armature))^-1 (tau - bias).
    - ``frames(q) -> (12 n,)``: per link R (9, row-major) then p (3), base <- link.
    - ``tip(q) -> (16 + 6 n,)``: the end effector's pose (4, 4) row-major, base frame,
      then the geometric Jacobian (6, n) row-major (rows: linear, then angular).

    Attributes:
        n: number of joints.
        revolute: per joint, True when revolute/continuous.
        axes: per joint the unit axis (3,) in its link frame.
        source: the generated Python code.
    """

    n: int
    revolute: tuple[bool, ...]
    axes: tuple[tuple[float, float, float], ...]
    source: str
    rnea: Callable[..., tuple[float, ...]]
    bias: Callable[..., tuple[float, ...]]
    mass: Callable[..., tuple[float, ...]]
    fd: Callable[..., tuple[float, ...]]
    frames: Callable[..., tuple[float, ...]]
    tip: Callable[..., tuple[float, ...]]


def _build(model: SerialChain) -> DynamicsModel:
    n = model.n
    q = [f"q{i}" for i in range(n)]
    qd = [f"qd{i}" for i in range(n)]
    qdd = [f"qdd{i}" for i in range(n)]
    tau_in = [f"tau{i}" for i in range(n)]
    arm = [f"arm{i}" for i in range(n)]
    gv = ["g0", "g1", "g2"]
    sources = []

    em = _Emitter()
    tf = _emit_transforms(em, model, q)
    out = _emit_rnea(em, model, tf, qd, qdd, gv)
    sources.append(_function("rnea", ["q", "qd", "qdd", "g"], em,
                             {"q": q, "qd": qd, "qdd": qdd, "g": gv}, out))

    em = _Emitter()
    tf = _emit_transforms(em, model, q)
    out = _emit_rnea(em, model, tf, qd, [0.0] * n, gv)
    sources.append(_function("bias", ["q", "qd", "g"], em, {"q": q, "qd": qd, "g": gv}, out))

    def mass_columns(em: _Emitter, tf: _Joints) -> list[list[Sym]]:
        Mx: list[list[Sym]] = [[0.0] * n for _ in range(n)]
        for k in range(n):
            e = [1.0 if i == k else 0.0 for i in range(n)]
            col = _emit_rnea(em, model, tf, [0.0] * n, e, [0.0, 0.0, 0.0])
            for i in range(k, n):
                Mx[i][k] = col[i]
                Mx[k][i] = col[i]
        return Mx

    em = _Emitter()
    tf = _emit_transforms(em, model, q)
    Mx = mass_columns(em, tf)
    sources.append(_function("mass", ["q"], em, {"q": q}, [Mx[i][j] for i in range(n)
                                                           for j in range(n)]))

    em = _Emitter()
    tf = _emit_transforms(em, model, q)
    h = _emit_rnea(em, model, tf, qd, [0.0] * n, gv)
    Mx = mass_columns(em, tf)
    Ma = [[em.add(Mx[i][j], arm[i]) if i == j else Mx[i][j] for j in range(n)]
          for i in range(n)]
    rhs = [em.lin([(1.0, tau_in[i], 1.0), (-1.0, h[i], 1.0)]) for i in range(n)]
    out = _ldl_solve(em, Ma, rhs)
    sources.append(_function("fd", ["q", "qd", "tau", "g", "armature"], em,
                             {"q": q, "qd": qd, "tau": tau_in, "g": gv, "armature": arm}, out))

    em = _Emitter()
    tf = _emit_transforms(em, model, q)
    Rb: list[Vec] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    pb: Vec = [0.0, 0.0, 0.0]
    frames_out: list[Sym] = []
    for i in range(n):
        pb = em.vadd(pb, em.matvec(Rb, tf.P[i]))
        Rb = [[em.lin([(1.0, Rb[r][k], tf.R[i][k][c]) for k in range(3)]) for c in range(3)]
              for r in range(3)]
        frames_out += [Rb[r][c] for r in range(3) for c in range(3)] + list(pb)
    sources.append(_function("frames", ["q"], em, {"q": q}, frames_out))

    # The end effector's pose and geometric Jacobian (thesis eq. 3.13, 3.17), base frame:
    # column i = [z_i × (p_e − o_i); z_i] (revolute) or [z_i; 0] (prismatic).
    em = _Emitter()
    tf = _emit_transforms(em, model, q)
    Rb = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    pb = [0.0, 0.0, 0.0]
    zs: list[Vec] = []
    origins: list[Vec] = []
    for i, joint in enumerate(model.joints):
        R0 = joint.origin[:3, :3]
        pb = em.vadd(pb, em.matvec(Rb, tf.P[i]) if joint.kind != "prismatic"
                     else em.matvec(Rb, _cvec(joint.origin[:3, 3])))
        R_joint0 = [[em.lin([(1.0, Rb[r][k], _snap(R0[k, c])) for k in range(3)])
                     for c in range(3)] for r in range(3)]  # base <- joint frame at q = 0
        z = em.matvec(R_joint0, _cvec(joint.axis))
        if joint.kind == "prismatic":
            pb = em.vadd(pb, em.vscale(q[i], z))
        zs.append(z)
        origins.append(pb)
        Rb = [[em.lin([(1.0, Rb[r][k], tf.R[i][k][c]) for k in range(3)]) for c in range(3)]
              for r in range(3)]
    tip_R, tip_p = model.tip[:3, :3], model.tip[:3, 3]
    pe = em.vadd(pb, em.matvec(Rb, _cvec(tip_p)))
    Re = [[em.lin([(1.0, Rb[r][k], _snap(tip_R[k, c])) for k in range(3)]) for c in range(3)]
          for r in range(3)]
    cols: list[list[Sym]] = []
    for joint, z, o in zip(model.joints, zs, origins, strict=True):
        if joint.kind == "prismatic":
            cols.append(list(z) + [0.0, 0.0, 0.0])
        else:
            d = [em.lin([(1.0, pe[r], 1.0), (-1.0, o[r], 1.0)]) for r in range(3)]
            cols.append(list(em.cross(z, d)) + list(z))
    pose = [x for r in range(3) for x in (*Re[r], pe[r])] + [0.0, 0.0, 0.0, 1.0]
    tip_out = pose + [col[r] for r in range(6) for col in cols]
    sources.append(_function("tip", ["q"], em, {"q": q}, tip_out))

    source = "\n\n".join(sources) + "\n"
    # Any: the functions the generated source defines, each the field of its name below
    namespace: dict[str, Any] = {"_sin": math.sin, "_cos": math.cos}
    exec(compile(source, f"<dynamics of {model.name}>", "exec"), namespace)  # noqa: S102
    return DynamicsModel(
        n=n,
        revolute=tuple(j.kind != "prismatic" for j in model.joints),
        axes=tuple(cast("tuple[float, float, float]", tuple(float(x) for x in j.axis))  # (3,)
                   for j in model.joints),
        source=source,
        rnea=namespace["rnea"],
        bias=namespace["bias"],
        mass=namespace["mass"],
        fd=namespace["fd"],
        frames=namespace["frames"],
        tip=namespace["tip"],
    )


_CACHE_KEY = "_armlab_dynamics_model"


def dynamics_model(model: SerialChain) -> DynamicsModel:
    """The compiled :class:`DynamicsModel` of ``model``, built on first use and memoised."""
    cached = model.__dict__.get(_CACHE_KEY)
    if cached is None:
        if not isinstance(getattr(model, "joints", None), tuple):  # e.g. a whole quadruped
            raise ValueError(f"model must be a SerialChain, got {type(model).__name__}")
        cached = _build(model)
        model.__dict__[_CACHE_KEY] = cached  # the fields of the frozen model stay untouched
    return cached
