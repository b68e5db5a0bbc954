"""Points riding on a link: their position, Jacobian and the joint torques of a force there.

Base-frame quantities of a point fixed in one link's frame (thesis eq. 3.14–3.15 applied
to any point, not only the tip). The link frames come from the chain's compiled
kinematics (:func:`armlab.kinematics._rnea_codegen.dynamics_model`).
"""

from __future__ import annotations

import numpy as np

from armlab.kinematics._rnea_codegen import dynamics_model
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import floats, vector


def point_position(model: SerialChain, q: np.ndarray, link: int, point: np.ndarray) -> np.ndarray:
    """(3,) base-frame position of ``point`` (3,) m given in link ``link``'s frame."""
    R, p = link_frames(model, floats("q", q, model.n))[_link_index(model, link)]
    return R @ vector("point", point, 3) + p


def point_jacobian(model: SerialChain, q: np.ndarray, link: int, point: np.ndarray) -> np.ndarray:
    """Linear Jacobian (3, n) of a point fixed on a link, base frame.

    Column j <= link is z_j × (p - o_j) for a revolute joint, z_j for a prismatic one
    (thesis eq. 3.14-3.15 applied to any point); columns of later joints are zero.
    A force F (base frame) at that point acts on the joints as J^T F.
    """
    k = _link_index(model, link)
    frames = link_frames(model, floats("q", q, model.n))
    R, o = frames[k]
    return point_jacobian6(model, frames, k, R @ vector("point", point, 3) + o)[:3]


def point_force_torques(model: SerialChain, q: np.ndarray, link: int, point: np.ndarray,
                        force: np.ndarray) -> np.ndarray:
    """(n,) joint torques J^T F of a force (3,) N, base frame, at a point (3,) of a link."""
    return point_jacobian(model, q, link, point).T @ vector("force", force, 3)


def _link_index(model: SerialChain, link: int) -> int:
    if isinstance(link, bool) or not isinstance(link, int | np.integer) or not (
            0 <= int(link) < model.n):
        raise ValueError(f"link must be an index 0..{model.n - 1}, got {link!r}")
    return int(link)


def link_frames(model: SerialChain, q: list[float]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per link (R (3, 3), origin (3,)), base <- link, from one call of the generated code."""
    fr = dynamics_model(model).frames(q)
    return [(np.array(fr[12 * i: 12 * i + 9]).reshape(3, 3), np.array(fr[12 * i + 9: 12 * i + 12]))
            for i in range(model.n)]


def point_jacobian6(model: SerialChain, frames: list[tuple[np.ndarray, np.ndarray]], link: int,
                     p: np.ndarray) -> np.ndarray:
    """(6, n) Jacobian of the base-frame point p (3,) riding on ``link``: linear rows
    z_j × (p - o_j) (revolute) or z_j (prismatic), angular rows z_j (revolute), j <= link."""
    J = np.zeros((6, model.n))
    for j in range(link + 1):
        Rj, oj = frames[j]
        joint = model.joints[j]
        z = Rj @ joint.axis
        if joint.kind == "prismatic":
            J[:3, j] = z
        else:
            J[:3, j] = np.cross(z, p - oj)
            J[3:, j] = z
    return J
