"""The balls an arm touches the world with: each link's collision capsules
(:class:`~armlab.kinematics.model.Capsule`, from the URDF's ``<collision>``) as balls along
their segments, close enough that the surface between two dips in by under a third of a
radius (a table's edge under the forearm finds it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armlab.kinematics.model import SerialChain

#: Centres along a capsule at most this many radii apart: two balls of radius r that far
#: apart leave the surface between them at most r (1 − √(1 − 0.7²)) ≈ 0.29 r short.
SPACING = 1.4


@dataclass(frozen=True)
class Ball:
    """One contact ball: on moving link ``link`` (index), its centre (3,) m in that link's
    frame, its radius m."""

    link: int
    centre: tuple[float, float, float]
    radius: float


def contact_balls(model: SerialChain) -> tuple[Ball, ...]:
    """Every link's collision capsules as balls (:data:`SPACING`), base to tip; () for a
    model whose file gives no ``<collision>``."""
    balls = []
    for i, link in enumerate(model.links):
        for c in link.collision:
            a, b = np.asarray(c.a, dtype=float), np.asarray(c.b, dtype=float)
            length = float(np.linalg.norm(b - a))
            count = 1 if length < 1e-12 else max(2, math.ceil(
                length / (SPACING * c.radius)) + 1 if c.radius > 0 else 2)
            for s in np.linspace(0.0, 1.0, count) if count > 1 else (0.0,):
                x, y, z = (a + s * (b - a)).tolist()
                balls.append(Ball(i, (x, y, z), float(c.radius)))
    return tuple(balls)
