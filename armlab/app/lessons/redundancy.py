"""Lesson: a redundant planar arm on a circle, with and without its joint limits (seed 002).

The planar 3R arm (three links of 0.5 m) draws the paper's circle in five ways at
once, each a coloured ghost arm in its own panel: the paper's four simulations
(1: θ̇ = J⁺ẋ; 2: + joint limits by the decomposition method, eq. 10-20; 3: + the
manipulability gradient k_a ∇w in the null space, eq. 4; 4: both) and a method that
guarantees the limits (bounded least squares). Stick pictures, the end-effector path,
the manipulability ellipse and a red dot on any joint outside its limits show in the
scene; charts show each joint angle inside its limit band, the manipulability and the
position error over the whole run (the paper's figures).

"Run" calls the same functions as ``armlab experiment seed002-circle``
(``armlab.kinematics.redundancy.simulate_circle`` then
``armlab.control.experiments.seed002.summarise``)
for every mode with the gains on the sliders, in a worker thread; the figures
table shows exactly what the experiment prints. A :class:`Publisher` plays the
runs back at the chosen playback speed (scene at 30 Hz; the charts are sent once per run).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from armlab.app.lessons import Lesson, LessonContext
from armlab.app.lessons._common import (
    LessonBase,
    close_in_turn,
    esc,
    guarded,
    joint_label,
    set_content,
    status_html,
)
from armlab.app.lessons.redundancy_plots import RedundancyPlots
from armlab.app.lessons.redundancy_scene import (
    MODE_COLORS,
    MODE_LABELS,
    RedundancyScene,
    arm_points,
)
from armlab.app.page.inputs import guarded_slider, notify
from armlab.app.page.surface import Surface
from armlab.control.experiments.seed002 import SETTLE_S, summarise
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.redundancy import (
    MODES,
    CircleRun,
    CircleTask,
    simulate_circle,
)
from armlab.kinematics.units import deg

NAME = "redundancy"
TITLE = "Redundancy"
HELP = ("A redundant planar 3R arm draws the paper's circle five ways side by side: the four "
        "simulations of seed 002 (J⁺ only; joint limits by the decomposition method; the "
        "manipulability gradient k_a ∇w; both) and a bounded method that guarantees the "
        "limits. Watch the joints leave their limits (red dots), the manipulability ellipse "
        "and the charts; change k_a and K and run again.")
#: The first action, shown under the status line.
TRY = ("Press **Run the circle** and watch which arms leave their joint limits (red dots).")
ROBOTS = ("redundant_planar",)
ORDER = 20
#: a student's page can hold a private copy (it simulates on its own; no servos, no ``ctx.arms``)
PRIVATE = True

#: The simulations shown, in chart-series order.
SHOWN_MODES: tuple[str, ...] = ("1", "2", "3", "4", "bounded")
#: Slider ranges: k_a (paper 200) and K (paper 400; K Δt must stay below 2).
K_A_RANGE = (0.0, 500.0)
GAIN_RANGE = (10.0, 480.0)
SPEED_RANGE = (0.05, 1.0)


def build(server: Surface, ctx: LessonContext) -> RedundancyLesson:
    """Open the lesson on ``server`` (see :mod:`armlab.app.lessons`)."""
    return RedundancyLesson(server, ctx)


@dataclass(frozen=True)
class RunSet:
    """The five simulations for one pair of gains.

    Attributes:
        gain: K of ẋ = ẋ_d + K(x_d − x), 1/s. k_a: gradient gain of eq. 2.
        runs: mode -> the time series (``simulate_circle``).
        figures: mode -> what ``armlab experiment seed002-circle --mode M`` prints.
        points: mode -> (T, 4, 3) arm points of every sample (stick pictures).
    """

    gain: float
    k_a: float
    runs: dict[str, CircleRun]
    figures: dict[str, dict[str, Any]]
    points: dict[str, np.ndarray]

    @property
    def dt(self) -> float:
        t = next(iter(self.runs.values())).t
        return float(t[1] - t[0])

    @property
    def duration(self) -> float:
        return float(next(iter(self.runs.values())).t[-1])


def run_modes(model: SerialChain, *, gain: float, k_a: float,
              modes: tuple[str, ...] = SHOWN_MODES) -> RunSet:
    """Run every mode on the paper's circle with these gains (what "Run" does).

    Raises:
        ValueError: for gains the simulation refuses (e.g. K Δt >= 2).
    """
    task = CircleTask(gain=gain, k_a=k_a)
    runs, figures, points = {}, {}, {}
    for mode in modes:
        run = simulate_circle(model, mode, task)
        runs[mode] = run
        figures[mode] = summarise(model, run)
        points[mode] = arm_points(model, run.q)
    return RunSet(float(gain), float(k_a), runs, figures, points)


def figures_markdown(rs: RunSet | None) -> str:
    """The figures table (same numbers as the experiment) with the paper's claims."""
    if rs is None:
        return "*Press **Run** to compute the five simulations.*"
    rows = ["| mode | max error after 0.2 s (mm) | worst excursion θ1, θ2, θ3 (°) | mean w | "
            "min w |", "|---|---|---|---|---|"]
    for mode, f in rs.figures.items():
        v = ", ".join(f"{deg(x):.1f}" for x in f["max_violation_rad"])
        rows.append(f"| {MODE_LABELS[mode]} | {f['max_error_m'] * 1000:.3f} | {v} | "
                    f"{f['mean_manipulability']:.3f} | {f['min_manipulability']:.3f} |")
    w = {m: f["mean_manipulability"] for m, f in rs.figures.items()}
    same = abs(w.get("2", 0) - w.get("4", 1)) < 1e-9
    return "\n".join([
        f"**Figures** (K = {rs.gain:g} 1/s, k_a = {rs.k_a:g}; identical to "
        f"`armlab experiment seed002-circle --mode M --gain {rs.gain:g} --k-a {rs.k_a:g}`)",
        "", *rows, "",
        "The paper: 1 and 3 leave the limits (joints 2 and 3 in 1); 2 and 4 stay inside; "
        "w of 4 above w of 2. "
        + ("Here 2 and 4 are the **same motion**: the printed least-squares step "
           "(eq. 18-19) pulls the joints to the middle of their ranges and cancels the "
           "gradient term (docs/redundancy.md). The bounded method keeps the limits *and* "
           "raises w." if same else "Here w of 4 and of 2 differ."),
    ])


