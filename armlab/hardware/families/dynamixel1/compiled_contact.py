"""The walls' push on a class's arms, compiled to machine code (numba).

``BatchedPlant._wall_torques`` works out, at every RK4 stage of every step, the push of
each wall on the touch its arm holds (the held depth less nᵀJ (q − q₀), the normal speed
nᵀJ q̇, the push max(0, k·depth − c·vₙ), its Coulomb friction against the sliding
velocity) as numpy over the touches. :func:`held_pushes` is the same arithmetic per
touch, in its order, for the usual case of one touch per arm; numba compiles it in a
thread (:class:`armlab.kinematics.machine_code.MachineCode`) and its results equal the
numpy code's bit for bit (a test steps a class both ways).
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


def _build() -> dict[str, Kernel]:
    import numba

    signature = ("void(f8[:, ::1], f8[:, ::1], i8[::1], f8[:, ::1], f8[:, ::1], f8[::1], "
                 "f8[::1], f8[::1], f8[::1], f8[:, :, ::1], f8[:, ::1], b1, f8, "
                 "f8[:, ::1], f8[::1])")
    return {"pushes": numba.njit(signature, nogil=True, cache=True)(held_pushes)}


#: the process's compiled :func:`held_pushes` (any chain, any number of touches)
MACHINE = MachineCode(_build, "the walls' pushes")
