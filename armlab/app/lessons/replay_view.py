"""A run file played back beside the live robot: a ghost, a time slider, play/pause and a
chart of the run's recorded angles (the lesson's **Open run**).

The ghost shows the recorded sample nearest the slider's time, exactly as recorded (its
joint angles are the run's ``q`` at that sample, not an interpolation); the live robot and
its charts go on meanwhile. Play moves the slider at the run's own pace from where it is.

The ghost is made for the model the lesson drives (:func:`make_ghost`): a see-through
orange arm (a serial chain, its torso left out), a see-through quadruped standing at the
run's body height, or an orange hand beside the live one (the hand lesson's
:class:`armlab.kinematics.hand_statics.FingerGeometry`, joints finger1..3).
"""

from __future__ import annotations

import math
import threading
import time
from itertools import islice
from typing import Protocol

import numpy as np
import viser

from armlab.app.lessons._common import guarded, remove_quietly, set_content
from armlab.app.lessons.hand_scene import HandScene
from armlab.app.page.arm_view import ArmView
from armlab.app.page.plots import COLORS, SeriesSpec, add_chart, dash, fixed_x, uplot_series
from armlab.app.page.surface import Surface
from armlab.control.experiments.seed003 import joint_names as gait_joint_names
from armlab.control.runs import Run, check_drawable
from armlab.kinematics.hand_statics import FingerGeometry
from armlab.kinematics.model import Quadruped, SerialChain

#: The replay ghost's colour: see-through orange, apart from the blue command ghost and
#: the green reference arm.
REPLAY_RGBA = (0.95, 0.55, 0.1, 0.35)
#: Most samples the replay chart gets (evenly spaced recorded samples, first and last kept).
CHART_POINTS = 1500
#: Frames a second while playing.
PLAY_HZ = 30.0
#: The replay hand's fingers (orange, as the ghost arm) and where it stands beside the live
#: hand (palm frame, m).
HAND_GHOST_RGB = (240, 140, 25)
HAND_GHOST_OFFSET = (0.0, 0.16, 0.0)
#: The quadruped ghost's body height when the run does not say (its ``params["D_m"]``), m.
QUADRUPED_HEIGHT_M = 0.09

#: What a replay ghost can draw: an arm, a quadruped, the hand lesson's finger geometry.
GhostModel = SerialChain | Quadruped | FingerGeometry


class Ghost(Protocol):
    """A replay's ghost: posed by the run's joint vector ``q``."""

    @property
    def model(self) -> GhostModel: ...
    @property
    def joint_names(self) -> tuple[str, ...]: ...
    @property
    def q(self) -> np.ndarray: ...

    def set_q(self, q: np.ndarray) -> None: ...

    def place(self, run: Run) -> None: ...

    def set_visible(self, visible: bool) -> None: ...

    def remove(self) -> None: ...


def hand_joint_names(finger: FingerGeometry) -> tuple[str, ...]:
    """The hand's joints as a run names them: finger1, finger2, finger3."""
    return tuple(f"finger{i + 1}" for i in range(len(finger.azimuths)))


#: The robot name of a run of the hand lesson's hand.
HAND_ROBOT = "hand"


def ghost_robot(model: GhostModel) -> str:
    """The robot name a run of ``model`` carries ("hand" for the hand lesson's)."""
    return HAND_ROBOT if isinstance(model, FingerGeometry) else model.name


def ghost_joint_names(model: GhostModel) -> tuple[str, ...]:
    """The joints a run of ``model`` names, in its order."""
    if isinstance(model, FingerGeometry):
        return hand_joint_names(model)
    if isinstance(model, Quadruped):
        return gait_joint_names(model)  # legs RF, LF, RH, LH, hip to knee
    return model.joint_names


