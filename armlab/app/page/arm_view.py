"""A serial arm drawn from its URDF, posed from joint angles without re-running yourdfpy.

``viser.extras.ViserUrdf`` builds the link meshes from the URDF; its
``update_cfg`` recomputes every joint with yourdfpy (about 1 ms for this arm).
:class:`ArmView` keeps ViserUrdf's scene nodes but poses them itself: a revolute
joint's frame only turns (parent <- child = origin · R(axis, q)), so one
quaternion product per moving joint is enough, and unchanged joints send
nothing (viser skips an unchanged pose).
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
import trimesh
import viser
import viser.transforms as vtf
import yourdfpy
from viser.extras import ViserUrdf

from armlab.app.page.surface import Surface
from armlab.app.viser_ext.urdf import joint_frames as urdf_joint_frames
from armlab.app.viser_ext.urdf import meshes as urdf_meshes
from armlab.kinematics.model import Quadruped, SerialChain
from armlab.kinematics.urdf_meshes import resolve_resource, warn_missing_once

#: Colour of a link drawn without its mesh (collision shape or capsule).
FALLBACK_RGB = (150, 150, 160)
#: Colour of a link drawn see-through (:meth:`ArmView.see_through`).
SEE_THROUGH_RGB = (190, 190, 200)
#: Radius of the capsule drawn between joint frames for a link with no usable shape (m).
CAPSULE_RADIUS = 0.015


def _quat_mul(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    """Hamilton product of two wxyz quaternions (in Python floats: every page poses its
    arm's joints with it every frame)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


class ArmView:
    """The robot's URDF meshes in the scene, posed by joint vector.

    Args:
        server: where to draw: the lab's server (every page) or one page.
        model: the chain (joint order of ``q``); its ``urdf_path`` is drawn. A
            :class:`~armlab.kinematics.model.Quadruped` is posed by its 12 leg joints in leg
            order (RF, LF, RH, LH), each leg's joints base to foot.
        root: scene node name under which the robot hangs (created here).
        color: RGBA override (e.g. a translucent ghost); None keeps the URDF colours.

    Attributes:
        root: the root frame handle (move or hide the whole robot with it).
        link_frames: URDF link name -> scene frame handle.
        drawn_as: for every link with a <visual>: "visual" (its own shapes),
            "collision" (a mesh was missing: its collision shapes) or "capsule" (a
            mesh was missing and no collision shape could be drawn either). Each
            missing mesh is warned about once
            (``armlab.kinematics.urdf_meshes.MissingMeshWarning``).
    """

    def __init__(self, server: Surface, model: SerialChain | Quadruped, *, root: str,
                 color: tuple[float, float, float, float] | None = None) -> None:
        if model.urdf_path is None:
            raise ValueError("model: has no urdf_path to draw")
        self.model = model
        self._scene = server.scene
        self.root = server.scene.add_frame(root, show_axes=False)
        urdf_path = Path(model.urdf_path)
        package_paths = tuple(getattr(model, "package_paths", ()))
        missing: set[str] = set()

        def find(fname: str) -> str:
            found = resolve_resource(fname, urdf_path=urdf_path, package_paths=package_paths)
            if found is None:
                missing.add(fname)
                return fname
            return str(found)

        with _quiet_yourdfpy():  # its own "can't find" lines would repeat ours
            parsed = yourdfpy.URDF.load(urdf_path, filename_handler=find)
        self._parsed = parsed
        self._urdf = ViserUrdf(server, parsed, root_node_name=root, mesh_color_override=color)  # type: ignore[arg-type]  # a Surface is the server or one client's handle
        # Places the fixed joints once (moving ones are set by set_q below).
        self._urdf.update_cfg(np.zeros(len(parsed.actuated_joint_names)))
        # ViserUrdf keeps one frame per URDF joint, named after the joint's child link.
        joints = parsed.joint_map
        frames = urdf_joint_frames(self._urdf)
        by_child = {}
        for frame in frames:
            by_child[frame.name.rsplit("/", 1)[-1]] = frame
        self.link_frames: dict[str, viser.SceneNodeHandle] = by_child
        self.drawn_as = self._draw_fallbacks(server, root, urdf_path, package_paths, missing,
                                             color)
        # (frame, origin (4, 4), origin quaternion, unit axis, joint type) per moving joint;
        # the quaternion and axis as tuples of floats (set_q's arithmetic, every frame)
        self._moving: list[tuple[viser.SceneNodeHandle, np.ndarray, tuple[float, ...],
                                 tuple[float, ...], str]] = []
        names = _joint_names(model)
        for name in names:
            j = joints[name]
            origin, q0, axis = _joint_origin(j)
            frame = by_child[j.child]
            frame.position = origin[:3, 3]
            self._moving.append((frame, origin, q0, axis, j.type))
        self.q = np.full(len(names), np.nan)
        self._off_chain: dict[str, list] = {}  # set_joint's joints, by name
        self.set_q(np.zeros(len(names)) if isinstance(model, Quadruped) else model.neutral())

    @property
    def moving_root(self) -> str:
        """Scene name of the first moving joint's frame: everything that moves hangs from
        it (a camera framing the arm itself, not the body it stands on, frames this)."""
        return self._moving[0][0].name if self._moving else self.root.name

    def set_q(self, q: np.ndarray) -> None:
        """Pose the robot at joint vector ``q`` (n,), rad (m for prismatic joints)."""
        q = np.asarray(q, dtype=float)
        for i, moving in enumerate(self._moving):
            qi = float(q[i])
            if qi != self.q[i]:
                _pose(*moving, qi)
        self.q = q.copy()

    def set_joint(self, name: str, value: float) -> None:
        """Pose the URDF joint ``name`` off the chain (a gripper's finger: m, or rad) at
        ``value``, and every joint that mimics it at multiplier · value + offset (the
        other finger)."""
        posed = self._off_chain.get(name)
        if posed is None:  # found once: a gripper's reading changes every frame it moves
            posed = self._off_chain[name] = self._joints_moved_by(name)
        for frame, origin, q0, axis, kind, multiplier, offset in posed:
            _pose(frame, origin, q0, axis, kind, multiplier * float(value) + offset)

    def _joints_moved_by(self, name: str) -> list[tuple[viser.SceneNodeHandle, np.ndarray,
                                                        tuple[float, ...], tuple[float, ...],
                                                        str, float, float]]:
        """(frame, origin, origin quaternion, unit axis, type, multiplier, offset) of the
        URDF joint ``name`` (1, 0) and of every joint that mimics it."""
        out = []
        for j in self._parsed.joint_map.values():
            mimic = j.mimic
            if j.name == name:
                multiplier, offset = 1.0, 0.0
            elif mimic is not None and mimic.joint == name:
                multiplier = mimic.multiplier if mimic.multiplier is not None else 1.0
                offset = mimic.offset or 0.0
            else:
                continue
            out.append((self.link_frames[j.child], *_joint_origin(j), j.type,
                        float(multiplier), float(offset)))
        return out

    def see_through(self, link: str, *, opacity: float = 0.25) -> bool:
        """Draw ``link`` translucent, so that links behind it show (a body the arm stands
        on): its own meshes are hidden and its visual shapes drawn again, grey, at
        ``opacity`` (0: not drawn at all). False if the robot has no such link or nothing
        of it to draw."""
        frame = self.link_frames.get(link)
        robot = self._parsed.robot
        visuals: list[Any] = next((lk.visuals for lk in robot.links if lk.name == link), [])
        if frame is None or not visuals:
            return False
        assert self.model.urdf_path is not None  # its links' visuals came from it
        urdf_path = Path(self.model.urdf_path)
        package_paths = tuple(getattr(self.model, "package_paths", ()))
        shapes = [m for v in visuals
                  if (m := _shape(v.geometry, v.origin, urdf_path, package_paths)) is not None]
        if not shapes:
            return False
        for node in self.meshes():
            if node.name.rsplit("/", 1)[0] == frame.name:
                node.visible = False
        if opacity <= 0.0:
            return True
        mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(shapes))  # of Trimeshes
        self._scene.add_mesh_simple(
            f"{frame.name}/see_through", mesh.vertices, mesh.faces, color=SEE_THROUGH_RGB,
            opacity=opacity, side="double")
        return True

    def meshes(self) -> list[viser.SceneNodeHandle]:
        """The robot's mesh nodes (one per visual of each link, named under its frame)."""
        return urdf_meshes(self._urdf)

    def remove(self) -> None:
        self.root.remove()

    def _draw_fallbacks(self, server: Surface, root: str, urdf_path: Path,
                        package_paths: tuple[Path, ...], missing: set[str],
                        color: tuple[float, float, float, float] | None) -> dict[str, str]:
        """Draw every link whose visual mesh is missing from its collision shapes, else
        as a capsule from its frame to each child joint; never leave it invisible."""
        robot = self._parsed.robot
        rgb = FALLBACK_RGB if color is None else tuple(int(255 * c) for c in color[:3])
        opacity = None if color is None or len(color) < 4 else color[3]
        drawn: dict[str, str] = {}
        for link in robot.links:
            if not link.visuals:
                continue
            lost = [v.geometry.mesh.filename for v in link.visuals
                    if v.geometry is not None and v.geometry.mesh is not None
                    and v.geometry.mesh.filename in missing]
            if not lost:
                drawn[link.name] = "visual"
                continue
            for fname in lost:
                warn_missing_once(fname, urdf_path=urdf_path, link=link.name)
            if len(lost) < len(link.visuals):
                drawn[link.name] = "visual"  # some of its own shapes are drawn
                continue
            frame = self.link_frames.get(link.name)
            parent = frame.name if frame is not None else f"{root}/visual"
            shapes = [m for c in link.collisions
                      if (m := _shape(c.geometry, c.origin, urdf_path, package_paths)) is not None]
            kind = "collision"
            if not shapes:
                shapes, kind = _capsules(robot, link.name), "capsule"
            mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(shapes))  # of Trimeshes
            server.scene.add_mesh_simple(f"{parent}/fallback_{kind}", mesh.vertices, mesh.faces,
                                         color=rgb, opacity=opacity)  # type: ignore[arg-type]  # three ints: color[:3] scaled
            drawn[link.name] = kind
        return drawn


