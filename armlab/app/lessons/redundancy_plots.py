"""The redundancy lesson's charts: the paper's figures for the whole 2 s run.

Five charts over the circle's 2 s, one line per simulation (mode colours as in
the scene), drawn once a run is computed (the 3D view plays it back):

1.-3. each joint angle, degrees, with its limits as dashed lines and the allowed
      band shaded between them (seed 002 §5: joint 1 [90°, 180°], joint 2
      [−90°, 0°], joint 3 [−180°, −90°]);
4. Yoshikawa's manipulability w = sqrt(det(J Jᵀ));
5. the position-error norm |x_d − x|, mm.

Unlike the live charts (``armlab.app.page.plots.LivePlot``, a window sliding with "now"), the
x axis is the run's own time, pinned to [0, duration] (``armlab.app.page.plots.fixed_x``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import viser

from armlab.app.lessons._common import joint_label
from armlab.app.lessons.redundancy_scene import MODE_COLORS
from armlab.app.page.plots import SeriesSpec, add_chart, fixed_x, uplot_series
from armlab.kinematics.model import SerialChain
from armlab.kinematics.redundancy import CircleRun
from armlab.kinematics.units import deg

LIMIT_COLOR = "#777777"
BAND_FILL = "rgba(46, 125, 50, 0.10)"


#: Mode -> dash pattern: mode 1 vs bounded (blue vs purple) and 2 vs 4 (drawn on top
#: of each other) are told apart by pattern, not only by colour.
MODE_DASHES: dict[str, tuple[int, ...] | None] = {
    "1": None, "2": None, "3": (2, 3), "4": (6, 4), "bounded": (12, 3, 2, 3)}
#: Mode -> line width: mode 2 (solid, as mode 1) is the wide line under the others.
MODE_WIDTHS = {"1": 2.0, "2": 4.0, "3": 2.0, "4": 2.0, "bounded": 2.0}


class RunPlot:
    """A uPlot chart of whole runs against their time, 0..``duration`` s.

    Args:
        gui: where to add it.
        title: chart title. y_label: left axis label.
        series: the lines (y arrays given to :meth:`show` in this order).
        duration: s, the x extent.
        bands: uPlot bands (series index pairs, 1-based as in uPlot) to shade.
        points: samples sent per line (the runs are decimated to about this many).
    """

    def __init__(self, gui: viser.GuiApi, *, title: str, y_label: str,
                 series: Sequence[SeriesSpec], duration: float, bands: tuple = (),
                 points: int = 126, height: int = 150) -> None:
        self.duration = float(duration)
        self.points = points
        self.n_series = len(series)
        self.handle = add_chart(
            gui, data=(np.array([0.0, self.duration]), *(np.zeros(2) for _ in series)),
            series=({"label": "t (s)"}, *(uplot_series(s) for s in series)),
            scales={"x": fixed_x(0.0, self.duration), "y": {"auto": True}},
            x_label="t (s)", y_label=y_label,
            bands=bands or None, title=title, height=height, legend={"live": False},
            cursor={"show": False})
        self.updates = 0  #: how many times data was sent

    def show(self, t: np.ndarray, ys: Sequence[np.ndarray]) -> None:
        """Draw the runs: ``t`` (N,) from 0 to ``duration``, one (N,) array per series."""
        if len(ys) != self.n_series:
            raise ValueError(f"ys: expected {self.n_series} series, got {len(ys)}")
        t = np.asarray(t, dtype=float)
        every = max(1, int(np.ceil(len(t) / self.points)))
        idx = np.unique(np.append(np.arange(0, len(t), every), len(t) - 1))
        x = t[idx].copy()
        x[0], x[-1] = 0.0, self.duration  # every run spans the whole axis
        self.handle.data = (x, *(np.asarray(y, dtype=float)[idx] for y in ys))
        self.updates += 1

    def remove(self) -> None:
        self.handle.remove()


class RedundancyPlots:
    """The five charts, added to ``gui`` in the current container.

    Args:
        gui: where to add them.
        model: the arm (joint names and limits).
        modes: the simulations, in series order.
        duration: length of a run, s.
    """

    def __init__(self, gui: viser.GuiApi, model: SerialChain, modes: tuple[str, ...], *,
                 duration: float = 2.0) -> None:
        self.model = model
        self.modes = modes
        # Mode 4 dashed: it runs exactly on top of mode 2 (docs/redundancy.md); every
        # mode differs from the others in dash pattern or width as well as colour.
        lines = tuple(SeriesSpec(f"mode {m}", MODE_COLORS[m], MODE_DASHES[m],
                                 width=MODE_WIDTHS[m]) for m in modes)
        limits = (SeriesSpec("lower limit", LIMIT_COLOR, (6, 4), width=1.0),
                  SeriesSpec("upper limit", LIMIT_COLOR, (6, 4), width=1.0))
        n = len(modes)
        # Shade the allowed band: between the upper (n + 2) and lower (n + 1) series.
        band = ({"series": (n + 2, n + 1), "fill": BAND_FILL},)
        self.joints = [RunPlot(gui, title=f"Joint {i + 1} angle {joint_label(name)} and its limits",
                               y_label="angle (°)", series=lines + limits, duration=duration,
                               bands=band) for i, name in enumerate(model.joint_names)]
        self.w = RunPlot(gui, title="Manipulability w = √det(J Jᵀ)", y_label="w (m²)",
                         series=lines, duration=duration)
        self.error = RunPlot(gui, title="Position error |x_d − x|", y_label="error (mm)",
                             series=lines, duration=duration)

    @property
    def plots(self) -> tuple[RunPlot, ...]:
        return (*self.joints, self.w, self.error)

    def show(self, runs: dict[str, CircleRun]) -> None:
        """Draw every run (all of the same length and sample times)."""
        t = runs[self.modes[0]].t
        lo, hi = deg(self.model.lower), deg(self.model.upper)
        for i, plot in enumerate(self.joints):
            ys = [deg(runs[m].q[:, i]) for m in self.modes]
            plot.show(t, [*ys, np.full(len(t), lo[i]), np.full(len(t), hi[i])])
        self.w.show(t, [runs[m].w for m in self.modes])
        self.error.show(t, [runs[m].error() * 1000.0 for m in self.modes])
