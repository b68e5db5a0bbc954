"""The robots the lab ships, by name (``armlab.load_robot``): their URDF files, the
receptionist arm's link-length presets and each one's tip link."""

from __future__ import annotations

from pathlib import Path
from typing import Literal, overload

from armlab.kinematics.model import Quadruped, SerialChain, URDFError
from armlab.kinematics.urdf_read import chain_from_urdf, holds_quadruped, quadruped_from_urdf

ROBOTS_DIR = Path(__file__).with_name("robots")

#: Robot names and their URDF files; receptionist_arm has two link-length presets.
ROBOT_FILES = {
    "receptionist_arm": "receptionist_arm.urdf",
    "redundant_planar": "redundant_planar.urdf",
    "planar_servo_arm": "planar_servo_arm.urdf",
    "quadruped": "quadruped.urdf",
    "open_manipulator_x": "open_manipulator_x.urdf",
    "so101": "so101.urdf",
}
#: The end-effector link of a shipped robot whose URDF has more than one leaf reached
#: through revolute joints (the SO-101's gripper jaw is one; its tool frame the tip).
ROBOT_TIPS = {"so101": "gripper_frame_link"}

#: Thesis link-length presets (cm) for the receptionist arm -> URDF file.
RECEPTIONIST_PRESETS = {
    "18.5/25": "receptionist_arm.urdf",  # appendix code (default)
    "18.5/18.5": "receptionist_arm_18_5.urdf",  # specification list
    "17/25": "receptionist_arm_17_25.urdf",  # the FK text of eq. 3.13
}


#: The shipped robots that are one serial chain (every name of ROBOT_FILES but quadruped).
ChainName = Literal["receptionist_arm", "redundant_planar", "planar_servo_arm",
                    "open_manipulator_x", "so101"]


@overload
def load_robot(name_or_path: ChainName, *, preset: str | None = None,
               tip_link: str | None = None,
               package_paths: tuple[str | Path, ...] = ()) -> SerialChain: ...
@overload
def load_robot(name_or_path: Literal["quadruped"], *, preset: str | None = None,
               tip_link: str | None = None,
               package_paths: tuple[str | Path, ...] = ()) -> Quadruped: ...
@overload
def load_robot(name_or_path: str | Path, *, preset: str | None = None,
               tip_link: str | None = None,
               package_paths: tuple[str | Path, ...] = ()) -> SerialChain | Quadruped: ...
def load_robot(name_or_path: str | Path, *, preset: str | None = None,
               tip_link: str | None = None,
               package_paths: tuple[str | Path, ...] = ()) -> SerialChain | Quadruped:
    """Load a robot by name (see ``ROBOT_FILES``) or from a URDF path.

    Args:
        name_or_path: "receptionist_arm", "redundant_planar", "planar_servo_arm",
            "quadruped", "open_manipulator_x", "so101", or a path to a .urdf file.
        preset: for "receptionist_arm", a key of ``RECEPTIONIST_PRESETS``
            (link lengths in cm, "18.5/25" by default).
        tip_link: for a URDF path, the end-effector link: the chain runs from the
            file's root to it (see :func:`chain_from_urdf` for the default).
        package_paths: for a URDF path, extra folders holding ``package://`` meshes.

    Raises:
        ValueError: for an unknown name (the message lists the known ones) or preset.
        URDFError: for a malformed URDF (the message names the file and reason).
    """
    text = str(name_or_path)
    if text in ROBOT_FILES:
        fname = ROBOT_FILES[text]
        if preset is not None:
            if text != "receptionist_arm" or preset not in RECEPTIONIST_PRESETS:
                raise ValueError(
                    f"unknown preset {preset!r} for {text}; known: {sorted(RECEPTIONIST_PRESETS)}"
                )
            fname = RECEPTIONIST_PRESETS[preset]
        path = ROBOTS_DIR / fname
        if text == "quadruped":
            return quadruped_from_urdf(path)
        return chain_from_urdf(path, tip_link=tip_link or ROBOT_TIPS.get(text))
    if text.endswith(".urdf") or Path(text).exists():
        path = Path(text)
        if not path.exists():
            raise URDFError(f"{path}: no such file")
        if tip_link is None and holds_quadruped(path):
            return quadruped_from_urdf(path)
        return chain_from_urdf(path, tip_link=tip_link, package_paths=package_paths)
    raise ValueError(f"unknown robot {text!r}; known robots: {', '.join(ROBOT_FILES)}")