class RobotGhost:
    """A see-through orange copy of an arm (its torso left out) or of a quadruped (standing
    at the run's body height, at the origin: a run holds joint angles, not where it
    walked)."""

    def __init__(self, server: Surface, model: SerialChain | Quadruped, *, root: str) -> None:
        self.model = model
        self.joint_names = ghost_joint_names(model)
        self.view = ArmView(server, model, root=root, color=REPLAY_RGBA)
        if isinstance(model, SerialChain):
            self.view.see_through("torso", opacity=0.0)  # the arm only

    @property
    def q(self) -> np.ndarray:
        return self.view.q

    def set_q(self, q: np.ndarray) -> None:
        self.view.set_q(q)

    def place(self, run: Run) -> None:
        """A quadruped's body at the run's body height (``params["D_m"]``)."""
        if isinstance(self.model, Quadruped):
            height = run.params.get("D_m", QUADRUPED_HEIGHT_M)
            ok = isinstance(height, int | float) and 0.0 < float(height) < 1.0
            self.view.root.position = (0.0, 0.0, float(height) if ok else QUADRUPED_HEIGHT_M)

    def set_visible(self, visible: bool) -> None:
        self.view.root.visible = visible

    def remove(self) -> None:
        self.view.remove()


class HandGhost:
    """The hand drawn again, its fingers orange, beside the live hand
    (:data:`HAND_GHOST_OFFSET`), without an object or force arrows."""

    def __init__(self, server: Surface, finger: FingerGeometry, *, root: str) -> None:
        self.model = finger
        self.joint_names = hand_joint_names(finger)
        self.scene = HandScene(server, finger, root=root, finger_rgb=HAND_GHOST_RGB,
                               frame_view=False)
        self.scene.root.position = HAND_GHOST_OFFSET
        self.scene.set_object(None, 1000.0)
        self.q = np.full(len(self.joint_names), np.nan)
        self._no_force = np.zeros(len(self.joint_names))

    def set_q(self, q: np.ndarray) -> None:
        self.q = np.array(q, dtype=float)
        self.scene.set_state(self.q, self._no_force, 1.0)

    def place(self, run: Run) -> None:
        """Nothing: the ghost hand stays beside the live one."""

    def set_visible(self, visible: bool) -> None:
        self.scene.root.visible = visible

    def remove(self) -> None:
        self.scene.remove()


def make_ghost(server: Surface, model: GhostModel, *, root: str) -> Ghost:
    """The ghost of ``model`` under the scene node ``root`` (see the module docstring)."""
    if isinstance(model, FingerGeometry):
        return HandGhost(server, model, root=root)
    return RobotGhost(server, model, root=root)


def chart_index(m: int, *, most: int = CHART_POINTS) -> np.ndarray:
    """Indices of the samples (of ``m``) a replay chart shows: all, or ``most`` evenly
    spaced ones with the first and the last."""
    if m <= most:
        return np.arange(m)
    return np.unique(np.round(np.linspace(0, m - 1, most)).astype(int))


def sample_at(t: np.ndarray, at: float) -> int:
    """Index of the sample of ``t`` (m,) s, increasing, nearest ``at`` s (the earlier one
    on a tie)."""
    k = int(np.searchsorted(t, at, side="left"))
    if k <= 0:
        return 0
    if k >= len(t):
        return len(t) - 1
    return k if t[k] - at < at - t[k - 1] else k - 1


