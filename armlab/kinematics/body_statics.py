"""The quadruped's body resting on its feet: floor plane, contact forces, tilt (quasi-static).

Seed 003 reports 3.6–5.7° of body tilt on flat ground and a 1.201 % servo error
(eq. 4.1), both caused by the servos giving way under the robot's weight. This
module holds the statics of that, as pure functions of the feet's positions in the
body frame (from the joint angles the servos actually hold) and the centre of mass:

1. :func:`rest_plane`: the floor seen from the body. A rigid body on point feet rests
   on a face of the feet's lower convex hull, the one whose contact polygon holds the
   centre of mass (the body is free to tilt until that holds). Standing on a trot's
   diagonal, the centre of mass is off the support line, so the body tips about it
   until the swing foot on that side touches: three contacts.
2. :func:`contact_forces`: the floor's normal force on each contact foot, from force
   and moment balance (three feet: exact; four: least-norm; two: the lever rule).
3. :func:`tilt_deg`: the angle between the floor's normal and the body's z axis.

The servos' compliance enters through the feet's positions: a loaded leg's servos
give way (J^T f on each joint against its compliance margin, slope and punch; see
``armlab.hardware.families.dynamixel1.quadruped``), the foot rises in the body frame, and the plane
through the deflected contact feet is the body's pose.

Frames: body frame x forward, y left, z up; feet (4, 3) in ``LEGS`` order, m.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

from armlab.kinematics.batched_dynamics import batched_dynamics
from armlab.kinematics.model import Quadruped
from armlab.kinematics.smallarrays import cross3

#: A foot within this distance of the rest plane touches the floor, m.
CONTACT_TOL = 1e-3


def _plane(p: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Unit normal n (n_z > 0) and offset d of the plane n·x = d through three points."""
    n = np.array(cross3((p[1] - p[0]).tolist(), (p[2] - p[0]).tolist()))
    norm = float(np.linalg.norm(n))
    if norm < 1e-12 or abs(n[2]) < 0.5 * norm:  # degenerate, or steeper than 60°
        return None
    n = n / norm * math.copysign(1.0, n[2])
    return n, float(n @ p[0])


def _in_triangle(c: np.ndarray, tri: np.ndarray, n: np.ndarray) -> bool:
    """Whether ``c`` projected along ``n`` falls inside the triangle ``tri`` (3, 3)."""
    s = [float(n @ np.array(cross3((tri[(k + 1) % 3] - tri[k]).tolist(),
                                   (c - tri[k]).tolist()))) for k in range(3)]
    return min(s) >= -1e-12 or max(s) <= 1e-12


def rest_plane(feet: np.ndarray, com: np.ndarray, *, tol: float = CONTACT_TOL
               ) -> tuple[np.ndarray, float, np.ndarray]:
    """The floor plane the body rests on, and which feet touch it.

    Args:
        feet: (4, 3) feet in the body frame, m.
        com: (3,) centre of mass in the body frame, m.

    Returns:
        (n, d, contact): the floor's unit normal n (3,) pointing up into the body, its
        offset d (the floor is n·x = d), and the (4,) bool contact flags. Among the
        planes through three feet with every foot on or above it (a face of the
        feet's lower hull), the one whose triangle holds the centre of mass seen
        along the body's z axis (else along the face's normal); if none does (the
        robot would fall over), the least tilted such face.
    """
    feet = np.asarray(feet, dtype=float)
    faces: list[tuple[np.ndarray, float, np.ndarray]] = []
    for tri in itertools.combinations(range(len(feet)), 3):
        pl = _plane(feet[list(tri)])
        if pl is None:
            continue
        n, d = pl
        if np.any(feet @ n < d - tol):  # a foot below this plane: not a resting face
            continue
        faces.append((n, d, feet[list(tri)]))
    if not faces:
        raise ValueError("feet: no three feet span a plane under the body")
    chosen: tuple[np.ndarray, float] | None = None
    # The side the centre of mass lies on with the body level decides which way it tips
    # (a body that leans is held there too: its centre of mass moves with the lean).
    for axis in (np.array([0.0, 0.0, 1.0]), None):
        for n, d, corners in faces:
            if _in_triangle(com, corners, n if axis is None else axis):
                chosen = (n, d)
                break
        if chosen is not None:
            break
    if chosen is None:  # it would fall over: the least tilted face
        n, d, _ = max(faces, key=lambda f: float(f[0][2]))
        chosen = (n, d)
    n, d = chosen
    return n, d, np.abs(feet @ n - d) <= tol


