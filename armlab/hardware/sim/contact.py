"""Contact with the world: a static obstacle (a wall: a plane; a table top or a block: a
box) and the points and balls of the arm that touch it.

The normal force at a contact is a spring on the penetration and a damper on its rate,
never pulling: f_n = max(0, k·p − c·ṗ_n), p the depth of the ball's surface inside the
obstacle (a point: a ball of radius 0), along the obstacle's outward normal there. Along
the surface, Coulomb friction μ·f_n against the sliding, regularised as a damper
:data:`FRICTION_DAMPING` on the sliding speed capped at μ·f_n (a "stick" that never does
work on the arm: its power −|f_t|·|v_t| ≤ 0). The plant integrates them at each RK4 stage
(:meth:`armlab.hardware.sim.plant.Plant.set_wall`).

A box (``size``: width and height across its face, thickness behind it) has one face on
the plane through ``origin`` with outward ``normal``; its other faces bound it. A ball
inside it is pushed out of the nearest face; outside it, away from its nearest point (an
edge or a corner too).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from armlab.control.backend import FRICTION_RANGE
from armlab.kinematics.validate import scalar, vector

Vec = tuple[float, float, float]

#: N·s/m: the slope of the wall's friction below its Coulomb limit (the regularised
#: "stick": a damper on the sliding speed, capped at μ·f_n). Explicit RK4 at the plant's
#: 1 ms step keeps a damper c stable on a mass m while c·dt/m stays below about 2.8; the
#: lightest hand the lab drives (the receptionist arm's, some 0.35 kg of link and
#: reflected rotor) takes 200 at 0.6
FRICTION_DAMPING = 200.0


@dataclass(frozen=True)
class Touch:
    """A point or ball of the arm that touches obstacles: on moving link ``link``, centred
    at ``point`` (3,) m in its frame, of ``radius`` m (0: a point)."""

    link: int
    point: Vec
    radius: float = 0.0


@dataclass(frozen=True)
class TouchGroup:
    """The touches of one link with the ball bounding them all (centre (3,) m in the
    link's frame, radius m): a group whose bounding ball is clear of the obstacle touches
    nothing (one test instead of one a ball)."""

    link: int
    centre: Vec
    reach: float
    touches: tuple[Touch, ...]


@dataclass(frozen=True)
class Obstacle:
    """A wall (``size`` None: the plane through ``origin`` (3,) m with unit ``normal``
    (3,) towards the free side) or a box (``size``: (width, height, thickness) m, its face
    on that plane, ``across`` and ``up`` (3,) the unit directions of its width and height),
    base frame; ``stiffness`` N/m, ``damping`` N·s/m, ``friction`` μ; the arm's touches
    grouped by link."""

    origin: Vec
    normal: Vec
    stiffness: float
    damping: float
    groups: tuple[TouchGroup, ...]
    friction: float = 0.0
    size: Vec | None = None
    across: Vec = (1.0, 0.0, 0.0)
    up: Vec = (0.0, 1.0, 0.0)


def face_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(across, up): unit directions across a face of unit ``normal``, across horizontal
    in the frame (perpendicular to z; x where the normal is along z), up = normal × across."""
    across = np.cross([0.0, 0.0, 1.0], normal)
    if np.linalg.norm(across) < 1e-6:
        across = np.array([1.0, 0.0, 0.0])
    across = across / np.linalg.norm(across)
    return across, np.cross(normal, across)


def checked_wall(origin_base: object, normal_base: object, stiffness: object, damping: object,
                 link: int | None, point: object, *, n: int, tip: np.ndarray,
                 link_index: Callable[[int], int],
                 ) -> tuple[np.ndarray, np.ndarray, float, float, int, np.ndarray]:
    """A wall's arguments checked (``Plant.set_wall``, ``BatchedPlant.set_wall``): origin
    (3,), unit normal (3,), stiffness, damping, the contact link's index and the contact
    point (3,) in its frame (the tip on the last link, else the link's origin).

    Raises:
        ValueError: naming the argument that is missing, zero, non-finite or out of range.
    """
    if normal_base is None:
        raise ValueError("normal_base is needed with a wall origin")
    nrm = vector("normal_base", normal_base, 3)
    length = float(np.linalg.norm(nrm))
    if length < 1e-9:
        raise ValueError("normal_base must not be zero")
    k = scalar("stiffness", stiffness, positive=True)
    c = scalar("damping", damping, nonnegative=True)
    li = n - 1 if link is None else link_index(link)
    pt = np.array(tip) if point is None else vector("point", point, 3)
    if point is None and link is not None and li != n - 1:
        pt = np.zeros(3)
    return vector("origin_base", origin_base, 3), nrm / length, k, c, li, pt


def checked_friction(friction: object) -> float:
    """A wall's friction μ checked: finite, in :data:`FRICTION_RANGE`."""
    mu = scalar("friction", friction, nonnegative=True)
    if not FRICTION_RANGE[0] <= mu <= FRICTION_RANGE[1]:
        raise ValueError(f"friction must be in {FRICTION_RANGE[0]:g}..{FRICTION_RANGE[1]:g}, "
                         f"got {mu:g}")
    return mu


#: m: the largest box side the lab takes (a table top is some 2 m at most)
SIZE_MAX = 10.0


def checked_size(size: object) -> Vec | None:
    """A box's (width, height, thickness) m checked: each finite and in (0, 10] m; None
    (a plane) stays None."""
    if size is None:
        return None
    s = vector("size", size, 3)
    if not all(0.0 < x <= SIZE_MAX for x in s):
        raise ValueError(f"size: each of width, height and thickness must be in "
                         f"(0, {SIZE_MAX:g}] m, got {s.tolist()}")
    return float(s[0]), float(s[1]), float(s[2])


#: touches a group holds at most: four neighbouring balls along a capsule, so an arm
#: resting on a table near its elbow looks at the few balls there, not its whole forearm
GROUP_SIZE = 4


def touch_groups(touches: Sequence[Touch]) -> tuple[TouchGroup, ...]:
    """``touches`` grouped by link in runs of :data:`GROUP_SIZE` (in their order: a
    capsule's balls are neighbours), each group with its bounding ball."""
    groups = []
    chunks: list[tuple[Touch, ...]] = []
    for link in sorted({t.link for t in touches}):
        on_link = [t for t in touches if t.link == link]
        chunks += [tuple(on_link[i:i + GROUP_SIZE]) for i in range(0, len(on_link), GROUP_SIZE)]
    for chunk in chunks:
        pts = np.array([t.point for t in chunk])
        centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
        reach = max(float(np.linalg.norm(np.array(t.point) - centre)) + t.radius for t in chunk)
        x, y, z = centre.tolist()
        groups.append(TouchGroup(chunk[0].link, (x, y, z), reach, chunk))
    return tuple(groups)


def surface(ob: Obstacle, p: Sequence[float]) -> tuple[float, Vec]:
    """(signed distance m, outward unit normal (3,)) of point ``p`` (3,) from the
    obstacle's surface: positive outside, negative inside; for a box, towards its nearest
    point outside (a face, an edge, a corner) or out of its nearest face inside. (Plain
    floats: the plant asks it for every touch at every RK4 stage.)"""
    o, nrm = ob.origin, ob.normal
    d0, d1, d2 = p[0] - o[0], p[1] - o[1], p[2] - o[2]
    h = d0 * nrm[0] + d1 * nrm[1] + d2 * nrm[2]
    if ob.size is None:
        return h, nrm
    ac, up = ob.across, ob.up
    x = d0 * ac[0] + d1 * ac[1] + d2 * ac[2]
    y = d0 * up[0] + d1 * up[1] + d2 * up[2]
    w, ht, th = ob.size
    z = h + th / 2  # from the box's middle along the normal
    sx, sy, sz = (1.0 if x >= 0 else -1.0), (1.0 if y >= 0 else -1.0), (1.0 if z >= 0 else -1.0)
    qx, qy, qz = abs(x) - w / 2, abs(y) - ht / 2, abs(z) - th / 2
    if qx > 0.0 or qy > 0.0 or qz > 0.0:  # outside: away from the nearest point
        ox, oy, oz = max(qx, 0.0) * sx, max(qy, 0.0) * sy, max(qz, 0.0) * sz
        dist = math.sqrt(ox * ox + oy * oy + oz * oz)
        lx, ly, lz = ox / dist, oy / dist, oz / dist
    elif qx >= qy and qx >= qz:  # inside: out of the nearest face
        dist, lx, ly, lz = qx, sx, 0.0, 0.0
    elif qy >= qz:
        dist, lx, ly, lz = qy, 0.0, sy, 0.0
    else:
        dist, lx, ly, lz = qz, 0.0, 0.0, sz
    return dist, (lx * ac[0] + ly * up[0] + lz * nrm[0], lx * ac[1] + ly * up[1] + lz * nrm[1],
                  lx * ac[2] + ly * up[2] + lz * nrm[2])


def normal_push(ob: Obstacle, depth: float, nrm: Sequence[float], v: Sequence[float]
                ) -> float:
    """N of the normal push on a touch ``depth`` m inside the obstacle (> 0) moving at
    ``v`` (3,) m/s, ``nrm`` the outward normal there: a spring on the penetration and a
    damper on its rate, never pulling."""
    vn = v[0] * nrm[0] + v[1] * nrm[1] + v[2] * nrm[2]
    return max(0.0, ob.stiffness * depth - ob.damping * vn)


def rub(ob: Obstacle, push_n: float, nrm: Sequence[float], v: Sequence[float]) -> list[float]:
    """(3,) N of the obstacle's friction on a touch moving at ``v`` (3,) while it pushes
    ``push_n`` N along ``nrm``: opposing the sliding (the velocity along the surface), the
    damper :data:`FRICTION_DAMPING` on its speed capped at Coulomb's μ·push. It never does
    work on the arm: it only takes energy out."""
    vn = v[0] * nrm[0] + v[1] * nrm[1] + v[2] * nrm[2]
    slide = [v[r] - vn * nrm[r] for r in range(3)]
    speed = math.sqrt(slide[0] ** 2 + slide[1] ** 2 + slide[2] ** 2)
    if push_n <= 0.0 or ob.friction <= 0.0 or speed <= 0.0:
        return [0.0, 0.0, 0.0]
    size = min(ob.friction * push_n, FRICTION_DAMPING * speed)
    return [-size * slide[r] / speed for r in range(3)]


def clear(ob: Obstacle, centre: Sequence[float], reach: float) -> bool:
    """Whether a ball of radius ``reach`` centred at ``centre`` (3,) is clear of the
    obstacle (nothing inside it can touch)."""
    return surface(ob, centre)[0] > reach
