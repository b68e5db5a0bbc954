"""A wall the compliance law renders: on real servos, which touch no simulated wall.

The loop measures the hand (forward kinematics of the servos' angles, the Jacobian for
its speed) against a plane (a :class:`~armlab.control.backend.WallSetting`:
a point, the unit normal towards the free side, a stiffness and a damping). Inside it,
the wall pushes the hand out with f = k·p + d·ṗ (p the penetration, never pulling), and
the joints would hold τ_wall = −Jᵀ f n against it: the torque the sensorless estimate
τ_ext of eq. 2.21–2.23 reads of a real wall. The law takes it as part of the external
torque its environment answers (eq. 2.7: M θ̈_env + D θ̇_env + K θ_env = K_f (τ_ext +
τ_wall)), so the reference θ_cmd − θ_env backs out of the wall as it would from a push,
and a person pushing the arm into it feels it give way no further. PD (eq. 2.20) has no
environment: it renders no wall.
"""

from __future__ import annotations

import numpy as np

from armlab.control.backend import WallSetting
from armlab.kinematics.model import SerialChain


def wall_force(wall: WallSetting, x: np.ndarray, v: np.ndarray) -> float:
    """N the wall pushes the hand at ``x`` (3,) m moving at ``v`` (3,) m/s out with, along
    its normal: k·p + d·ṗ inside it (p m of penetration), never pulling; 0 outside."""
    penetration = -float(np.dot(wall.normal, x - wall.origin))
    if penetration <= 0.0:
        return 0.0
    return max(0.0, wall.stiffness * penetration - wall.damping * float(np.dot(wall.normal, v)))


def rendered_wall(model: SerialChain, wall: WallSetting, q: np.ndarray, qd: np.ndarray
                  ) -> tuple[float, np.ndarray]:
    """The wall at the arm's measured ``q``, ``qd`` (n,): (f N, τ_wall (n,) N·m the joints
    would hold against it, −Jᵀ f n)."""
    jac = model.jacobian(q)[:3]
    x = model.fk(q)[:3, 3]
    f = wall_force(wall, x, jac @ qd)
    return f, -(jac.T @ (f * wall.normal))
