"""The thesis's simplified closed forms of the receptionist arm's dynamics (§3.4), for
comparison with the general recursion (:func:`armlab.kinematics.dynamics.rnea`; docs/dynamics.md).
"""

from __future__ import annotations

import math

import numpy as np

from armlab.kinematics.validate import vector


def thesis_closed_form(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *,
                       lengths: tuple[float, float] = (0.185, 0.25),
                       masses: tuple[float, float] = (0.176, 0.19), g: float = 9.81,
                       literal: bool = False) -> np.ndarray:
    """Servo torques of the receptionist arm by the thesis's simplified §3.4 equations.

    Thesis eq. 3.28 (servo 1, theta0 about y), 3.31 (servo 2, theta1 about z) and 3.36
    (servo 3, theta2 about z), with links as rods (centre of mass mid-link, I = m L²/3),
    gravity g along +x, and the joint force F21 from eq. 3.34: m2 a_C2 = F21 + m2 g.
    Each printed equation "I θ̈ = moment" is read as Euler's law about the joint with
    the servo torque added, so the servo torque is tau = I θ̈ - moment.

    Args:
        q, qd, qdd: (3,) in the model's chain order [theta1, theta0, theta2].
        lengths: (L1, L2) m; masses: (m1, m2) kg; g: m/s².
        literal: keep the printed typos: 3.31's moment has both terms with the sign of
            -(r × F)_z, and 3.36 uses (z_B - z_C2) where (y_B - y_C2) is meant. By
            default both are fixed.

    Returns:
        (3,) torques in chain order [theta1, theta0, theta2], N·m.

    What this leaves out, compared with :func:`rnea` (docs/dynamics.md): the moment
    link 2 passes to link 1 through the elbow (only the force F21 is carried), the
    rotation of the joint axes (moments are taken about the fixed world y and z axes),
    link 1's Coriolis/gyroscopic terms, and 3.36 applies I = m L²/3 about the centre of
    mass with θ̈2 alone instead of the absolute angular acceleration.
    """
    t1, t0, t2 = vector("q", q, 3)
    d1, d0, d2 = vector("qd", qd, 3)
    a1, a0, a2 = vector("qdd", qdd, 3)
    L1, L2 = lengths
    m1, m2 = masses
    c0, s0, c1, s1 = math.cos(t0), math.sin(t0), math.cos(t1), math.sin(t1)
    Rz1 = np.array([[c1, -s1, 0.0], [s1, c1, 0.0], [0.0, 0.0, 1.0]])
    Ry0 = np.array([[c0, 0.0, s0], [0.0, 1.0, 0.0], [-s0, 0.0, c0]])
    R1 = Rz1 @ Ry0
    ez, ey = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
    u1 = R1[:, 0]
    u2 = R1 @ np.array([math.cos(t2), math.sin(t2), 0.0])
    C1, B = 0.5 * L1 * u1, L1 * u1
    C2 = B + 0.5 * L2 * u2
    # Angular velocities/accelerations of the links (world frame), then a_C2.
    y1 = Rz1 @ ey
    w1 = d1 * ez + d0 * y1
    al1 = a1 * ez + a0 * y1 + np.cross(d1 * ez, d0 * y1)
    z2 = R1 @ ez
    w2 = w1 + d2 * z2
    al2 = al1 + a2 * z2 + np.cross(w1, d2 * z2)
    aB = np.cross(al1, B) + np.cross(w1, np.cross(w1, B))
    r = C2 - B
    aC2 = aB + np.cross(al2, r) + np.cross(w2, np.cross(w2, r))
    F21 = m2 * aC2 - m2 * np.array([g, 0.0, 0.0])  # eq. 3.34
    xc1, yc1, zc1 = C1
    xB, yB, zB = B
    xC2, yC2, zC2 = C2
    moment0 = m1 * g * zc1 + F21[2] * xB - F21[0] * zB  # eq. 3.28
    moment1 = m1 * g * yc1 + F21[1] * xB - F21[0] * yB  # eq. 3.31 as printed
    if not literal:
        moment1 = -moment1  # (r_C1 × G1 + r_B × (-F21))_z
    lever = (zB - zC2) if literal else (yB - yC2)
    moment2 = F21[1] * (xB - xC2) - F21[0] * lever  # eq. 3.36
    I1 = m1 * L1**2 / 3.0
    I2 = m2 * L2**2 / 3.0
    return np.array([I1 * a1 - moment1, I1 * a0 - moment0, I2 * a2 - moment2])
