"""Robot models and pure kinematics/dynamics functions (no I/O, no threads, no viser)."""

from armlab.kinematics.model import (
    Quadruped,
    SerialChain,
    URDFError,
    chain_from_urdf,
    load_robot,
)

__all__ = ["Quadruped", "SerialChain", "URDFError", "chain_from_urdf", "load_robot"]