class ReplayView:
    """The Replay folder and the ghost (see the module docstring). Added where the caller's
    GUI context is; hidden until :meth:`show` gives it a run.

    Args:
        server: where the ghost is drawn.
        gui: the GUI API (call inside the tab that holds it).
        root: scene node of the ghost.

    Attributes:
        run: the run shown (None: none).
        ghost: the ghost (None: no run shown).
        index: the sample the ghost shows.
        chart_rows: the samples the chart shows (indices into the run).
    """

    def __init__(self, server: Surface, gui: viser.GuiApi, *, root: str) -> None:
        self.server = server
        self.gui = gui
        self.root = root
        self.run: Run | None = None
        self.ghost: Ghost | None = None
        self.index = 0
        self.chart_rows = np.zeros(0, dtype=int)
        self._t = np.zeros(0)  #: the run's times from its start, s
        self._lock = threading.RLock()
        self._playing = threading.Event()
        self._player: threading.Thread | None = None
        self._closed = False
        self.folder = gui.add_folder("Replay", expand_by_default=True, visible=False)
        with self.folder:
            self.about = gui.add_markdown("")
            self.time = gui.add_slider("Run time (s)", min=0.0, max=1.0, step=0.01,
                                       initial_value=0.0,
                                       hint="Where in the run the orange ghost is: it shows "
                                            "the recorded sample nearest this time")
            self.at = gui.add_markdown("")  #: the time and angles the ghost shows
            self.play = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY,
                                       hint="Play the run at its own pace from the slider's "
                                            "time (press again to pause)")
            self.close_button = gui.add_button("Close the replay", icon=viser.Icon.X,
                                               hint="Take the ghost and this chart away")
        self.chart: viser.GuiUplotHandle | None = None
        self.time.on_update(lambda e: self._show_at(float(self.time.value)))
        self.play.on_click(lambda e: guarded(e, self.toggle_play))
        self.close_button.on_click(lambda e: self.close_run())

    # ------------------------------------------------------------------ a run

    def show(self, run: Run, model: GhostModel, *, title: str) -> None:
        """Show ``run`` on a ghost of ``model`` (its joints the run's), at its start.

        Raises:
            ValueError: the run's joints (names, in order) are not the model's, or a value
                is beyond what can be drawn (:func:`armlab.control.runs.check_drawable`).
        """
        check_drawable(run, "the run")
        joints = ghost_joint_names(model)
        if tuple(run.joint_names) != joints:
            raise ValueError(f"its joints ({plain(', '.join(run.joint_names))}) are not this "
                             f"robot's ({', '.join(joints)}): open it where the same "
                             "robot is driven")
        self.pause()
        with self._lock:
            if self._closed:
                return
            if self.ghost is None or self.ghost.model is not model:
                if self.ghost is not None:
                    self.ghost.remove()
                self.ghost = make_ghost(self.server, model, root=self.root)
            self.ghost.place(run)
            self.ghost.set_visible(True)
            self.run = None  # until the slider is ready for this run
            self._t = run.t - run.t[0]
            duration = float(self._t[-1])
            step = float(np.median(np.diff(self._t))) if len(self._t) > 1 else 0.01
            self.index = -1
            self.time.max = max(duration, step)
            self.time.step = step
            self._add_chart(run)
            set_content(self.about, about_markdown(run, title=title))
            self.folder.visible = True
            if self.time.value != 0.0:
                self.time.value = 0.0  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
            # published last: a slider moved from here on is not undone by the reset above
            self.run = run
            self._show_at(0.0)

    def _add_chart(self, run: Run) -> None:
        if self.chart is not None:
            remove_quietly(self.chart)
        rows = self.chart_rows = chart_index(len(run.t))
        x = self._t[rows]
        degrees = [np.degrees(run.signals["q"][rows, j]) for j in range(len(run.joint_names))]
        series = [SeriesSpec(name.replace("theta", "θ"), COLORS[j % len(COLORS)], dash(j))
                  for j, name in enumerate(run.joint_names)]
        with self.folder:
            self.chart = add_chart(
                self.gui, title="Recorded angles (the run)", height=170,
                series=({"label": "t (s)"}, *(uplot_series(s) for s in series)),
                scales={"x": fixed_x(0.0, float(x[-1]) if x[-1] > 0 else 1.0),
                        "y": {"auto": True}},
                y_label="angle (°)", x_label="t from the run's start (s)",
                data=(x, *degrees), legend={"live": False}, cursor={"show": False})

    def _show_at(self, at: float) -> None:
        """Pose the ghost at the recorded sample nearest ``at`` s from the run's start."""
        with self._lock:
            run, ghost = self.run, self.ghost
            if run is None or ghost is None or not math.isfinite(at):
                return
            k = sample_at(self._t, at)
            if k == self.index:
                return
            self.index = k
            ghost.set_q(run.signals["q"][k])
            set_content(self.at, pose_line(run, k, t=float(self._t[k])))

    @property
    def ghost_q(self) -> np.ndarray | None:
        """The joint angles the ghost shows now, rad (None: no run shown)."""
        with self._lock:
            return None if self.ghost is None or self.run is None else self.ghost.q.copy()

    # ------------------------------------------------------------------ play

    def toggle_play(self) -> None:
        """Play from the slider's time (from the start when it is at the end), or pause."""
        if self._playing.is_set():
            self.pause()
            return
        with self._lock:
            if self.run is None:
                raise ValueError("no run is open: press Open run first")
            if float(self.time.value) >= float(self._t[-1]):
                self.time.value = 0.0  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
            self._playing.set()
            self.play.label = "Pause"
            self.play.icon = viser.Icon.PLAYER_PAUSE
            self._player = threading.Thread(target=self._play_loop, name="armlab-replay",
                                            daemon=True)
            self._player.start()

    def pause(self) -> None:
        """Stop playing (the ghost stays where it is)."""
        self._playing.clear()
        player = self._player
        if player is not None and player is not threading.current_thread():
            player.join(2.0)
        self._player = None
        with self._lock:
            if not self._closed and self.play.label != "Play":
                self.play.label = "Play"
                self.play.icon = viser.Icon.PLAYER_PLAY

    def _play_loop(self) -> None:
        last = time.monotonic()
        while self._playing.is_set():
            time.sleep(1.0 / PLAY_HZ)
            now = time.monotonic()
            with self._lock:
                if self.run is None or self._closed:
                    break
                end = float(self._t[-1])
                at = min(end, float(self.time.value) + (now - last))
                self.time.value = at  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
            last = now
            if at >= end:
                break
        self._playing.clear()
        with self._lock:
            if not self._closed:
                self.play.label = "Play"
                self.play.icon = viser.Icon.PLAYER_PLAY

    # ------------------------------------------------------------------ lifetime

    def close_run(self) -> None:
        """Hide the replay: ghost and chart away, the folder hidden."""
        self.pause()
        with self._lock:
            self.run = None
            if self.ghost is not None:
                remove_quietly(self.ghost)  # (a page that left has nothing to remove)
                self.ghost = None
            if self.chart is not None:
                remove_quietly(self.chart)
                self.chart = None
            if not self._closed:
                self.folder.visible = False

    def remove(self) -> None:
        """Stop playing and take the ghost away (the folder goes with the lesson's GUI)."""
        self.close_run()
        with self._lock:
            self._closed = True


