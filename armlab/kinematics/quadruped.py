"""The seed 003 quadruped: geometry, leg frames and its URDF (generated, parameterised).

Body frame: origin at the body's centre, x forward, y left, z up. Four legs
RF, LF, RH, LH (right/left, front/hind), each hip yaw → hip pitch → knee, on
Dynamixel AX-12A servos (seed 003 §3.2). The seed gives no dimensions; the defaults
are plausible for a 12 × AX-12A acrylic robot and every length is a parameter.

Each leg's own frame (the seed's x, y, z of eq. 3.1-3.9 and Table 1.1) is at its hip,
x forward, y outward, z up: the left legs' frame is the body frame moved to the hip,
the right legs' frame is its mirror image (y = −body y). :func:`leg_to_body` and
:func:`body_to_leg` convert. The URDF's joint axes are chosen so that the URDF joint
angles are exactly the seed's θ1, θ2, θ3 on every leg.

``armlab/kinematics/robots/quadruped.urdf`` is ``quadruped_urdf()`` written out
(tests/test_seed003_model.py checks they agree).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from armlab.kinematics.leg_ik import LegGeometry
from armlab.kinematics.validate import scalar

#: Legs in the order of armlab.kinematics.urdf_read.LEG_NAMES.
LEGS = ("RF", "LF", "RH", "LH")
#: +1 for the left legs (outward = +y of the body), −1 for the right legs.
SIDE = {"RF": -1, "LF": 1, "RH": -1, "LH": 1}
#: +1 for the front legs, −1 for the hind legs.
END = {"RF": 1, "LF": 1, "RH": -1, "LH": -1}

#: AX-12A travel: 300 degrees, ±150 degrees about the centre.
AX12_HALF_RANGE = float(np.radians(150.0))


@dataclass(frozen=True)
class QuadrupedGeometry:
    """Dimensions (m) and masses (kg) of the quadruped.

    Attributes:
        leg: femur and tibia lengths (the seed's l1, l2).
        hip_x, hip_y: hips at (±hip_x, ±hip_y, 0) in the body frame.
        body_size: (length, width, thickness) of the body box.
        body_mass: body with controller, battery and the four hip-yaw servos.
        coxa_mass: what the hip-yaw output carries (the hip-pitch servo, 55 g AX-12A).
        femur_mass: femur bracket with the knee servo; tibia_mass: the tibia.
        joint_limit: symmetric joint limit, rad (AX-12A: ±150°).
    """

    leg: LegGeometry = field(default_factory=LegGeometry)
    hip_x: float = 0.08
    hip_y: float = 0.06
    body_size: tuple[float, float, float] = (0.22, 0.15, 0.04)
    body_mass: float = 0.55
    coxa_mass: float = 0.06
    femur_mass: float = 0.07
    tibia_mass: float = 0.03
    joint_limit: float = AX12_HALF_RANGE

    def __post_init__(self) -> None:
        for name in ("hip_x", "hip_y", "body_mass", "coxa_mass", "femur_mass", "tibia_mass",
                     "joint_limit"):
            scalar(name, getattr(self, name), positive=True)


#: The default geometry (immutable).
DEFAULT_GEOMETRY = QuadrupedGeometry()


def hip_position(leg: str, geom: QuadrupedGeometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """(3,) hip of ``leg`` in the body frame, m."""
    _check_leg(leg)
    return np.array([END[leg] * geom.hip_x, SIDE[leg] * geom.hip_y, 0.0])


def leg_to_body(p_leg: np.ndarray, leg: str, geom: QuadrupedGeometry = DEFAULT_GEOMETRY
                ) -> np.ndarray:
    """Point(s) (..., 3) from the leg's seed frame into the body frame."""
    p = np.asarray(p_leg, dtype=float)
    return hip_position(leg, geom) + p * np.array([1.0, SIDE[leg], 1.0])


def foot_in_tibia(leg: str, geom: QuadrupedGeometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """(3,) the foot point of ``leg`` in its tibia's frame (where the floor pushes), m."""
    _check_leg(leg)
    return np.array([0.0, SIDE[leg] * geom.leg.tibia, 0.0])


def body_to_leg(p_body: np.ndarray, leg: str, geom: QuadrupedGeometry = DEFAULT_GEOMETRY
                ) -> np.ndarray:
    """Point(s) (..., 3) from the body frame into the leg's seed frame."""
    p = np.asarray(p_body, dtype=float) - hip_position(leg, geom)
    return p * np.array([1.0, SIDE[leg], 1.0])


def _check_leg(leg: str) -> None:
    if leg not in SIDE:
        raise ValueError(f"leg must be one of {', '.join(LEGS)}, got {leg!r}")


def _f(v: float) -> str:
    return f"{float(v):.10g}"


def _v(*vs: float) -> str:
    return " ".join(_f(v) for v in vs)


def _box_inertia(m: float, sx: float, sy: float, sz: float) -> str:
    ixx = m * (sy * sy + sz * sz) / 12.0
    iyy = m * (sx * sx + sz * sz) / 12.0
    izz = m * (sx * sx + sy * sy) / 12.0
    return (f'<inertia ixx="{_f(ixx)}" ixy="0" ixz="0" iyy="{_f(iyy)}" iyz="0" '
            f'izz="{_f(izz)}"/>')


def _leg_urdf(leg: str, geom: QuadrupedGeometry) -> list[str]:
    s = SIDE[leg]
    l1, l2 = geom.leg.femur, geom.leg.tibia
    hip = hip_position(leg, geom)
    yaw_axis = _v(0, 0, -s)  # θ1 turns the outward axis towards +x on both sides
    pitch_axis = _v(-s, 0, 0)  # positive θ2, θ3 turn the outward axis downwards
    lim = (f'<limit lower="{_f(-geom.joint_limit)}" upper="{_f(geom.joint_limit)}" '
           f'effort="1.5" velocity="5.8"/>')
    servo = '<material name="servo"><color rgba="0.12 0.12 0.14 1"/></material>'
    frame = '<material name="frame"><color rgba="0.35 0.6 0.9 0.9"/></material>'
    shin = '<material name="shin"><color rgba="0.95 0.55 0.15 1"/></material>'
    foot = '<material name="foot"><color rgba="0.2 0.2 0.2 1"/></material>'
    return [
        f'  <link name="{leg}_hip"/>',
        f'  <joint name="{leg}_hip_mount" type="fixed"><parent link="body"/>'
        f'<child link="{leg}_hip"/><origin xyz="{_v(*hip)}"/></joint>',
        f'  <link name="{leg}_coxa"><inertial><mass value="{_f(geom.coxa_mass)}"/>'
        f'{_box_inertia(geom.coxa_mass, 0.032, 0.05, 0.04)}</inertial>'
        f'<visual><geometry><box size="0.032 0.05 0.04"/></geometry>{servo}</visual></link>',
        f'  <joint name="{leg}_hip_yaw" type="revolute"><parent link="{leg}_hip"/>'
        f'<child link="{leg}_coxa"/><axis xyz="{yaw_axis}"/>{lim}</joint>',
        f'  <link name="{leg}_femur"><inertial><origin xyz="{_v(0, s * l1 / 2, 0)}"/>'
        f'<mass value="{_f(geom.femur_mass)}"/>'
        f'{_box_inertia(geom.femur_mass, 0.03, l1, 0.02)}</inertial>'
        f'<visual><origin xyz="{_v(0, s * l1 / 2, 0)}"/><geometry>'
        f'<box size="{_v(0.03, l1, 0.02)}"/></geometry>{frame}</visual>'
        f'<visual><origin xyz="{_v(0, s * l1, 0)}"/><geometry>'
        f'<box size="0.05 0.032 0.04"/></geometry>{servo}</visual></link>',
        f'  <joint name="{leg}_hip_pitch" type="revolute"><parent link="{leg}_coxa"/>'
        f'<child link="{leg}_femur"/><axis xyz="{pitch_axis}"/>{lim}</joint>',
        f'  <link name="{leg}_tibia"><inertial><origin xyz="{_v(0, s * l2 / 2, 0)}"/>'
        f'<mass value="{_f(geom.tibia_mass)}"/>'
        f'{_box_inertia(geom.tibia_mass, 0.012, l2, 0.012)}</inertial>'
        f'<visual><origin xyz="{_v(0, s * l2 / 2, 0)}" rpy="{_v(np.pi / 2, 0, 0)}"/>'
        f'<geometry><cylinder radius="0.006" length="{_f(l2)}"/></geometry>{shin}</visual>'
        f'</link>',
        f'  <joint name="{leg}_knee" type="revolute"><parent link="{leg}_femur"/>'
        f'<child link="{leg}_tibia"/><origin xyz="{_v(0, s * l1, 0)}"/>'
        f'<axis xyz="{pitch_axis}"/>{lim}</joint>',
        f'  <link name="{leg}_foot"><visual><geometry><sphere radius="0.01"/></geometry>'
        f'{foot}</visual></link>',
        f'  <joint name="{leg}_foot_fixed" type="fixed"><parent link="{leg}_tibia"/>'
        f'<child link="{leg}_foot"/><origin xyz="{_v(*foot_in_tibia(leg, geom))}"/></joint>',
    ]


def quadruped_urdf(geom: QuadrupedGeometry = DEFAULT_GEOMETRY) -> str:
    """URDF text of the quadruped with the given dimensions (seed 003 robot).

    Links per leg: ``<LEG>_hip`` (fixed mount on the body) → ``<LEG>_coxa`` (hip yaw θ1)
    → ``<LEG>_femur`` (hip pitch θ2) → ``<LEG>_tibia`` (knee θ3) → ``<LEG>_foot``
    (fixed, at the foot point). The body link ``body`` is the root, its centre of mass at
    the body frame's origin. Load it with ``armlab.kinematics.urdf_read.quadruped_from_urdf``.
    """
    bx, by, bz = geom.body_size
    lines = [
        '<?xml version="1.0"?>',
        "<!-- Quadruped of seed 003 (4 legs x 3 Dynamixel AX-12A: hip yaw, hip pitch, knee).",
        "     Generated by armlab.kinematics.quadruped.quadruped_urdf(); edit the generator,",
        "     not this file.",
        f"     Femur {_f(geom.leg.femur)} m, tibia {_f(geom.leg.tibia)} m, hips at "
        f"(+-{_f(geom.hip_x)}, +-{_f(geom.hip_y)}) m.",
        "     Body frame: x forward, y left, z up. Joint angles are the seed's theta1 (yaw from",
        "     the outward axis towards forward), theta2 (femur below horizontal), theta3 (knee,",
        "     downward positive) on every leg. -->",
        '<robot name="quadruped">',
        f'  <link name="body"><inertial><mass value="{_f(geom.body_mass)}"/>'
        f'{_box_inertia(geom.body_mass, bx, by, bz)}</inertial>'
        f'<visual><geometry><box size="{_v(bx, by, bz)}"/></geometry>'
        '<material name="body"><color rgba="0.85 0.85 0.8 0.9"/></material></visual>'
        f'<visual><origin xyz="{_v(bx / 2 - 0.01, 0, bz / 2 + 0.005)}"/><geometry>'
        '<box size="0.02 0.04 0.01"/></geometry>'
        '<material name="nose"><color rgba="0.85 0.15 0.15 1"/></material></visual></link>',
    ]
    for leg in LEGS:
        lines.extend(_leg_urdf(leg, geom))
    lines.append("</robot>")
    return "\n".join(lines) + "\n"