TEACH = """\
**What the five arms do** (seed 002, circle x_d(t) = (0.25(1 − cos πt), 0.25(2 + sin πt)) m,
2 s, Δt = 4 ms, task loop ẋ = ẋ_d + K(x_d − x)):

- **1** θ̇ = J⁺ẋ: the shortest joint velocity; joints 2 and 3 leave their limits.
- **3** θ̇ = J⁺ẋ + (I − J⁺J) k_a ∇w (eq. 4): the self-motion climbs the manipulability
  w = √det(J Jᵀ); still no limits.
- **2 / 4** limits as velocity bounds (θ_min − θ)/Δt ≤ θ̇ ≤ (θ_max − θ)/Δt (eq. 5-7), the
  decomposition J = [J_r J_nr] and the least-squares θ̇_r of eq. 18-20.
- **bounded** the same bounds as a hard constraint (bounded least squares): limits kept,
  gradient used.

The **ellipse** at the hand is {J θ̇ : |θ̇| ≤ 1}: its semi-axes are J's singular values,
their product is w. A thin ellipse means the hand can hardly move across it.
Joint dots turn **red** while the joint is outside its limits. Left column: no redundancy
use; right column: the gradient. Top row: no limits; middle row: the paper's limit
method; bottom: the guaranteed method.
"""


