"""The hand lesson's 3D scene: palm, three fingers, their motors, the object, force arrows.

Everything hangs from one root frame (palm frame of :mod:`armlab.kinematics.hand_statics`: z
along the fingers, the object on the z axis). Each finger is a frame at its
hinge, turned to its azimuth and tilted by its angle; a box is the finger, a
sphere its fingertip pad, coloured from grey (no force) to red (at the limit).
"""

from __future__ import annotations

import math

import numpy as np
import viser
import viser.transforms as vtf

from armlab.app.page import theme
from armlab.app.page.camera import View, show
from armlab.app.page.surface import Surface
from armlab.kinematics.hand_statics import FingerGeometry, tip_positions

OBJECT_HEIGHT = 0.09  #: m, height of the drawn cylinder
ARROW_M_PER_N = 0.03  #: arrow length per newton of fingertip force
PAD_RADIUS = 0.007
IDLE_RGB = (150, 150, 150)
LIMIT_RGB = (220, 30, 30)
FINGER_RGB = (40, 70, 160)


def stiffness_rgb(stiffness: float) -> tuple[int, int, int]:
    """Object colour: soft (100 N/m) light green to hard (50 kN/m) dark grey, log scale."""
    a = float(np.clip((math.log10(stiffness) - 2.0) / (math.log10(5e4) - 2.0), 0.0, 1.0))
    soft, hard = np.array([120, 210, 120]), np.array([80, 80, 90])
    return tuple(int(v) for v in (1 - a) * soft + a * hard)  # type: ignore[return-value]  # three ints: an RGB colour


#: rad a finger must turn before the page is sent its new pose (0.006°: not visible)
STILL_RAD = 1e-4


def pad_rgb(force: float, limit: float) -> tuple[int, int, int]:
    """Fingertip colour for ``force`` N against the limit ``limit`` N."""
    a = float(np.clip(force / limit, 0.0, 1.0)) if limit > 0 else 0.0
    c = (1 - a) * np.array(IDLE_RGB) + a * np.array(LIMIT_RGB)
    return tuple(int(v) for v in c)  # type: ignore[return-value]  # three ints: an RGB colour