def _joint_origin(j: yourdfpy.Joint) -> tuple[np.ndarray, tuple[float, ...], tuple[float, ...]]:
    """A URDF joint's origin (4, 4), its wxyz quaternion and the unit joint axis (the two as
    floats, for :func:`_pose`)."""
    origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
    axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
    return (origin, tuple(vtf.SO3.from_matrix(origin[:3, :3]).wxyz.tolist()),
            tuple((axis / np.linalg.norm(axis)).tolist()))


def _pose(frame: viser.SceneNodeHandle, origin: np.ndarray, q0: Sequence[float],
          axis: Sequence[float], kind: str, value: float) -> None:
    """Pose one joint's child frame at ``value`` (m for a prismatic joint, else rad);
    ``q0`` the origin's wxyz quaternion, ``axis`` the unit joint axis."""
    if kind == "prismatic":  # parent <- child = origin · Trans(axis q)
        frame.position = origin[:3, 3] + origin[:3, :3] @ (np.asarray(axis) * value)
    else:  # parent <- child = origin · Rot(axis, q)
        h = 0.5 * value
        s = math.sin(h)
        frame.wxyz = _quat_mul(q0, (math.cos(h), s * axis[0], s * axis[1], s * axis[2]))


def _joint_names(model: SerialChain | Quadruped) -> tuple[str, ...]:
    """Joint names in the order of ``q``: a chain's, or every leg's of a quadruped."""
    if isinstance(model, Quadruped):
        return tuple(name for leg in model.legs.values() for name in leg.joint_names)
    return model.joint_names


