"""The walls' push on a class's arms, compiled to machine code (numba).

``BatchedPlant._wall_torques`` works out, at every RK4 stage of every step, the push of
each wall on the touch its arm holds (the held depth less nᵀJ (q − q₀), the normal speed
nᵀJ q̇, the push max(0, k·depth − c·vₙ), its Coulomb friction against the sliding
velocity) as numpy over the touches. :func:`held_pushes` is the same arithmetic per
touch, in its order, for the usual case of one touch per arm; numba compiles it in a
thread (:class:`armlab.kinematics.machine_code.MachineCode`) and its results equal the
numpy code's bit for bit (a test steps a class both ways).

``BatchedPlant._near_walls`` works out, once a step, which touches are near their walls.
For the usual case of plane walls (each arm's hand tip against its own plane),
:func:`plane_asks` and :func:`plane_touches` are its arithmetic before and after the
forward kinematics of the arms it asks about, in its order.
"""

from __future__ import annotations

import math

import numpy as np

from armlab.kinematics.machine_code import Kernel, MachineCode

A = np.ndarray  # (every array argument; numba reads the types off the arrays)


def held_pushes(q: A, qd: A, rows: A, q0: A, along: A, depth0: A, k: A, c: A, mu: A,
                cols: A, normal: A, rubs: bool, friction_damping: float,
                tau: A, mag: A) -> None:
    """``tau`` (n, T) = J^T F and ``mag`` (T,) N, written, of T touches (one per arm row
    ``rows`` (T,)) at (q, qd) (n, N): ``q0`` (n, T) the state their hold was taken at,
    ``along`` (n, T) nᵀJ there, ``depth0`` (T,) m their depth then, ``k``, ``c``, ``mu``
    (T,) stiffness, damping and friction, ``cols`` (n, 3, T) J's columns, ``normal``
    (3, T); friction only when ``rubs`` (capped at ``friction_damping`` · sliding speed)."""
    n = q.shape[0]
    for t in range(rows.shape[0]):
        r = rows[t]
        moved = along[0, t] * (q[0, r] - q0[0, t])
        vn = along[0, t] * qd[0, r]
        for j in range(1, n):
            moved += along[j, t] * (q[j, r] - q0[j, t])
            vn += along[j, t] * qd[j, r]
        depth = depth0[t] - moved
        push = 0.0
        if depth > 0.0:
            push = k[t] * depth - c[t] * vn
            if not push > 0.0:
                push = 0.0
        mag[t] = push
        for j in range(n):
            tau[j, t] = along[j, t] * push
        if rubs:
            s0 = cols[0, 0, t] * qd[0, r]
            s1 = cols[0, 1, t] * qd[0, r]
            s2 = cols[0, 2, t] * qd[0, r]
            for j in range(1, n):
                s0 += cols[j, 0, t] * qd[j, r]
                s1 += cols[j, 1, t] * qd[j, r]
                s2 += cols[j, 2, t] * qd[j, r]
            s0 -= vn * normal[0, t]
            s1 -= vn * normal[1, t]
            s2 -= vn * normal[2, t]
            speed = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
            cap = min(mu[t] * push, friction_damping * speed)
            scale = -cap / speed if speed > 0.0 else 0.0
            r0, r1, r2 = scale * s0, scale * s1, scale * s2
            for j in range(n):
                tau[j, t] = tau[j, t] + (cols[j, 0, t] * r0 + cols[j, 1, t] * r1
                                         + cols[j, 2, t] * r2)


