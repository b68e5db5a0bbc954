"""What ``viser.extras.ViserUrdf`` keeps private: the scene nodes it made for a robot.

relies on: ``ViserUrdf._joint_frames`` (one frame per URDF joint, named after its child
link) and ``ViserUrdf._meshes`` (every mesh node); seen in viser 1.1.1
"""

from __future__ import annotations

from typing import Any

from armlab.app.viser_ext.probe import assigned_in


def missing() -> list[str]:
    """What of the above this viser lacks."""
    from viser.extras import ViserUrdf

    return [f"ViserUrdf.{n}" for n in ("_joint_frames", "_meshes")
            if not assigned_in(ViserUrdf, n)]


def joint_frames(urdf: Any) -> list[Any]:
    """The frame nodes ``urdf`` (a ViserUrdf) made, one per URDF joint."""
    return list(urdf._joint_frames)


def meshes(urdf: Any) -> list[Any]:
    """The mesh nodes ``urdf`` (a ViserUrdf) made."""
    return list(urdf._meshes)