@contextlib.contextmanager
def _quiet_yourdfpy() -> Iterator[None]:
    logger = logging.getLogger("yourdfpy")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _shape(geometry: yourdfpy.Geometry | None, origin: np.ndarray | None, urdf_path: Path,
           package_paths: tuple[Path, ...]) -> trimesh.Trimesh | None:
    """A collision element as a mesh in its link's frame (None: nothing drawable)."""
    if geometry is None:
        return None
    if geometry.box is not None:
        mesh = trimesh.creation.box(extents=geometry.box.size)
    elif geometry.cylinder is not None:
        mesh = trimesh.creation.cylinder(radius=geometry.cylinder.radius,
                                         height=geometry.cylinder.length)
    elif geometry.sphere is not None:
        mesh = trimesh.creation.icosphere(radius=geometry.sphere.radius, subdivisions=2)
    elif geometry.mesh is not None:
        found = resolve_resource(geometry.mesh.filename, urdf_path=urdf_path,
                                 package_paths=package_paths)
        if found is None:
            return None
        mesh = trimesh.load(found, force="mesh")
        if geometry.mesh.scale is not None:
            mesh.apply_scale(geometry.mesh.scale)
    else:
        return None
    if origin is not None:
        mesh.apply_transform(origin)
    return mesh


def _capsules(robot: yourdfpy.Robot, link: str) -> list[trimesh.Trimesh]:
    """Capsules from ``link``'s frame to each child joint's origin (a ball for a leaf)."""
    out = []
    for joint in robot.joints:
        if joint.parent != link or joint.origin is None:
            continue
        end = np.asarray(joint.origin, dtype=float)[:3, 3]
        length = float(np.linalg.norm(end))
        if length < 1e-6:
            continue
        T = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], end / length)
        T[:3, 3] = end / 2
        out.append(trimesh.creation.capsule(height=length, radius=CAPSULE_RADIUS, transform=T))
    if not out:
        out.append(trimesh.creation.icosphere(radius=2 * CAPSULE_RADIUS, subdivisions=2))
    return out