class RedundancyLesson(LessonBase):
    """The redundancy lesson on ``server`` (a :class:`armlab.app.lessons.LessonHandle`).

    Args:
        server: the viser server.
        ctx: robot choice (the lesson simulates; it drives no servos).
        pose_hz, plot_hz: scene and chart update rates.
    """

    def __init__(self, server: Surface, ctx: LessonContext, *,
                 pose_hz: float = 30.0, plot_hz: float = 10.0) -> None:
        super().__init__(server, ctx)
        model = load_robot(ctx.robot)
        if not isinstance(model, SerialChain) or model.n != 3:
            raise ValueError(f"robot: {ctx.robot} is not a planar 3R arm")
        self.model = model
        self.modes = SHOWN_MODES
        self.q0 = np.array(CircleTask().q0)
        self.results: RunSet | None = None
        self._worker: threading.Thread | None = None
        self.computing = False
        self.last_error = ""
        self._play_start: float | None = None  # monotonic time of t = 0 of the playback
        self._paused_t = 0.0
        self._shown_k = -1
        self._plotted: RunSet | None = None  # the runs the charts show
        with self.opening():
            self._build_gui()
            self.scene = RedundancyScene(server, model, modes=self.modes, root="/redundancy")
        self.show(0.0)
        self.publish(pose=self._pose_frame, plots=self._plot_frame, pose_hz=pose_hz,
                     plot_hz=plot_hz)

    # ================================================================== GUI

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.status = self._gui.add_status(try_this=TRY)
        tabs = self._gui.add(gui.add_tab_group(order=-70.0))
        with tabs.add_tab("Run", viser.Icon.PLAYER_PLAY):
            self.run_button = gui.add_button(
                "Run the circle", color="green", icon=viser.Icon.PLAYER_PLAY,
                hint="Compute the five simulations with these gains and play them")
            self.reset_button = gui.add_button(
                "Reset", icon=viser.Icon.REFRESH,
                hint="Back to θ(0) = [180°, −90°, −90°]; Run plays again")
            self.run_button.on_click(lambda e: guarded(e, self.run))
            self.reset_button.on_click(lambda e: guarded(e, self.reset))
            d = CircleTask()
            lo, hi = K_A_RANGE
            self.k_a = guarded_slider(
                gui, "k_a (gradient gain)", name="k_a", lo=lo, hi=hi, step=10.0,
                initial=d.k_a, apply=self._params_changed,
                hint="Gain of the manipulability gradient (eq. 2); the paper uses 200. "
                "Changes modes 3, 4 and bounded.")
            lo, hi = GAIN_RANGE
            self.gain = guarded_slider(
                gui, "K (1/s)", name="K", lo=lo, hi=hi, step=10.0, initial=d.gain,
                apply=self._params_changed, hint="Task-space gain of ẋ = ẋ_d + K(x_d − x); "
                "the paper uses 400. K Δt must stay below 2 (K < 500).")
            lo, hi = SPEED_RANGE
            self.speed = guarded_slider(
                gui, "Playback speed (×)", name="playback speed", lo=lo, hi=hi, step=0.05,
                initial=0.25, apply=self._speed_changed,
                hint="1 = real time (the circle takes 2 s)")
            self.k_a_slider, self.gain_slider = self.k_a.handle, self.gain.handle
            self.speed_slider = self.speed.handle
            with gui.add_folder("Show", expand_by_default=False):
                self.show_boxes: dict[str, Any] = {}
                for mode in self.modes:
                    box = gui.add_checkbox(MODE_LABELS[mode], True,
                                           hint=MODES[mode])
                    box.on_update(lambda _e, m=mode: self.scene.show_mode(  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
                        m, bool(self.show_boxes[m].value)))
                    self.show_boxes[mode] = box
        with tabs.add_tab("Figures", viser.Icon.TABLE):
            self.figures_md = gui.add_markdown(figures_markdown(None))
        with tabs.add_tab("Teach", viser.Icon.SCHOOL):
            gui.add_markdown(TEACH)
            gui.add_html(_legend_html())
        with self._gui.chart_panel("Charts") as tab, tab:
            self.plots = RedundancyPlots(gui, self.model, self.modes)

    # ================================================================== actions

    def _params_changed(self, _value: float) -> None:
        """k_a or K moved: the runs on screen no longer match the sliders (the status
        line, drawn every frame, says so)."""

    def _speed_changed(self, value: float) -> None:
        with self._lock:
            if self._play_start is not None:
                t = self.playhead()
                self._play_start = time.monotonic() - t / value

    @property
    def stale(self) -> bool:
        """True when the runs shown were made with other gains than the sliders'."""
        rs = self.results
        return rs is not None and (rs.gain != self.gain.value or rs.k_a != self.k_a.value)

    def run(self, *, wait: bool = False) -> None:
        """Compute the five runs with the sliders' gains (worker thread), then play them.

        With the same gains as the runs shown it just plays them again.

        Raises:
            ValueError: while a computation is still going.
        """
        with self._lock:
            if self.computing:
                raise ValueError("still computing the last run; wait a few seconds")
            if self.results is not None and not self.stale:
                self._restart_playback()
                return
            self.computing = True
            self.last_error = ""
            gain, k_a = self.gain.value, self.k_a.value
            self._worker = threading.Thread(target=self._compute, args=(gain, k_a),
                                            name="armlab-redundancy", daemon=True)
            self._worker.start()
            worker = self._worker
        if wait:
            worker.join()

    def _compute(self, gain: float, k_a: float) -> None:
        try:
            rs = run_modes(self.model, gain=gain, k_a=k_a, modes=self.modes)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError) as exc:
            with self._lock:
                self.computing = False
                self.last_error = str(exc)
            for client in self.server.get_clients().values():
                notify(client, "Run failed", str(exc))
            return
        with self._lock:
            if self._closed:
                return
            self.results = rs
            self.computing = False
            self.figures_md.content = figures_markdown(rs)
            self._restart_playback()

    def _restart_playback(self) -> None:
        with self._lock:
            self.scene.clear()
            self._shown_k = -1
            self._play_start = time.monotonic()

    def reset(self) -> None:
        """Stop the playback and put every arm back at θ(0)."""
        with self._lock:
            self.scene.clear()
            self._shown_k = -1
            self.hold_at(0.0)

    def hold_at(self, t: float) -> None:
        """Stop the playback at time ``t`` s of the runs and show that instant (the pages
        keep showing it until the next Run)."""
        with self._lock:
            self._play_start = None
            self._paused_t = float(t)
            self.show(t)

    def playhead(self) -> float:
        """Time of the runs shown now, s (0 before a run; stops at the end)."""
        rs = self.results
        if rs is None or self._play_start is None:
            return self._paused_t
        t = (time.monotonic() - self._play_start) * self.speed.value
        return min(t, rs.duration)

    # ================================================================== drawing

    def sample_at(self, t: float) -> int:
        """Index of the sample shown at time ``t`` s (0 without runs)."""
        rs = self.results
        if rs is None:
            return 0
        return int(np.clip(math.floor(t / rs.dt + 1e-9), 0, len(rs.runs[self.modes[0]].t) - 1))

    def ghost_q(self, mode: str) -> np.ndarray:
        """(3,) joint angles the ghost of ``mode`` shows now, rad."""
        return self.scene.views[mode].arm.q.copy()

    def show(self, t: float) -> None:
        """Pose every ghost at time ``t`` of the runs and draw sticks and paths so far."""
        with self._lock:
            rs = self.results
            if rs is None:
                if self._shown_k != 0:
                    for mode in self.modes:
                        self.scene.set_pose(mode, self.q0, status="θ(0) = [180°, −90°, −90°]")
                    self._shown_k = 0
                return
            k = self.sample_at(t)
            if k == self._shown_k:
                return
            for mode in self.modes:
                run = rs.runs[mode]
                self.scene.set_pose(mode, run.q[k], status=_mode_status(self.model, run, k))
                self.scene.set_history(mode, rs.points[mode], k + 1, rs.dt)
            self._shown_k = k

    def _pose_frame(self) -> None:
        if self.results is not None and self._play_start is not None:
            self.show(self.playhead())
        self._update_status()

    def _plot_frame(self, force: bool) -> None:
        rs = self.results
        if rs is None or (rs is self._plotted and not force):
            return
        self.plots.show(rs.runs)
        self._plotted = rs

    def _update_status(self) -> None:
        rs = self.results
        if self.computing:
            state, color = "computing the five runs…", "#1f5eea"
        elif self.last_error:
            state, color = f"run refused: {self.last_error}", "#b00020"
        elif rs is None:
            state, color = "ready: press Run", "#555"
        elif self._play_start is None:
            state, color = "reset to θ(0): press Run to play again", "#555"
        else:
            t = self.playhead()
            if t < rs.duration:
                state, color = f"playing t = {t:.2f} s of {rs.duration:g} s", "#1f5eea"
            else:
                state, color = "done: press Run to replay", "#2e7d32"
        note = ""
        if self.stale:
            note = ("<div style='color:#a15c00;font-size:0.85em'>k_a or K changed: press Run "
                    "to compute with the new gains</div>")
        set_content(self.status, status_html(
            state, color, f"K = {self.gain.value:g} 1/s · k_a = {self.k_a.value:g} · "
            f"playback ×{self.speed.value:g}", extra=note))

    # ================================================================== lifetime

    def close(self) -> None:
        """Stop the publisher, remove scene and GUI (a computation still going is dropped)."""
        if self.mark_closed():
            close_in_turn(self.publisher.close, self.scene.remove, self._gui.remove_all)