def contact_forces(feet: np.ndarray, com: np.ndarray, weight: float, n: np.ndarray
                   ) -> np.ndarray:
    """Normal force (N) of the floor on each of ``feet`` (k, 3) that carry ``weight`` N.

    Force balance along n and moment balance about the axes in the floor plane, with the
    centre of mass ``com`` (3,) projected along n. Two feet: the lever rule along their
    line; three: the exact solution; four: the least-norm one. Negative shares (centre
    of mass outside the feet) are clipped to 0 and the rest renormalised.
    """
    feet = np.asarray(feet, dtype=float)
    k = len(feet)
    if k == 0:
        return np.zeros(0)
    if k == 1:
        return np.array([float(weight)])
    # coordinates in the floor plane
    e1 = np.array(cross3(np.asarray(n, dtype=float).tolist(), (0.0, 1.0, 0.0)))
    e1 /= np.linalg.norm(e1)
    e2 = np.array(cross3(np.asarray(n, dtype=float).tolist(), e1.tolist()))
    uv = np.stack([(feet - com) @ e1, (feet - com) @ e2])  # (2, k)
    if k == 2:
        a, b = uv[:, 0], uv[:, 1]
        ab = b - a
        s = float(np.clip(-(a @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0))
        shares = np.array([1.0 - s, s])
    else:
        A = np.vstack([np.ones(k), uv])
        shares = np.linalg.lstsq(A, np.array([1.0, 0.0, 0.0]), rcond=None)[0]
        shares = np.clip(shares, 0.0, None)
        shares /= shares.sum()
    return float(weight) * shares


def feet_and_com(model: Quadruped, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Feet (4, 3) and centre of mass (3,) in the body frame for the joint angles ``q`` (12,)
    rad (legs in order), m: one pass over each leg's link poses.

    The centre of mass is :func:`armlab.kinematics.stability.centre_of_mass_model`'s (the body's
    own at the body origin).
    """
    q = np.asarray(q, dtype=float).reshape(len(model.legs), -1)
    feet = np.empty((len(model.legs), 3))
    total, moment = model.body_mass, np.zeros(3)
    for i, (chain, qi) in enumerate(zip(model.legs.values(), q, strict=True)):
        poses = chain.base_pose @ chain.link_poses(qi)
        feet[i] = (poses[-1] @ chain.tip)[:3, 3]
        for pose, link in zip(poses, chain.links, strict=True):
            moment += link.mass * (pose[:3, :3] @ link.com + pose[:3, 3])
            total += link.mass
    return feet, moment / total


def feet_in_body(model: Quadruped, q: np.ndarray) -> np.ndarray:
    """(4, 3) feet in the body frame for the (12,) joint angles ``q`` (legs in order), m."""
    return feet_and_com(model, q)[0]


def rest_pose(model: Quadruped, q: np.ndarray
              ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]:
    """How the body rests on the floor with the legs at ``q`` (12,) rad.

    Returns:
        (n, d, contact, feet, com): the floor's normal in the body frame (3,) and offset
        (the floor is n·x = d, so −d is how far below the body's origin it lies, m), the
        (4,) contact flags, the feet (4, 3) and the centre of mass (3,) in the body
        frame, m.

    Raises:
        ValueError: when no three feet span a plane under the body.
    """
    feet, com = feet_and_com(model, q)
    n, d, contact = rest_plane(feet, com)
    return n, d, contact, feet, com


def implied_tilt_deg(model: Quadruped, q: np.ndarray) -> float:
    """The body's tilt (degrees) that the legs at ``q`` (12,) rad imply on flat ground.

    With the angles the servos report, this is the tilt their giving way causes
    (seed 003: 3.6–5.7° on flat ground).
    """
    return tilt_deg(rest_pose(model, q)[0])


def tilt_deg(n: np.ndarray) -> float:
    """Tilt of the body, degrees: the angle between the floor's normal and body z."""
    return math.degrees(math.acos(float(np.clip(n[2], -1.0, 1.0))))


#: The four triangles of feet, in :func:`rest_plane`'s order.
TRIANGLES = tuple(itertools.combinations(range(4), 3))


# -- over robots: the functions above, numpy over R robots (a class of quadrupeds) -------

def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b over the last axis (3): ``numpy.cross``'s products, without its overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def feet_and_coms(model: Quadruped, q: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Feet (R, 4, 3) and centres of mass (R, 3) in the body frame, m, of R robots whose
    legs are at ``q``: per leg in ``model.legs`` order its joint angles (R, 3) rad
    (:func:`feet_and_com` over robots)."""
    rows = q[0].shape[0]
    feet = np.empty((rows, len(model.legs), 3))
    total, moment = model.body_mass, np.zeros((rows, 3))
    for i, (chain, qi) in enumerate(zip(model.legs.values(), q, strict=True)):
        fr = batched_dynamics(chain).frames(np.ascontiguousarray(qi.T)).reshape(chain.n, 12, rows)
        rot = fr[:, :9].transpose(0, 2, 1).reshape(chain.n, rows, 3, 3)  # base <- link
        origin = fr[:, 9:].transpose(0, 2, 1)  # (n, R, 3)
        rb, pb = chain.base_pose[:3, :3], chain.base_pose[:3, 3]
        tip = rot[-1] @ chain.tip[:3, 3] + origin[-1]
        feet[:, i] = tip @ rb.T + pb
        coms = np.array([link.com for link in chain.links])  # (n, 3), link frames
        masses = np.array([link.mass for link in chain.links])
        at = np.einsum("lrij,lj->lri", rot, coms) + origin  # (n, R, 3), base frame
        moment += np.einsum("l,lri->ri", masses, at @ rb.T + pb)
        total += float(masses.sum())
    return feet, moment / total


def rest_planes(feet: np.ndarray, com: np.ndarray, *, tol: float = CONTACT_TOL
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`rest_plane` of R robots: feet (R, 4, 3), com (R, 3), m.

    Returns:
        (n, d, contact, ok): the floor's unit normal (R, 3), offset (R,) (the floor is
        n·x = d), contact flags (R, 4), and (R,) whether three feet span a plane under
        the body at all (where not, ``rest_plane`` raises; n, d, contact are then
        meaningless).
    """
    rows = feet.shape[0]
    p = feet[:, np.array(TRIANGLES)]  # (R, 4 triangles, 3 corners, 3)
    nrm = _cross(p[:, :, 1] - p[:, :, 0], p[:, :, 2] - p[:, :, 0])  # (R, 4, 3)
    norm = np.sqrt(np.sum(nrm * nrm, axis=2))
    valid = (norm >= 1e-12) & (np.abs(nrm[:, :, 2]) >= 0.5 * norm)  # not degenerate, <= 60°
    normals = nrm / (np.where(valid, norm, 1.0) * np.where(nrm[:, :, 2] < 0, -1.0, 1.0))[..., None]
    offsets = np.sum(normals * p[:, :, 0], axis=2)
    # a resting face: no foot below it
    valid &= np.all(np.einsum("rkc,rtc->rtk", feet, normals) >= offsets[..., None] - tol, axis=2)
    # the centre of mass inside the triangle, seen along body z, then along the face's normal
    cross = _cross(p[:, :, [1, 2, 0]] - p, com[:, None, None, :] - p)  # (R, 4, 3 edges, 3)
    s_z = cross[..., 2]
    s_n = np.sum(cross * normals[:, :, None, :], axis=3)
    in_z = (s_z.min(axis=2) >= -1e-12) | (s_z.max(axis=2) <= 1e-12)
    in_n = (s_n.min(axis=2) >= -1e-12) | (s_n.max(axis=2) <= 1e-12)
    first_z, first_n = valid & in_z, valid & in_n
    least_tilted = np.argmax(np.where(valid, normals[:, :, 2], -np.inf), axis=1)
    choice = np.where(first_z.any(axis=1), np.argmax(first_z, axis=1),
                      np.where(first_n.any(axis=1), np.argmax(first_n, axis=1), least_tilted))
    r = np.arange(rows)
    n, d = normals[r, choice], offsets[r, choice]
    contact = np.abs(np.einsum("rkc,rc->rk", feet, n) - d[:, None]) <= tol
    return n, d, contact, valid.any(axis=1)


def floor_forces(feet: np.ndarray, com: np.ndarray, weight: np.ndarray, n: np.ndarray,
                 contact: np.ndarray) -> np.ndarray:
    """(R, 4) the floor's normal force on each foot, N: per robot
    :func:`contact_forces` of its contact feet carrying ``weight``
    (R,) N, 0 on the others (feet (R, 4, 3), com (R, 3), n (R, 3), contact (R, 4)).

    Three or four contacts (every rest plane has three): the least-norm shares of the
    moment balance for all robots at once; fewer: ``contact_forces`` per robot."""
    rows = feet.shape[0]
    f = np.zeros(contact.shape)
    k = contact.sum(axis=1)
    many = k >= 3
    if many.any():
        m = contact[many].astype(float)
        nn = n[many]
        e1 = np.stack([-nn[:, 2], np.zeros(len(nn)), nn[:, 0]], axis=1)  # n × y
        e1 /= np.sqrt(np.sum(e1 * e1, axis=1))[:, None]
        e2 = _cross(nn, e1)
        rel = feet[many] - com[many, None, :]
        a = np.stack([m, np.einsum("rkc,rc->rk", rel, e1) * m,
                      np.einsum("rkc,rc->rk", rel, e2) * m], axis=1)  # (R', 3, 4)
        y = np.linalg.solve(a @ a.transpose(0, 2, 1),
                            np.broadcast_to([1.0, 0.0, 0.0], (len(nn), 3))[..., None])
        shares = np.clip((a.transpose(0, 2, 1) @ y)[..., 0], 0.0, None)
        f[many] = weight[many, None] * shares / shares.sum(axis=1, keepdims=True)
    for r in np.flatnonzero(~many & (k > 0)):  # not from a rest plane: as BodyOnLegs
        f[r, contact[r]] = contact_forces(feet[r, contact[r]], com[r], float(weight[r]), n[r])
    assert f.shape == (rows, contact.shape[1])
    return f


def implied_tilts_deg(model: Quadruped, q: np.ndarray) -> np.ndarray:
    """:func:`implied_tilt_deg` of M poses ``q`` (M, 12) rad at once, degrees (M,).

    Raises:
        ValueError: a pose with no three feet under the body (as :func:`rest_pose`).
    """
    q = np.asarray(q, dtype=float).reshape(-1, 12)
    if not len(q):
        return np.zeros(0)
    feet, com = feet_and_coms(model, [q[:, 3 * k:3 * k + 3] for k in range(len(model.legs))])
    n, _, _, ok = rest_planes(feet, com)
    if not ok.all():
        raise ValueError("no three feet span a floor under the body")
    return np.degrees(np.arccos(np.clip(n[:, 2], -1.0, 1.0)))


__all__ = ["CONTACT_TOL", "rest_plane", "contact_forces", "tilt_deg", "feet_and_com",
           "feet_and_coms", "rest_planes", "floor_forces", "implied_tilts_deg",
           "feet_in_body", "rest_pose", "implied_tilt_deg"]
