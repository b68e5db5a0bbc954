"""armlab: a browser lab for teaching robot-arm kinematics and compliance control.

The repository's folders are this package's parts: :mod:`armlab.kinematics` (what a
robot is and pure functions of it), :mod:`armlab.control` (controllers, observers,
the control loop, headless experiments), :mod:`armlab.hardware` (servos: the wire,
their tables, the simulation, the emulator, the backends) and :mod:`armlab.app` (the
browser lab and the ``armlab`` command). A notebook needs only what is here::

    import armlab
    arm = armlab.load_robot("receptionist_arm")
"""

from armlab.kinematics import Quadruped, SerialChain, URDFError, load_robot

__all__ = ["Quadruped", "SerialChain", "URDFError", "load_robot"]
