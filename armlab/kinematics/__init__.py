"""Robot models and pure kinematics/dynamics functions (no I/O, no threads, no viser)."""

from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import Quadruped, SerialChain, URDFError
from armlab.kinematics.urdf_read import chain_from_urdf

__all__ = ["Quadruped", "SerialChain", "URDFError", "chain_from_urdf", "load_robot"]
