"""Contact with the world: a static obstacle (a wall: a plane; a table top or a block: a
box) and the points and balls of the arm that touch it.

The normal force at a contact is a spring on the penetration and a damper on its rate,
never pulling: f_n = max(0, k·p − c·ṗ_n), p the depth of the ball's surface inside the
obstacle (a point: a ball of radius 0), along the obstacle's outward normal there. Along
the surface, Coulomb friction μ·f_n against the sliding, regularised as a damper
:data:`FRICTION_DAMPING` on the sliding speed capped at μ·f_n (a "stick" that never does
work on the arm: its power −|f_t|·|v_t| ≤ 0). The plant evaluates them at each RK4 stage
(:meth:`armlab.hardware.sim.plant.Plant.set_wall`).

How a step evaluates them: at the step's start, each touch that the joints' speeds can
bring within :data:`HOLD_MARGIN_M` of the obstacle in the step is *held*
(:class:`HeldTouch`): its Jacobian columns J (thesis eq. 3.17), its depth and the
obstacle's normal at its nearest point there. At each RK4 stage the touch's depth is
then depth − n · J (q − q₀) and its velocity J q̇ (:func:`held_push`): the first-order
expansion of where the touch is, exact at the step's start, off by under
½ |∂²p/∂q²| |Δq|² within a 1 ms step (some 10⁻⁷ m at 1 rad/s). One forward kinematics a
step instead of one a stage: the force at the step's end, which the loop records, is the
next step's start, so it costs none of its own. The spring and damper act on that depth
at every stage, so the contact's own dynamics keep RK4's accuracy (an arm dropped on a
table comes to rest, never bouncing higher: tests/test_contact_shapes.py).

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


#: m: a touch farther than this from the obstacle, beyond what the joints' speeds can
#: move it in a step (2 dt · reach · Σ|θ̇|), is left out of that step: it can push nothing
HOLD_MARGIN_M = 0.005


@dataclass(frozen=True)
class HeldTouch:
    """A touch near the obstacle as one step holds it, from the step's start (q₀): its
    Jacobian columns ``cols`` (3,) for joints 0..its link (thesis eq. 3.17), ``along``
    those columns along the normal (nᵀJ: the depth's rate per joint), its ``depth`` m
    inside the obstacle (negative: outside) and the obstacle's outward ``normal`` (3,) at
    its nearest point (module docstring)."""

    cols: tuple[Vec, ...]
    along: tuple[float, ...]
    depth: float
    normal: Vec


_NO_FORCE = (0.0, 0.0, 0.0)


def held_touch(cols: Sequence[Vec], depth: float, normal: Vec) -> HeldTouch:
    """The :class:`HeldTouch` of a touch ``depth`` m inside the obstacle, of Jacobian
    columns ``cols`` and outward ``normal`` there."""
    n0, n1, n2 = normal
    return HeldTouch(tuple(cols), tuple(c[0] * n0 + c[1] * n1 + c[2] * n2 for c in cols),
                     depth, normal)


def held_push(ob: Obstacle, held: HeldTouch, dq: Sequence[float], qd: Sequence[float],
              tau: list[float]) -> float:
    """N of the obstacle's normal push on ``held`` at joint offsets ``dq`` = q − q₀ (n,)
    from the step's start and speeds ``qd`` (n,) (0 clear of it), its Jᵀf with friction
    added to ``tau`` (n,) N·m: depth − nᵀJ dq inside, its normal speed nᵀJ q̇, the push
    max(0, k·depth − c·vₙ); the friction against the sliding J q̇ − vₙ n, the damper
    :data:`FRICTION_DAMPING` on its speed capped at μ·push (sums in joint order)."""
    along = held.along
    dn = vn = 0.0
    for a, x, w in zip(along, dq, qd, strict=False):  # (joints past its link: none)
        dn += a * x
        vn += a * w
    depth = held.depth - dn
    if depth <= 0.0:
        return 0.0
    mag = max(0.0, ob.stiffness * depth - ob.damping * vn)
    if mag == 0.0:
        return 0.0
    if ob.friction <= 0.0:
        for j, a in enumerate(along):
            tau[j] += mag * a
        return mag
    nrm, cols = held.normal, held.cols
    vx = vy = vz = 0.0
    for col, w in zip(cols, qd, strict=False):
        vx += col[0] * w
        vy += col[1] * w
        vz += col[2] * w
    rx, ry, rz = rub(ob, mag, (vx - vn * nrm[0], vy - vn * nrm[1], vz - vn * nrm[2]))
    for j, (a, col) in enumerate(zip(along, cols, strict=True)):
        tau[j] += mag * a + (col[0] * rx + col[1] * ry + col[2] * rz)
    return mag


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
    floats: the plant asks it for every touch near the obstacle at every step.)"""
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


def rub(ob: Obstacle, push_n: float, slide: Sequence[float]) -> tuple[float, float, float]:
    """(3,) N of the obstacle's friction on a touch sliding at ``slide`` (3,) m/s along
    its surface while it pushes ``push_n`` N: opposing the sliding, the damper
    :data:`FRICTION_DAMPING` on its speed capped at Coulomb's μ·push. It never does work on
    the arm: it only takes energy out."""
    sx, sy, sz = slide
    speed = math.sqrt(sx * sx + sy * sy + sz * sz)
    if push_n <= 0.0 or ob.friction <= 0.0 or speed <= 0.0:
        return _NO_FORCE
    scale = -min(ob.friction * push_n, FRICTION_DAMPING * speed) / speed
    return scale * sx, scale * sy, scale * sz


def clear(ob: Obstacle, centre: Sequence[float], reach: float) -> bool:
    """Whether a ball of radius ``reach`` centred at ``centre`` (3,) is clear of the
    obstacle (nothing inside it can touch)."""
    return surface(ob, centre)[0] > reach
