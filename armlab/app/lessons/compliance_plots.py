"""The compliance lesson's live charts: one joint at a time, about 10 s, degrees and N·m/kgf·cm.

Four charts for the chosen joint (a button group picks it, or a dropdown for an arm
whose joint names would not fit on a phone's row of buttons):

1. joint angle: command θ_cmd, reference θ_ref (sent to the servo), actual θ;
2. angle error θ_cmd − θ;
3. torque: the servo's load after the LPF against Newton–Euler τ_NE;
4. estimated external torque τ_ext (left axis) and the environment offset θ_env (right).

Showing one joint keeps a frame of charts near 10 KB (12 arrays of 101 float64),
about 110 kB/s per browser at 11 Hz while the arm moves. Picking another joint or
torque unit replaces the four charts (see :class:`armlab.app.page.plots.LivePlot`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from armlab.app.lessons._common import joint_label
from armlab.app.page.plots import (
    ANGLE_SPAN_DEG,
    COLORS,
    TORQUE_SPAN_NM,
    LivePlot,
    SeriesSpec,
    decimation,
    rebuild_plots,
)
from armlab.kinematics.units import KGF_CM_PER_NM

DEG = 180.0 / np.pi
TORQUE_UNITS = ("N·m", "kgf·cm")
#: viser ``order`` of the four charts (after the pickers): angle, external torque (the
#: push shows there: second, so it is in view at 1280x720 too), error, servo torque.
CHART_ORDER = (10.0, 11.0, 12.0, 13.0)
ERROR_SPAN_DEG = 2.0  #: smallest span of the angle error chart, °
#: characters of joint names a row of buttons holds on a phone; more get a dropdown
BUTTONS_MAX_CHARS = 24


class JointPlots:
    """The charts and their joint/unit pickers, added to ``gui`` inside ``container``.

    Args:
        gui: the GUI API.
        container: the tab (or folder) that holds them; re-entered to replace charts.
        joint_names: model joint names (chart order).
        default_joint: index shown first.
        window_s, points: chart window (s) and decimation bins.
        reference: the angle chart has a fourth line, dashed: the reference arm's angle
            (``armlab serve --exercise``: the lab's own law beside the student's).
    """

    def __init__(self, gui: viser.GuiApi, container: Any, joint_names: tuple[str, ...], *,
                 default_joint: int = 0, window_s: float = 10.0, points: int = 100,
                 reference: bool = False) -> None:
        self.gui = gui
        self.reference = reference
        self.container = container
        self.window_s = window_s
        self.points = points
        self.labels = tuple(joint_label(n) for n in joint_names)
        self._lock = threading.Lock()
        self._joint = default_joint
        self._unit = TORQUE_UNITS[0]
        self._stale = False
        with container:
            hint = "The joint the charts show"
            self.joint_picker: viser.GuiButtonGroupHandle | viser.GuiDropdownHandle
            if sum(len(label) for label in self.labels) <= BUTTONS_MAX_CHARS:
                buttons = gui.add_button_group("Joint", self.labels, order=1.0, hint=hint)
                buttons.on_click(self._pick)
                self.joint_picker = buttons
            else:
                dropdown = gui.add_dropdown("Joint", self.labels, order=1.0, hint=hint,
                                            initial_value=self.labels[default_joint])
                dropdown.on_update(self._pick)
                self.joint_picker = dropdown
            self.torque_unit = gui.add_dropdown("Torque unit", TORQUE_UNITS, order=2.0,
                                                initial_value=self._unit,
                                                hint="The thesis gives torques in kgf·cm")
        self._build()

        @self.torque_unit.on_update
        def _(_: viser.GuiEvent) -> None:
            if self.torque_unit.value != self._unit:
                self._unit = str(self.torque_unit.value)
                self._stale = True

    def _pick(self, _: viser.GuiEvent) -> None:
        value = str(self.joint_picker.value)
        if value in self.labels and self.labels.index(value) != self._joint:
            self._joint = self.labels.index(value)
            self._stale = True  # rebuilt by the next update

    def _build(self) -> None:
        j, u = self.labels[self._joint], self._unit
        k = KGF_CM_PER_NM if u == "kgf·cm" else 1.0
        kw: dict[str, Any] = {"window_s": self.window_s, "points": self.points}
        with self.container:
            self.angle = LivePlot(self.gui, title=f"Joint angle {j}", y_label="angle (°)",
                                  order=CHART_ORDER[0], series=(
                                      SeriesSpec("command θ_cmd", COLORS[0], (6, 4)),
                                      SeriesSpec("reference θ_ref", COLORS[1], (2, 3)),
                                      SeriesSpec("actual θ", COLORS[2]),
                                      *((SeriesSpec("lab's law θ (ghost)", COLORS[4],
                                                    (4, 4)),) if self.reference else ())),
                                  y_span=ANGLE_SPAN_DEG, **kw)
            self.error = LivePlot(self.gui, title=f"Angle error θ_cmd − θ, {j}",
                                  y_label="error (°)", order=CHART_ORDER[2], height=130,
                                  series=(SeriesSpec("error", COLORS[3]),),
                                  y_span=ERROR_SPAN_DEG, **kw)
            self.torque = LivePlot(self.gui, title=f"Torque {j}: servo (after LPF) vs "
                                                   "Newton–Euler",
                                   y_label=f"torque ({u})", order=CHART_ORDER[3], series=(
                                       SeriesSpec("servo, LPF", COLORS[2]),
                                       SeriesSpec("Newton–Euler", COLORS[4], (6, 4))),
                                   y_span=TORQUE_SPAN_NM * k, **kw)
            self.external = LivePlot(self.gui, title=f"External torque τ_ext and θ_env, {j}",
                                     y_label=f"τ_ext ({u})", y2_label="θ_env (°)",
                                     order=CHART_ORDER[1], series=(
                                         SeriesSpec("τ_ext", COLORS[3]),
                                         SeriesSpec("θ_env (°)", COLORS[5], (6, 4), "y2")),
                                     y_span=TORQUE_SPAN_NM * k, y2_span=ANGLE_SPAN_DEG, **kw)

    @property
    def joint(self) -> int:
        """Index of the joint shown."""
        return self._joint

    @property
    def unit(self) -> str:
        """Torque unit shown ("N·m" or "kgf·cm")."""
        return self._unit

    @property
    def plots(self) -> tuple[LivePlot, ...]:
        return (self.angle, self.error, self.torque, self.external)

    def update(self, snap: dict[str, np.ndarray], *, force: bool = False,
               reference: Callable[[np.ndarray, int], np.ndarray] | None = None) -> int:
        """Draw the newest window of ``snap`` (a recorder snapshot); returns charts sent.

        ``reference(t, joint)``: the reference arm's angle of ``joint`` at the times ``t``,
        rad (charts made with ``reference=True``; NaN without it)."""
        with self._lock:
            if self._stale:
                self._stale = False
                rebuild_plots(self.plots, self._build)
                force = True
            t = snap["t"]
            if len(t) < 2:
                return 0
            j = self._joint
            k = KGF_CM_PER_NM if self._unit == "kgf·cm" else 1.0
            col = {name: snap[name][:, j] for name in ("q_cmd", "q_ref", "q", "error",
                                                      "tau_load", "tau_dyn", "tau_ext",
                                                      "q_env")}
            # the four charts share the record's times: one decimation for all
            index = decimation(np.asarray(t, dtype=float), window_s=self.window_s,
                               points=self.points)
            sent = 0
            angles: tuple[np.ndarray, ...] = (col["q_cmd"] * DEG, col["q_ref"] * DEG,
                                              col["q"] * DEG)
            if self.reference:
                ref = (np.full(len(t), np.nan) if reference is None
                       else reference(np.asarray(t, dtype=float), j))
                angles = (*angles, ref * DEG)
            sent += self.angle.update(t, angles, force=force, index=index)
            sent += self.error.update(t, (col["error"] * DEG,), force=force, index=index)
            sent += self.torque.update(t, (col["tau_load"] * k, col["tau_dyn"] * k),
                                       force=force, index=index)
            sent += self.external.update(t, (col["tau_ext"] * k, col["q_env"] * DEG),
                                         force=force, index=index)
            return sent
