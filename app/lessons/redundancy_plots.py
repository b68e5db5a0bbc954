"""The redundancy lesson's charts: the paper's figures, drawn as the runs play.

Five charts over the 2 s of the circle, one line per simulation (mode colours as
in the scene):

1.-3. each joint angle, degrees, with its limits as dashed lines and the allowed
      band shaded between them (seed 002 §5: joint 1 [90°, 180°], joint 2
      [−90°, 0°], joint 3 [−180°, −90°]);
4. Yoshikawa's manipulability w = sqrt(det(J Jᵀ));
5. the position-error norm |x_d − x|, mm.
"""

from __future__ import annotations

import numpy as np
import viser

from app.lessons.redundancy_scene import MODE_COLORS
from app.plots import LivePlot, SeriesSpec
from kinematics.model import SerialChain
from kinematics.redundancy import CircleRun

DEG = 180.0 / np.pi
LIMIT_COLOR = "#777777"
BAND_FILL = "rgba(46, 125, 50, 0.10)"


class RedundancyPlots:
    """The five charts, added to ``gui`` in the current container.

    Args:
        gui: where to add them.
        model: the arm (joint names and limits).
        modes: the simulations, in series order.
        duration: length of a run, s (the charts' window).
        points: decimation bins per chart.
    """

    def __init__(self, gui: viser.GuiApi, model: SerialChain, modes: tuple[str, ...], *,
                 duration: float = 2.0, points: int = 120) -> None:
        self.model = model
        self.modes = modes
        kw = {"window_s": duration + 0.05, "points": points, "height": 150}
        # Mode 4 dashed: it runs exactly on top of mode 2 (docs/redundancy.md).
        lines = tuple(SeriesSpec(f"mode {m}", MODE_COLORS[m], (6, 4) if m == "4" else None)
                      for m in modes)
        limits = (SeriesSpec("lower limit", LIMIT_COLOR, (6, 4)),
                  SeriesSpec("upper limit", LIMIT_COLOR, (6, 4)))
        self.joints = []
        n = len(modes)
        for i in range(model.n):
            plot = LivePlot(gui, title=f"Joint {i + 1} angle θ{i + 1} and its limits",
                            y_label="°", series=lines + limits, **kw)
            # Shade the allowed band: between the upper (n + 2) and lower (n + 1) series.
            plot.handle.bands = ({"series": (n + 2, n + 1), "fill": BAND_FILL},)
            self.joints.append(plot)
        self.w = LivePlot(gui, title="Manipulability w = √det(J Jᵀ)", y_label="w (m²)",
                          series=lines, **kw)
        self.error = LivePlot(gui, title="Position error |x_d − x|", y_label="mm",
                              series=lines, **kw)
        for plot in self.plots:  # the whole run on the x axis, filled as it plays
            scales = dict(plot.handle.scales or {})
            scales["x"] = {"time": False, "auto": False, "range": (0.0, duration)}
            plot.handle.scales = scales

    @property
    def plots(self) -> tuple[LivePlot, ...]:
        return (*self.joints, self.w, self.error)

    def update(self, runs: dict[str, CircleRun], k: int, *, force: bool = False) -> int:
        """Draw the first ``k`` samples of every run; returns how many charts were sent."""
        if not runs or k < 2:
            return 0
        first = runs[self.modes[0]]
        t = first.t[:k]
        sent = 0
        lo, hi = self.model.lower * DEG, self.model.upper * DEG
        for i, plot in enumerate(self.joints):
            ys = [runs[m].q[:k, i] * DEG for m in self.modes]
            ys += [np.full(k, lo[i]), np.full(k, hi[i])]
            sent += plot.update(t, ys, force=force)
        sent += self.w.update(t, [runs[m].w[:k] for m in self.modes], force=force)
        sent += self.error.update(t, [runs[m].error()[:k] * 1000.0 for m in self.modes],
                                  force=force)
        return sent