class HandScene:
    """Scene nodes of the hand lesson under ``root``.

    Args:
        server: viser server.
        finger: the hand's geometry.
        root: scene node holding everything (removed by :meth:`remove`).
        finger_rgb: the fingers' colour (a replay's ghost hand: orange).
        frame_view: frame the page's camera on the hand (False: leave the view as it is).
    """

    def __init__(self, server: Surface, finger: FingerGeometry, *, root: str,
                 finger_rgb: tuple[int, int, int] = FINGER_RGB,
                 frame_view: bool = True) -> None:
        self.g = finger
        scene = server.scene
        self.root = scene.add_frame(root, show_axes=False)
        g = finger
        scene.add_cylinder(f"{root}/palm", radius=g.hinge_radius + 0.012, height=0.01,
                           color=(235, 235, 240), position=(0.0, 0.0, -0.005))
        self.fingers: list[viser.FrameHandle] = []
        self.pads: list[viser.IcosphereHandle] = []
        self._shown_phi = [g.open_angle] * len(g.azimuths)  #: what the page shows, rad
        self._shown_rgb: list[tuple[int, int, int] | None] = [None] * len(g.azimuths)
        for i, az in enumerate(g.azimuths):
            hinge = (g.hinge_radius * math.cos(az), g.hinge_radius * math.sin(az), 0.0)
            # the 6 V gearmotor (24 x 10 x 12 mm) under the palm, pulling the tendon
            scene.add_box(f"{root}/motor{i}", color=(200, 160, 40), dimensions=(0.024, 0.010,
                                                                                0.012),
                          wxyz=vtf.SO3.from_z_radians(az).wxyz,
                          position=(0.6 * hinge[0], 0.6 * hinge[1], -0.018))
            frame = scene.add_frame(f"{root}/finger{i}", show_axes=False, position=hinge,
                                    wxyz=self._finger_wxyz(az, g.open_angle))
            scene.add_box(f"{root}/finger{i}/link", color=finger_rgb,
                          dimensions=(0.010, 0.016, g.length), position=(0.0, 0.0, g.length / 2))
            pad = scene.add_icosphere(f"{root}/finger{i}/pad", radius=PAD_RADIUS,
                                      color=IDLE_RGB, position=(-0.004, 0.0, g.length))
            self.fingers.append(frame)
            self.pads.append(pad)
        self.object = scene.add_cylinder(f"{root}/object", radius=0.03, height=OBJECT_HEIGHT,
                                         color=stiffness_rgb(1000.0), opacity=0.45,
                                         position=(0.0, 0.0, 0.01 + OBJECT_HEIGHT / 2))
        self.arrows = scene.add_arrows(f"{root}/forces", points=np.zeros((3, 2, 3)),
                                       colors=LIMIT_RGB, shaft_radius=0.0015, head_radius=0.004,
                                       head_length=0.008, visible=False)
        self.label = theme.add_label(scene, f"{root}/label", "", position=(0.0, 0.0, 0.12))
        if frame_view:  # from the front right, above the palm
            show(server, View(roots=(root,), direction=(-0.14, 0.185, -0.125)))

    @staticmethod
    def _finger_wxyz(azimuth: float, phi: float) -> np.ndarray:
        """Finger frame: turned to ``azimuth`` about z, tilted by ``phi`` towards the axis.

        In the finger's plane x is radial outward, so closing (phi > 0) turns +z
        towards −x: a rotation by −phi about the frame's y axis.
        """
        cz, sz = math.cos(0.5 * azimuth), math.sin(0.5 * azimuth)
        cy, sy = math.cos(-0.5 * phi), math.sin(-0.5 * phi)
        return np.array([cz * cy, -sz * sy, cz * sy, sz * cy])  # q_z(azimuth) ⊗ q_y(−phi)

    def set_object(self, size: float | None, stiffness: float) -> None:
        """Draw the object: a cylinder of diameter ``size`` m (None: no object)."""
        if size is None:
            self.object.visible = False
            return
        self.object.radius = 0.5 * size
        self.object.color = stiffness_rgb(stiffness)
        self.object.visible = True

    def set_state(self, phi: np.ndarray, force: np.ndarray, limit: float) -> None:
        """Pose the fingers at ``phi`` (3,) rad and show the fingertip forces (3,) N.

        Sends only what the page would see change: a finger that turned by more than
        :data:`STILL_RAD`, a pad whose colour changed, the arrows while a force shows (a
        class of resting hands costs its pages nothing)."""
        g = self.g
        for i, az in enumerate(g.azimuths):
            if abs(float(phi[i]) - self._shown_phi[i]) > STILL_RAD:
                self._shown_phi[i] = float(phi[i])
                self.fingers[i].wxyz = self._finger_wxyz(az, float(phi[i]))
            rgb = pad_rgb(float(force[i]), limit)
            if rgb != self._shown_rgb[i]:
                self._shown_rgb[i] = rgb
                self.pads[i].color = rgb
        if np.max(force) < 0.01:
            if self.arrows.visible:
                self.arrows.visible = False
            return
        tips = tip_positions(g, phi)
        azimuths = np.asarray(g.azimuths)
        inward = -np.stack([np.cos(azimuths), np.sin(azimuths), np.zeros(3)], axis=1)
        # the object pushes each pad outward; draw the finger's push on the object (inward)
        start = tips - inward * (force[:, None] * ARROW_M_PER_N)
        self.arrows.points = np.stack([start, tips], axis=1).astype(np.float32)
        self.arrows.visible = True

    def set_label(self, text: str) -> None:
        self.label.text = text

    def remove(self) -> None:
        self.root.remove()
