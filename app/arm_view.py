"""A serial arm drawn from its URDF, posed from joint angles without re-running yourdfpy.

``viser.extras.ViserUrdf`` builds the link meshes from the URDF; its
``update_cfg`` recomputes every joint with yourdfpy (about 1 ms for this arm).
:class:`ArmView` keeps ViserUrdf's scene nodes but poses them itself: a revolute
joint's frame only turns (parent <- child = origin · R(axis, q)), so one
quaternion product per moving joint is enough, and unchanged joints send
nothing (viser skips an unchanged pose).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import viser
import viser.transforms as vtf
from viser.extras import ViserUrdf

from kinematics.model import Quadruped, SerialChain


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of two wxyz quaternions."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])


class ArmView:
    """The robot's URDF meshes in the scene, posed by joint vector.

    Args:
        server: viser server (or client handle).
        model: the chain (joint order of ``q``); its ``urdf_path`` is drawn. A
            :class:`~kinematics.model.Quadruped` is posed by its 12 leg joints in leg
            order (RF, LF, RH, LH), each leg's joints base to foot.
        root: scene node name under which the robot hangs (created here).
        color: RGBA override (e.g. a translucent ghost); None keeps the URDF colours.

    Attributes:
        root: the root frame handle (move or hide the whole robot with it).
        link_frames: URDF link name -> scene frame handle.
    """

    def __init__(self, server: viser.ViserServer, model: SerialChain | Quadruped, *, root: str,
                 color: tuple[float, float, float, float] | None = None) -> None:
        if model.urdf_path is None:
            raise ValueError("model: has no urdf_path to draw")
        self.model = model
        self.root = server.scene.add_frame(root, show_axes=False)
        self._urdf = ViserUrdf(server, Path(model.urdf_path), root_node_name=root,
                               mesh_color_override=color)
        # Places the fixed joints once (moving ones are set by set_q below).
        self._urdf.update_cfg(np.zeros(len(self._urdf._urdf.actuated_joint_names)))
        # ViserUrdf keeps one frame per URDF joint, named after the joint's child link.
        joints = self._urdf._urdf.joint_map
        frames = self._urdf._joint_frames
        by_child = {}
        for frame in frames:
            by_child[frame.name.rsplit("/", 1)[-1]] = frame
        self.link_frames: dict[str, viser.SceneNodeHandle] = by_child
        # (frame, origin (4, 4), origin quaternion, unit axis, joint type) per moving joint.
        self._moving: list[tuple[viser.SceneNodeHandle, np.ndarray, np.ndarray, np.ndarray,
                                 str]] = []
        names = _joint_names(model)
        for name in names:
            j = joints[name]
            origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
            q0 = vtf.SO3.from_matrix(origin[:3, :3]).wxyz
            axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
            axis = axis / np.linalg.norm(axis)
            frame = by_child[j.child]
            frame.position = origin[:3, 3]
            self._moving.append((frame, origin, q0, axis, j.type))
        self.q = np.full(len(names), np.nan)
        self.set_q(np.zeros(len(names)) if isinstance(model, Quadruped) else model.neutral())

    def set_q(self, q: np.ndarray) -> None:
        """Pose the robot at joint vector ``q`` (n,), rad (m for prismatic joints)."""
        q = np.asarray(q, dtype=float)
        for i, (frame, origin, q0, axis, kind) in enumerate(self._moving):
            qi = float(q[i])
            if qi == self.q[i]:
                continue
            if kind == "prismatic":  # parent <- child = origin · Trans(axis q)
                frame.position = origin[:3, 3] + origin[:3, :3] @ (axis * qi)
            else:  # parent <- child = origin · Rot(axis, q)
                h = 0.5 * qi
                frame.wxyz = _quat_mul(q0, np.array([math.cos(h), *(math.sin(h) * axis)]))
        self.q = q.copy()

    def remove(self) -> None:
        self.root.remove()


def _joint_names(model: SerialChain | Quadruped) -> tuple[str, ...]:
    """Joint names in the order of ``q``: a chain's, or every leg's of a quadruped."""
    if isinstance(model, Quadruped):
        return tuple(name for leg in model.legs.values() for name in leg.joint_names)
    return model.joint_names