def plane_asks(w_rows: A, point: A, qd: A, reach: float, dt: float, gap: A,
               margin: float, travel: A, ask: A) -> int:
    """``travel`` (W,) m, written, that arm rows ``w_rows`` (W,)'s touches may move in a
    step (2 dt · (``reach`` + |its touch point|) · Σ|θ̇|, ``point`` (3, N) in its link's
    frame, ``qd`` (n, N)), and ``ask`` (W,) written: the places in ``w_rows`` whose
    ``gap`` (N,) m, their nearest's distance as last worked out, is under ``margin`` +
    travel (those may be close). Returns how many of ``ask`` are filled."""
    n = qd.shape[0]
    asked = 0
    for w in range(w_rows.shape[0]):
        r = w_rows[w]
        size = math.sqrt(point[0, r] * point[0, r] + point[1, r] * point[1, r]
                         + point[2, r] * point[2, r])
        speed = abs(qd[0, r])
        for j in range(1, n):
            speed += abs(qd[j, r])
        travel[w] = 2.0 * dt * (reach + size) * speed
        if gap[r] < margin + travel[w]:
            ask[asked] = w
            asked += 1
    return asked


def plane_touches(w_rows: A, ask: A, p: A, cols: A, origin: A, normal: A, travel: A,
                  margin: float, gap: A, touch_rows: A, t_cols: A, depth: A,
                  t_normal: A, along: A) -> int:
    """The touches of arm rows ``w_rows[ask]`` (A,) near their plane walls: ``p`` (3, A)
    their tips in the base frame, ``cols`` (n, 3, A) their Jacobian columns, the walls'
    ``origin`` and ``normal`` (3, N), ``travel`` (W,) m as :func:`plane_asks` wrote it.
    Writes each asked row's ``gap`` (N,) (its tip's signed distance), then, for each tip
    within ``margin`` + travel of its wall, its row into ``touch_rows``, its columns,
    depth inside (−distance), the wall's normal and nᵀJ into ``t_cols`` (n, 3, ·),
    ``depth`` (·), ``t_normal`` (3, ·) and ``along`` (n, ·); and last every walled row's
    gap less its travel (at the step's end it is at least that far). Returns how many
    touches are written."""
    n = cols.shape[0]
    near = 0
    for a in range(ask.shape[0]):
        w = ask[a]
        r = w_rows[w]
        n0, n1, n2 = normal[0, r], normal[1, r], normal[2, r]
        dist = ((p[0, a] - origin[0, r]) * n0 + (p[1, a] - origin[1, r]) * n1
                + (p[2, a] - origin[2, r]) * n2)
        inside = 0.0 - dist
        gap[r] = dist
        if inside > -(margin + travel[w]):
            touch_rows[near] = r
            depth[near] = inside
            t_normal[0, near], t_normal[1, near], t_normal[2, near] = n0, n1, n2
            for j in range(n):
                c0, c1, c2 = cols[j, 0, a], cols[j, 1, a], cols[j, 2, a]
                t_cols[j, 0, near], t_cols[j, 1, near], t_cols[j, 2, near] = c0, c1, c2
                along[j, near] = c0 * n0 + c1 * n1 + c2 * n2
            near += 1
    for w in range(w_rows.shape[0]):
        r = w_rows[w]
        gap[r] = gap[r] - travel[w]
    return near


def _build() -> dict[str, Kernel]:
    import numba

    signature = ("void(f8[:, ::1], f8[:, ::1], i8[::1], f8[:, ::1], f8[:, ::1], f8[::1], "
                 "f8[::1], f8[::1], f8[::1], f8[:, :, ::1], f8[:, ::1], b1, f8, "
                 "f8[:, ::1], f8[::1])")
    asks = ("i8(i8[::1], f8[:, ::1], f8[:, ::1], f8, f8, f8[::1], f8, f8[::1], i8[::1])")
    touches = ("i8(i8[::1], i8[::1], f8[:, ::1], f8[:, :, ::1], f8[:, ::1], f8[:, ::1], "
               "f8[::1], f8, f8[::1], i8[::1], f8[:, :, ::1], f8[::1], f8[:, ::1], "
               "f8[:, ::1])")
    return {"pushes": numba.njit(signature, nogil=True, cache=True)(held_pushes),
            "plane_asks": numba.njit(asks, nogil=True, cache=True)(plane_asks),
            "plane_touches": numba.njit(touches, nogil=True, cache=True)(plane_touches)}


#: the process's compiled :func:`held_pushes` (any chain, any number of touches)
MACHINE = MachineCode(_build, "the walls' pushes")
