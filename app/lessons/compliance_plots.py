"""The compliance lesson's live charts: one joint at a time, about 10 s, degrees and N·m/kgf·cm.

Four charts for the chosen joint (a button group picks it):

1. joint angle: command θ_cmd, reference θ_ref (sent to the servo), actual θ;
2. angle error θ_cmd − θ;
3. torque: the servo's load after the LPF against Newton–Euler τ_NE;
4. estimated external torque τ_ext (left axis) and the environment offset θ_env (right).

Showing one joint keeps a frame of charts near 10 KB (12 arrays of 101 float64),
about 110 kB/s per browser at 11 Hz while the arm moves.
"""

from __future__ import annotations

import numpy as np
import viser

from app.plots import COLORS, LivePlot, SeriesSpec
from kinematics.units import KGF_CM_PER_NM

DEG = 180.0 / np.pi
TORQUE_UNITS = ("N·m", "kgf·cm")


def joint_label(name: str) -> str:
    """"theta2" -> "θ2" (other names unchanged)."""
    return name.replace("theta", "θ")


class JointPlots:
    """The charts and their joint/unit pickers, added to ``gui`` in the current container.

    Args:
        gui: where to add them.
        joint_names: model joint names (chart order).
        default_joint: index shown first.
        window_s, points: chart window (s) and decimation bins.
    """

    def __init__(self, gui: viser.GuiApi, joint_names: tuple[str, ...], *, default_joint: int = 0,
                 window_s: float = 10.0, points: int = 100) -> None:
        self.labels = tuple(joint_label(n) for n in joint_names)
        self.joint_picker = gui.add_button_group("Joint", self.labels,
                                                 hint="The joint the charts show")
        self.joint_picker.value = self.labels[default_joint]
        self._titles = ("Joint angle {j}", "Angle error θ_cmd − θ, {j}",
                        "Torque {j}: servo (after LPF) vs Newton–Euler",
                        "External torque τ_ext and θ_env, {j}")
        self.torque_unit = gui.add_dropdown("Torque unit", TORQUE_UNITS, initial_value="N·m",
                                            hint="The thesis gives torques in kgf·cm")
        kw = {"window_s": window_s, "points": points}
        self.angle = LivePlot(gui, title="Joint angle", y_label="angle (°)", series=(
            SeriesSpec("command θ_cmd", COLORS[0], (6, 4)),
            SeriesSpec("reference θ_ref", COLORS[1]),
            SeriesSpec("actual θ", COLORS[2])), **kw)
        self.error = LivePlot(gui, title="Angle error θ_cmd − θ", y_label="error (°)", series=(
            SeriesSpec("error", COLORS[3]),), height=130, **kw)
        self.torque = LivePlot(gui, title="Torque: servo (after LPF) vs Newton–Euler",
                               y_label="torque (N·m)", series=(
                                   SeriesSpec("servo, LPF", COLORS[2]),
                                   SeriesSpec("Newton–Euler", COLORS[4], (6, 4))), **kw)
        self.external = LivePlot(gui, title="External torque τ_ext and θ_env",
                                 y_label="τ_ext (N·m)",
                                 y2_label="θ_env (°)", series=(
                                     SeriesSpec("τ_ext", COLORS[3]),
                                     SeriesSpec("θ_env (°)", COLORS[5], (6, 4), "y2")), **kw)
        self._shown: tuple[int, str] | None = None

        @self.joint_picker.on_click
        def _(_: viser.GuiEvent) -> None:
            self._shown = None  # redraw (and retitle) at the next frame

        @self.torque_unit.on_update
        def _(_: viser.GuiEvent) -> None:
            self._shown = None
            unit = str(self.torque_unit.value)
            for plot, name in ((self.torque, "torque"), (self.external, "τ_ext")):
                axes = list(plot.handle.axes or ())
                if len(axes) > 1:
                    axes[1] = {**axes[1], "label": f"{name} ({unit})"}
                    plot.handle.axes = tuple(axes)

    @property
    def joint(self) -> int:
        """Index of the joint shown."""
        value = str(self.joint_picker.value)
        return self.labels.index(value) if value in self.labels else 0

    @property
    def plots(self) -> tuple[LivePlot, ...]:
        return (self.angle, self.error, self.torque, self.external)

    def update(self, snap: dict[str, np.ndarray], *, force: bool = False) -> int:
        """Draw the newest window of ``snap`` (a recorder snapshot); returns charts sent."""
        t = snap["t"]
        if len(t) < 2:
            return 0
        j = self.joint
        unit = str(self.torque_unit.value)
        key = (j, unit)
        if key != self._shown:
            force = True
            for plot, title in zip(self.plots, self._titles, strict=True):
                plot.handle.title = title.format(j=self.labels[j])
        self._shown = key
        k = KGF_CM_PER_NM if unit == "kgf·cm" else 1.0
        col = {name: snap[name][:, j] for name in ("q_cmd", "q_ref", "q", "error", "tau_load",
                                                  "tau_dyn", "tau_ext", "q_env")}
        sent = 0
        sent += self.angle.update(t, (col["q_cmd"] * DEG, col["q_ref"] * DEG, col["q"] * DEG),
                                  force=force)
        sent += self.error.update(t, (col["error"] * DEG,), force=force)
        sent += self.torque.update(t, (col["tau_load"] * k, col["tau_dyn"] * k), force=force)
        sent += self.external.update(t, (col["tau_ext"] * k, col["q_env"] * DEG), force=force)
        return sent