def _mode_status(model: SerialChain, run: CircleRun, k: int) -> str:
    """Two lines under a panel's title: which joints are outside their limits now; w and
    the error (each at most ``STATUS_CHARS`` characters, the panel's budget)."""
    q = run.q[k]
    out = [joint_label(model.joint_names[i]) for i in range(model.n)
           if q[i] < model.lower[i] - 1e-9 or q[i] > model.upper[i] + 1e-9]
    w = run.w[k]  # manipulability(task_jacobian(model, q)), stored by simulate_circle
    err = run.error()[k] * 1000.0 if run.t[k] >= SETTLE_S else float("nan")
    limits = "limits kept" if not out else f"{', '.join(out)} outside limits!"
    e = f" · error {err:.3f} mm" if math.isfinite(err) else ""
    return f"{limits}\nw = {w:.3f}{e}"


def _legend_html() -> str:
    items = "".join(
        f"<div><span style='display:inline-block;width:14px;height:4px;background:{c};"
        f"margin-right:6px;vertical-align:middle'></span>{esc(MODE_LABELS[m])}</div>"
        for m, c in MODE_COLORS.items())
    return f"<div style='font-size:0.85em'>{items}</div>"


#: This lesson, as the lab lists it (:data:`armlab.app.lessons.catalog.LESSONS`).
LESSON = Lesson(name=NAME, title=TITLE, help=HELP, first_step=TRY, robots=ROBOTS, build=build,
                order=ORDER, private=PRIVATE)

__all__ = ["RedundancyLesson", "RunSet", "run_modes", "build", "NAME", "TITLE", "HELP",
           "ROBOTS", "LESSON"]