def pose_line(run: Run, k: int, *, t: float) -> str:
    """The Replay folder's line under the slider: sample ``k``'s time from the run's start
    (``t`` s) and its recorded angles, degrees."""
    angles = " · ".join(f"{plain(name.replace('theta', 'θ'))} {math.degrees(q):+.1f}°"
                        for name, q in zip(run.joint_names, run.signals["q"][k], strict=True))
    return f"t = {t:.3f} s (sample {k + 1} of {len(run.t)}) · {angles}"


#: Most figures and most gains the Replay folder lists (a file may hold many more).
ABOUT_MOST = 40


def _more(items: dict) -> str:
    return f" … and {len(items) - ABOUT_MOST} more" if len(items) > ABOUT_MOST else ""


def about_markdown(run: Run, *, title: str) -> str:
    """What the Replay folder says of ``run``: its file, source, date, length, gains and
    figures (the file's text as plain words: no markup of its own reaches the page)."""
    duration = float(run.t[-1] - run.t[0])
    measured = [(k, v) for k, v in islice(run.figures.items(), ABOUT_MOST)
                if isinstance(v, float | int) and not isinstance(v, bool)]
    figures = ", ".join(f"{plain(k)} {v:.3g}" for k, v in measured) + _more(run.figures)
    gains = ", ".join(f"{plain(k)} {v:g}" if isinstance(v, float) else f"{plain(k)} {plain(v)}"
                      for k, v in islice(run.params.items(), ABOUT_MOST)) + _more(run.params)
    lines = [f"**{plain(title)}**: {plain(run.source)}, {plain(run.created)}, "
             f"{duration:.1f} s, {len(run.t)} samples, {len(run.commands)} commands "
             f"(lab {plain(run.lab_version)})"]
    if gains:
        lines.append(f"Gains: {gains}")
    if figures:
        lines.append(f"Figures: {figures}")
    return "\n\n".join(lines)


#: Characters that mean something in markdown or HTML, left out of a file's text.
MARKUP = frozenset("[]<>*`#|\\~&")


def plain(value: object, *, most: int = 80) -> str:
    """``value`` as text for the page: printable characters other than :data:`MARKUP`,
    at most ``most`` of them (a run file's names and words, shown as written)."""
    text = "".join(c for c in str(value) if c.isprintable() and c not in MARKUP)
    return text[:most] + ("…" if len(text) > most else "")
