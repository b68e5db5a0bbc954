"""Static stability of a walking robot: support polygon, centre of mass, stability margin.

Not in seed 003 (its conclusion suggests "centre of gravity" control as future work);
the textbook static criterion (McGhee & Frank 1968): a robot standing still on its
stance feet does not tip over while the vertical projection of its centre of mass lies
inside the support polygon, the convex hull of the stance feet. The static stability
margin is the distance from that projection to the nearest edge of the polygon,
negative when it lies outside. Two feet make a line (a degenerate polygon): the margin
is then minus the distance to that line segment, never positive, which is why a trot
is not statically stable.

Shapes: points on the floor are (k, 2) arrays (x, y), m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from armlab.kinematics.model import Quadruped
from armlab.kinematics.quadruped import DEFAULT_GEOMETRY, LEGS, QuadrupedGeometry, leg_to_body


def support_polygon(feet_xy: np.ndarray) -> np.ndarray:
    """Convex hull of the stance feet, counter-clockwise, without collinear points.

    Args:
        feet_xy: (k, 2) floor positions of the stance feet.

    Returns:
        (h, 2) hull vertices, h <= k (h = 2 for feet on a line, 1 for one foot).
    """
    pts = sorted({(x, y) for x, y in np.asarray(feet_xy, dtype=float).reshape(-1, 2).tolist()})
    if len(pts) <= 2:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    hull = lower[:-1] + upper[:-1]
    return np.array(hull, dtype=float)


def nearest_on_polygon(p: Sequence[float] | np.ndarray, hull: np.ndarray
                       ) -> tuple[float, float]:
    """(x, y) point of the polygon ``hull`` (h, 2)'s boundary nearest to ``p`` (2,): on its
    edges, on the segment for h = 2, the point for h = 1. Floats, not numpy: a walking
    robot's loop and each of its pages find it every period for at most four corners."""
    px, py = (float(v) for v in p[:2])
    pts = np.asarray(hull, dtype=float).tolist()
    best, best_d = (pts[0][0], pts[0][1]), math.inf
    edges = len(pts) if len(pts) > 2 else len(pts) - 1
    for i in range(edges):
        (ax, ay), (bx, by) = pts[i], pts[(i + 1) % len(pts)]
        abx, aby = bx - ax, by - ay
        l2 = abx * abx + aby * aby
        t = 0.0 if l2 == 0.0 else min(1.0, max(0.0, ((px - ax) * abx + (py - ay) * aby) / l2))
        cx, cy = ax + t * abx, ay + t * aby
        d = math.hypot(px - cx, py - cy)
        if d < best_d:
            best, best_d = (cx, cy), d
    return best


def stability_margin(com_xy: Sequence[float] | np.ndarray, feet_xy: np.ndarray, *,
                     hull: np.ndarray | None = None) -> float:
    """Static stability margin, m: distance from the centre-of-mass projection to the
    nearest edge of the support polygon, positive inside, negative outside.

    With two stance feet the polygon is a segment and the margin is minus the distance
    to it (0 when the projection is on it); with one foot, minus the distance to it;
    with none, −inf.

    Args:
        com_xy: (2,) projection of the centre of mass on the floor.
        feet_xy: (k, 2) stance feet on the floor.
        hull: their :func:`support_polygon`, when the caller has it.
    """
    px, py = (float(v) for v in com_xy[:2])
    hull = support_polygon(feet_xy) if hull is None else hull
    if len(hull) == 0:
        return -math.inf
    nx, ny = nearest_on_polygon((px, py), hull)
    d = math.hypot(px - nx, py - ny)
    if len(hull) <= 2:
        return -d
    pts = hull.tolist()
    inside = all((bx - ax) * (py - ay) - (by - ay) * (px - ax) >= 0.0
                 for (ax, ay), (bx, by) in zip(pts, pts[1:] + pts[:1], strict=True))
    return d if inside else -d


def centre_of_mass(angles: dict[str, np.ndarray], geom: QuadrupedGeometry = DEFAULT_GEOMETRY
                   ) -> np.ndarray:
    """(3,) centre of mass in the body frame, from the geometry's point masses.

    The body's mass sits at the body origin, each coxa's at its hip, each femur's and
    tibia's at the middle of the link (as in ``quadruped_urdf``).

    Args:
        angles: leg name → (θ1, θ2, θ3), rad (seed 003 joint angles).
    """
    l1, l2 = geom.leg.femur, geom.leg.tibia
    total = geom.body_mass
    moment = np.zeros(3)
    for leg in LEGS:
        t1, t2, t3 = (float(a) for a in angles[leg])
        u = np.array([math.sin(t1), math.cos(t1), 0.0])  # outward after yaw, leg frame
        knee = l1 * (math.cos(t2) * u - np.array([0.0, 0.0, math.sin(t2)]))
        shin = l2 * (math.cos(t2 + t3) * u - np.array([0.0, 0.0, math.sin(t2 + t3)]))
        for m, p in ((geom.coxa_mass, np.zeros(3)), (geom.femur_mass, knee / 2),
                     (geom.tibia_mass, knee + shin / 2)):
            moment += m * leg_to_body(p, leg, geom)
            total += m
    return moment / total


def centre_of_mass_model(robot: Quadruped, angles: dict[str, np.ndarray]) -> np.ndarray:
    """(3,) centre of mass in the body frame from a loaded quadruped model's inertials.

    Assumes the body link's own centre of mass at the body frame's origin (true for
    ``quadruped_urdf``); the legs' links use their URDF masses and centres.
    """
    total = robot.body_mass
    moment = np.zeros(3)
    for leg, chain in robot.legs.items():
        poses = chain.link_poses(np.asarray(angles[leg], dtype=float))
        for pose, link in zip(poses, chain.links, strict=True):
            world = chain.base_pose @ pose
            moment += link.mass * (world[:3, :3] @ link.com + world[:3, 3])
            total += link.mass
    return moment / total
