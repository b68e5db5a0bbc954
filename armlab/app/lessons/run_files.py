"""The Files tab of a lesson: **Save run**, **Open run**, **Export page**.

- **Save run** sends the browser that pressed it the last run as a run file
  (:mod:`armlab.control.runs`), named ``<robot>-<lesson>-<UTC time>.armlab-run.zip``.
  A run begins with the command a lesson posts with ``run=`` (or marks with
  :meth:`RunControls.begin_run`): from then on its rows are kept apart from the loop's
  record (:class:`armlab.control.run_track.RunTrack`, at most 120 s and 30 000 samples)
  until the lesson says it is over (:meth:`RunControls.finish_run`, with that run's own
  figures) and a settling tail. The runs each lesson marks (docs/runs.md has the
  table): the compliance lesson's step, thesis line, push, hand drag and challenges; the
  arm lesson's joint-slider moves, Home, hand-target drags and pushes; the hand's grasp
  and open; the quadruped's walks. The file holds the gains at its start and every
  change of them, the commands from its first, every signal at the loop rate, its
  figures, who saved it (the page's name in a class), which law ran (the lab's or the
  student's file, with its SHA-256 and text), the backend and the lab's version. Saved
  while the run goes on, it holds the run up to now, marked unfinished (no figures
  yet); with no run yet, the record's live window, labelled so.
- **Open run** takes a run file from the page (it arrives over the gated websocket;
  larger than :data:`armlab.control.runs.MAX_FILE_BYTES`, or past a page's or the lab's
  unfinished uploads, it is refused before it is kept, and a page's unfinished uploads
  go when it leaves: :mod:`armlab.app.viser_ext.uploads`), checks it with
  :func:`armlab.control.runs.read_run` for this lesson's robot, and plays it on a ghost
  arm (:class:`armlab.app.lessons.replay_view.ReplayView`). A bad file, and every
  upload that fails, gets one notification with the reason (at most 300 characters) on
  the page that sent it; the lab goes on.
- **Export page** sends the current run as one self-contained HTML page
  (:func:`armlab.app.export.html.export_html`).

A lesson posts its commands through :meth:`RunControls.post` (or tells
:meth:`RunControls.note` of one posted elsewhere), so that they go into the file.
The same code serves a student's private arm in a classroom: the lesson is built on
their page, its loop is the mirror of the worker's (whose recorder the worker's rows
are copied into), and the file goes to their browser.

A servo-arm lesson hands over its model and :class:`~armlab.control.loop.ControlLoop`
(``arm=``); a lesson with a loop of its own (the hand, the quadruped) hands over a
:class:`Recording` of it (``record=``): the robot, its record in the recorder's
layout, its parameters and the lesson's own signals (the hand's currents and forces,
:attr:`armlab.control.runs.Run.lesson_signals`), and its loop's record (``rows=``, a
:class:`~armlab.control.run_track.RowSource`) that its runs' rows are kept from; the
lesson lays a run's rows out (``record(rows=...)``). Every lesson calls
:meth:`RunControls.tick` at its publisher's every tick, a page open or not.

The compliance lesson's CSV download is :meth:`RunControls.run_csv`: the rows Save run
saves, through the same selection (:meth:`RunControls._selected`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import viser

from armlab.app.export.html import export_html
from armlab.app.lessons import Figures
from armlab.app.lessons._common import send_download
from armlab.app.lessons.replay_view import GhostModel, ReplayView, ghost_robot
from armlab.app.lessons.run_facts import GainLog, backend_json, law_json
from armlab.app.page.inputs import notify
from armlab.app.page.surface import Surface
from armlab.app.viser_ext import HooksMissing
from armlab.app.viser_ext.uploads import limit_uploads
from armlab.control.loop import ControlLoop
from armlab.control.recorder import snapshot_csv
from armlab.control.run_track import TAIL_S, RowSource, RunTrack
from armlab.control.runs import (
    MAX_FILE_BYTES,
    SUFFIX,
    Run,
    RunFileError,
    clip,
    read_run,
    run_bytes,
    run_from_snapshot,
)
from armlab.control.trajectory import JointTrajectory
from armlab.kinematics.model import SerialChain

#: Commands kept for the file (the oldest go first: a dragged target posts many).
MAX_COMMANDS = 5000
#: s of record kept before the run's first command (the pose it started from)
LEAD_S = 0.5
#: What a run file's ``extra.run.state`` says (docs/runs.md).
FINISHED, UNFINISHED, LIVE = "finished", "unfinished", "live window"
#: The title of every refusal of a file.
REFUSED = "Run file refused"
#: The most characters of a refusal's reason a notification shows.
MAX_REASON_CHARS = 300

log = logging.getLogger(__name__)


class _Status(Protocol):
    @property
    def t(self) -> float: ...


class CommandedLoop(Protocol):
    """A loop :meth:`RunControls.post` posts to: a servo arm's, the hand's, the quadruped's."""

    def post(self, command: Any) -> None: ...

    @property
    def status(self) -> _Status: ...


@dataclass(frozen=True)
class Recording:
    """A lesson's robot and its record now, as the Files tab saves it.

    Attributes:
        model: what the replay's ghost and the exported page draw (an arm, a quadruped,
            the hand's finger geometry).
        robot: the run's robot name.
        joint_names: its joints, in the record's order.
        snapshot: "t" (m,) s and per-joint (m, n) arrays in the recorder's layout: "q"
            (measured angles, rad), any of :data:`armlab.control.recorder.SIGNALS`, and
            each of ``lesson_signals``; other keys are not saved.
        params: the parameters in force (numbers, text, booleans).
        lesson_signals: the lesson's own signals in ``snapshot``, name -> unit.
        extra: JSON for the file's ``extra`` beside the lesson's own.
    """

    model: GhostModel
    robot: str
    joint_names: tuple[str, ...]
    snapshot: Mapping[str, np.ndarray]
    params: Mapping[str, Any]
    lesson_signals: Mapping[str, str] = field(default_factory=dict)
    extra: Mapping[str, object] = field(default_factory=dict)


def arm_recording(model: SerialChain, loop: ControlLoop, *, whole: bool = True) -> Recording:
    """A servo-arm lesson's :class:`Recording`: its loop's recorder (its whole window;
    ``whole=False``: none of it, for a run kept apart) and gains."""
    snap = loop.recorder.snapshot() if whole else {}
    return Recording(model=model, robot=model.name, joint_names=model.joint_names,
                     snapshot=snap, params=loop.params.as_dict())


@dataclass
class _Run:
    """The last run begun (:meth:`RunControls.begin_run`)."""

    label: str
    t0: float
    params: dict[str, Any]
    law: dict[str, Any]
    track: RunTrack | None  #: its rows (None: a lesson without a recorder: the window's)
    extra: dict[str, object] = field(default_factory=dict)  #: the lesson's, at its start
    figures: dict[str, float | None] | None = None  #: frozen when measured
    finished_at: float | None = None


def command_json(command: object, *, t: float) -> dict[str, Any]:
    """``command`` (a loop command dataclass) as a run file's JSON entry: ``{"t": s,
    "kind": class name, field: value, ...}``, arrays as lists, a trajectory as its name,
    times (s) and angles (rad). A mapping with a "kind" is taken as the entry itself."""
    if isinstance(command, Mapping) and isinstance(command.get("kind"), str):
        return {"t": float(t), **{str(k): _json_value(v) for k, v in command.items()
                                  if k != "t"}}
    out: dict[str, Any] = {"t": float(t), "kind": type(command).__name__}
    if dataclasses.is_dataclass(command):
        for f in dataclasses.fields(command):
            out[f.name] = _json_value(getattr(command, f.name))
    return out


def _json_value(value: object) -> object:
    if isinstance(value, JointTrajectory):
        return {"name": value.name, "times": value.times.tolist(), "q": value.q.tolist()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return str(value)


def file_stamp() -> str:
    """The UTC time now as a file name's part: ``20261128T031800Z``."""
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())


def commands_in_record(commands: list[dict[str, Any]], t: np.ndarray
                       ) -> list[dict[str, Any]]:
    """The ``commands`` whose effect the record holds.

    A command's ``t`` is the loop time of the last period run when it was posted (a
    lesson reads it from the loop's status), so the loop applies it one period later: a
    command posted before the record's first sample, in the period just before it, is
    still the run's (e.g. one posted at once to a new loop, whose first sample comes
    one period after its status' time). Times are compared to half a period, as loop
    times are sums of periods.

    Args:
        commands: as :meth:`RunControls.note` kept them, oldest first.
        t: (m,) s, the record's sample times (m ≥ 1), oldest first.
    """
    period = float(t[1] - t[0]) if len(t) > 1 else 0.0
    return [c for c in commands if c["t"] >= t[0] - 1.5 * period]


class RunControls:
    """The Files tab (see the module docstring): added where the caller's GUI context is.

    Args:
        server: the lesson's surface (the ghost is drawn there).
        gui: its GUI API (call inside the tab).
        lesson: the lesson's name (the file's ``source`` is ``page:<lesson>``).
        arm: () -> the model and loop the lesson drives now (a servo-arm lesson).
        record: () -> the lesson's :class:`Recording` now (instead of ``arm``); with
            ``rows``, also ``record(rows=snap)``: the Recording of a run's rows ``snap``
            (its loop record's ``unpack`` layout) instead of the window.
        rows: () -> the loop record a ``record`` lesson's runs are kept from (a
            :class:`~armlab.control.run_track.RowSource`: the hand's, the quadruped's) and
            its period, s, or less (None: such a run is the record's window from its start).
        model: () -> what the lesson draws now (with ``record``: opening a run needs no
            record).
        figures: () -> the lesson's figures (``run_figures``).
        start: () -> loop time the current run started (None: from the first command the
            record still holds, or the whole record).
        extra: () -> free JSON for the file's ``extra`` (link lengths, backend, ...).
        ghost_root: scene node of the replay ghost.
        ctx: the lesson's context: its backend kind and port, the student's law, the
            class's page names (None: a simulated arm, the lab's law, no class).
        backend: () -> the backend object (its servos' models go into the file).
        live_figures: a save with no run holds the lesson's figures (False: none, for a
            lesson whose runs carry their own: a window's figures would be another run's).

    Attributes:
        replay: the replay (ghost, slider, chart).
    """

    def __init__(self, server: Surface, gui: viser.GuiApi, *, lesson: str,
                 arm: Callable[[], tuple[SerialChain, ControlLoop]] | None = None,
                 record: Callable[..., Recording] | None = None,
                 rows: Callable[[], tuple[RowSource, float]] | None = None,
                 model: Callable[[], GhostModel] | None = None,
                 figures: Callable[[], Figures],
                 start: Callable[[], float | None] | None = None,
                 extra: Callable[[], Mapping[str, object]] | None = None,
                 ghost_root: str, ctx: Any = None,
                 backend: Callable[[], object] | None = None,
                 live_figures: bool = True) -> None:
        self._arm = arm
        if arm is not None:
            record, model = (lambda: arm_recording(*arm())), (lambda: arm()[0])
        if record is None or model is None:
            raise ValueError("RunControls needs arm=, or record= and model=")
        self.server = server
        self.lesson = lesson
        self._record = record
        self._rows = rows
        self._model = model
        self._figures = figures
        self._start = start or (lambda: None)
        self._extra = extra or dict
        self._commands: deque[dict[str, Any]] = deque(maxlen=MAX_COMMANDS)
        self._commands_lock = threading.Lock()  # posted from callbacks, read by Save
        self._ctx = ctx
        self._backend = backend or self._loop_backend
        self._live_figures = live_figures
        self._run: _Run | None = None
        self._gains = GainLog()
        self.save = gui.add_button("Save run", icon=viser.Icon.DEVICE_FLOPPY,
                                   hint="Download this run as one file (.armlab-run.zip: "
                                        "gains, commands, every recorded signal, figures) "
                                        "to keep, hand in, or open here again")
        self.open = gui.add_upload_button("Open run", icon=viser.Icon.FOLDER_OPEN,
                                          mime_type=".zip,application/zip",
                                          hint="Play a saved run file on a see-through "
                                               "ghost beside the live arm")
        self.export = gui.add_button("Export page", icon=viser.Icon.FILE_EXPORT,
                                     hint="Download this run as one HTML page (3D arm, "
                                          "charts, gains, figures) that opens offline")
        self.save.on_click(lambda e: send_download(
            e, lambda: self.save_file(by=getattr(e.client, "client_id", None))))
        self.export.on_click(lambda e: send_download(
            e, lambda: self.export_file(by=getattr(e.client, "client_id", None))))
        self._upload_lock = threading.Lock()
        self._last_upload: object = None  #: the upload last opened (or refused)
        self.open.on_upload(self._on_upload)
        try:
            limit_uploads(gui, max_bytes=MAX_FILE_BYTES, on_refused=self._refused,
                          connected=lambda: set(self.server.get_clients()))
        except HooksMissing as exc:  # no limit can be kept: take no files at all
            self.open.disabled = True
            self.open.hint = f"not available with this viser: {exc}"
        self.replay = ReplayView(server, gui, root=ghost_root)

    # ------------------------------------------------------------------ commands

    def post(self, loop: CommandedLoop, command: object, *, run: str | None = None) -> None:
        """Post ``command`` to ``loop`` and keep it for the file (at the loop's time); with
        ``run`` (its label, e.g. "step θ2") the command begins a run
        (:meth:`begin_run`)."""
        t = loop.status.t
        loop.post(command)  # (refused: the last run stays the last)
        if run is not None:
            self.begin_run(run, t=t)
        self.note(command, t=t)

    def begin_run(self, label: str, *, t: float) -> None:
        """A run labelled ``label`` begins at loop time ``t`` s (its first command's): its
        rows are kept from now (and :data:`LEAD_S` s before), the last run's are let go."""
        arm = self._arm() if self._arm is not None else None
        params = arm[1].params.as_dict() if arm is not None else dict(self._record().params)
        track = None
        if arm is not None:
            loop = arm[1]
            track = RunTrack(loop.recorder, t0=t, period=float(loop.params.period))
            self._gains.see(params, t=t)
        elif self._rows is not None:
            source, period = self._rows()
            track = RunTrack(source, t0=t, period=float(period))
        self._run = _Run(label=label, t0=float(t), params=params, track=track,
                         law=law_json(getattr(self._ctx, "law", None), params),
                         extra=dict(self._extra()))  # (its link lengths, if rebuilt since)

    def finish_run(self, figures: Mapping[str, float | None] | None = None, *,
                   t: float) -> None:
        """The run is over at loop time ``t`` s, measured as ``figures`` (name -> value,
        the unit in the name; only that run's): the file keeps those, and the rows to
        :data:`~armlab.control.run_track.TAIL_S` s after ``t``."""
        run = self._run
        if run is None or run.finished_at is not None:
            return
        run.figures = {k: v for k, v in dict(figures or {}).items()}
        run.finished_at = float(t)
        if run.track is not None:
            run.track.finish(t)

    def tick(self) -> None:
        """Keep the run's new rows and see the gains (a lesson calls this often, at least
        once per recorder window: its publisher's every tick)."""
        if self._arm is None:
            run = self._run
            if run is not None and run.track is not None:
                run.track.pull()
            return
        try:
            _, loop = self._arm()
        except ValueError:  # the arm is being rebuilt
            return
        self._gains.see(loop.params.as_dict(), t=loop.status.t)
        run = self._run
        if run is not None and run.track is not None:
            run.track.pull()

    def _loop_backend(self) -> object | None:
        """The backend of the arm's loop (None: no arm, or it is being rebuilt)."""
        if self._arm is None:
            return None
        try:
            return getattr(self._arm()[1], "backend", None)
        except ValueError:
            return None

    @property
    def run_label(self) -> str | None:
        """The last run's label (None: no run yet)."""
        run = self._run
        return None if run is None else run.label

    @property
    def going_on(self) -> str | None:
        """The label of the run that goes on (begun, not finished yet), or None."""
        run = self._run
        return None if run is None or run.finished_at is not None else run.label

    @property
    def run_t0(self) -> float | None:
        """Loop time the last run began, s (its first command's; None: no run)."""
        run = self._run
        return None if run is None else run.t0

    @property
    def run_span(self) -> tuple[float, float] | None:
        """(first, last) loop time, s, the last run keeps so far (None: no run, or a run
        without a track of its own)."""
        run = self._run
        return None if run is None or run.track is None else run.track.span()

    def note(self, command: object, *, t: float) -> None:
        """Keep ``command``, posted at loop time ``t`` s, for the file."""
        entry = command_json(command, t=t)
        with self._commands_lock:
            self._commands.append(entry)

    @property
    def commands(self) -> list[dict[str, Any]]:
        """The commands kept (at most :data:`MAX_COMMANDS`, the newest), oldest first."""
        with self._commands_lock:
            return list(self._commands)

    # ------------------------------------------------------------------ the run

    def current_run(self, *, by: int | None = None) -> Run:
        """The last run (whole, or up to now marked unfinished), or with no run the
        record's live window; saved by page ``by`` (its client id, for who saved it).

        Raises:
            ValueError: nothing recorded yet.
        """
        rec, snap, kw = self._selected()
        return self._make_run(rec, snap, by=by, **kw)

    def run_csv(self) -> tuple[dict[str, Any], str]:
        """The rows :meth:`current_run` saves, as CSV text (a servo-arm lesson's: the
        recorder's columns, :func:`armlab.control.recorder.snapshot_csv`, with the run's
        gains in a header line), and what the file says of the run (its ``extra.run``:
        label, state, times). One path with Save run: the same run, the same rows.

        Raises:
            ValueError: nothing recorded yet, or not a servo-arm lesson.
        """
        if self._arm is None:
            raise ValueError("a CSV of the run is a servo-arm lesson's (save the run file)")
        rec, snap, kw = self._selected()
        return kw["about"], snapshot_csv(snap, rec.joint_names, kw["params"])

    def _selected(self) -> tuple[Recording, dict[str, np.ndarray], dict[str, Any]]:
        """What :meth:`current_run` saves: the recording, its rows, and the rest of
        :meth:`_make_run`'s arguments (``about`` is the file's ``extra.run``)."""
        run = self._run
        if run is None or (run.track is None and self._arm is not None):
            return self._live_selected()
        if run.track is not None and self._arm is not None:
            model, loop = self._arm()
            rec = arm_recording(model, loop, whole=False)
            snap = {k: np.asarray(v) for k, v in run.track.snapshot().items()}
        elif run.track is not None:  # a loop of its own: the lesson lays its rows out
            rec = self._record(rows=run.track.snapshot())
            snap = {k: np.asarray(v) for k, v in rec.snapshot.items()}
        else:
            rec = self._record()
            snap = {k: np.asarray(v) for k, v in rec.snapshot.items()}
            keep = np.asarray(snap["t"]) >= run.t0 - LEAD_S
            if np.count_nonzero(keep) >= 2:
                snap = {k: v[keep] for k, v in snap.items()}
        t = snap["t"]
        if len(t) == 0 or not np.isfinite(snap["q"]).all(axis=1).any():
            raise ValueError("nothing recorded of the last run yet")
        t_end = float(t[-1])
        track = run.track
        # a command posted since the newest row is the run's (its effect yet to come),
        # until the run's rows are all in
        last = t_end if track is None or track.closed else math.inf
        commands = [c for c in self.commands if run.t0 - 1e-9 <= c["t"] <= last]
        finished = run.finished_at is not None
        state = FINISHED if finished else UNFINISHED
        about: dict[str, Any] = {
            "label": run.label, "state": state, "t0_s": run.t0, "t_end_s": t_end,
            "lead_s": LEAD_S}
        if finished:
            about["finished_at_s"] = run.finished_at
            about["tail_s"] = TAIL_S
        if track is not None and track.cut:
            about["cut"] = (f"cut at the bound of {track.max_s:g} s or {track.max_rows} "
                            "samples")
        if track is not None and track.lost:
            about["lost_samples"] = track.lost
        figures = dict(run.figures or {}) if finished else {}
        return rec, snap, {"commands": commands, "figures": figures, "params": run.params,
                           "about": about, "law": run.law,
                           "gains": self._gains.between(run.t0, t_end), "extra": run.extra}

    def _live_selected(self) -> tuple[Recording, dict[str, np.ndarray], dict[str, Any]]:
        """The record's window now, labelled as the live window (no run yet)."""
        rec = self._record()
        snap = {k: np.asarray(v) for k, v in rec.snapshot.items()}
        t = snap["t"]
        if len(t) == 0 or not np.isfinite(snap["q"]).all(axis=1).any():
            raise ValueError("nothing recorded yet")
        commands = commands_in_record(self.commands, t)
        start = self._start()
        if start is not None:
            keep = t >= start - LEAD_S
            if np.count_nonzero(keep) >= 2:
                snap = {k: v[keep] for k, v in snap.items()}
            commands = [c for c in commands if c["t"] >= start - LEAD_S]
        t = snap["t"]
        figures = dict(self._figures()) if self._live_figures else {}
        about = {"label": LIVE, "state": LIVE, "t0_s": float(t[0]), "t_end_s": float(t[-1])}
        params = dict(rec.params)
        return rec, snap, {"commands": commands, "figures": figures, "params": params,
                           "about": about,
                           "law": law_json(getattr(self._ctx, "law", None), params),
                           "gains": self._gains.between(float(t[0]), float(t[-1]))}

    def _make_run(self, rec: Recording, snap: Mapping[str, np.ndarray], *,
                  commands: list[dict[str, Any]], figures: Mapping[str, Any],
                  params: Mapping[str, Any], about: dict[str, Any], law: dict[str, Any],
                  by: int | None, gains: list[dict[str, Any]],
                  extra: Mapping[str, object] | None = None) -> Run:
        """The :class:`Run` of ``snap`` with what every file says (who, law, backend);
        ``extra``: the lesson's extra as it was when the run began (default: now)."""
        ctx = self._ctx
        who = getattr(ctx, "who", None)
        name = who(by) if who is not None and by is not None else ""
        extra = {**rec.extra, **(self._extra() if extra is None else extra)}
        extra.update({
            "run": about, "law": law, "gain_changes": gains,
            "backend": backend_json(str(getattr(ctx, "backend", "sim")),
                                    port=getattr(ctx, "port", None), backend=self._backend()),
        })
        if name:
            extra["student"] = name
        return run_from_snapshot(
            snap, robot=rec.robot, joint_names=rec.joint_names, source=f"page:{self.lesson}",
            params=dict(params), commands=commands, figures=dict(figures),
            extra=extra, lesson_signals=rec.lesson_signals)

    def file_name(self, run: Run, suffix: str) -> str:
        """``<robot>-<lesson>-<UTC time><suffix>``."""
        return f"{run.robot}-{self.lesson}-{file_stamp()}{suffix}"

    def save_file(self, *, by: int | None = None) -> tuple[str, bytes]:
        """(name, bytes) of the current run's file, saved by page ``by`` (ValueError:
        nothing recorded yet)."""
        run = self.current_run(by=by)
        return self.file_name(run, SUFFIX), run_bytes(run)

    def export_file(self, *, by: int | None = None) -> tuple[str, bytes]:
        """(name, bytes) of the current run's self-contained HTML page."""
        run = self.current_run(by=by)
        return self.file_name(run, ".html"), export_html(run, model=self._model()).encode()

    # ------------------------------------------------------------------ opening

    def open_bytes(self, name: str, content: bytes) -> Run:
        """Check the run file ``content`` (called ``name``) and replay it (read_run refuses
        one over :data:`armlab.control.runs.MAX_FILE_BYTES` unopened).

        Raises:
            RunFileError: the file is refused (the message says why).
        """
        model = self._model()
        run = read_run(bytes(content), robot=ghost_robot(model), name=name or "the run file")
        try:
            self.replay.show(run, model, title=name or "run file")
        except ValueError as exc:
            raise RunFileError(f"{name}: {exc}") from exc
        return run

    def _on_upload(self, event: viser.GuiEvent) -> None:
        # viser runs upload callbacks on a pool of threads and gives them the button, not
        # the file: each reads the newest file, so two uploads in quick succession call
        # back twice with the second file. It is opened once (the newest is what the
        # person chose last); the call that finds it already taken returns.
        with self._upload_lock:
            file = self.open.value
            if file is self._last_upload:
                return
            self._last_upload = file
        name = clip(str(getattr(file, "name", "")), 80)
        try:
            self.open_bytes(name, file.content)
        except ValueError as exc:  # RunFileError, or the arm being rebuilt
            notify(event.client, REFUSED, clip(str(exc), MAX_REASON_CHARS))
        except Exception as exc:  # noqa: BLE001 - never a silent failure: the page is told
            log.exception("opening the uploaded run file %s failed", name)
            notify(event.client, REFUSED,
                   f"{name or 'the run file'} could not be opened ({type(exc).__name__}: "
                   f"{clip(str(exc), 120)}); the lab goes on")

    def _refused(self, client_id: Any, name: str, why: str) -> None:
        """An upload refused before it was kept (too large): tell that page."""
        notify(self.server.get_clients().get(client_id), REFUSED, f"{name}: {why}")

    def page_only_buttons(self) -> tuple[viser.GuiButtonHandle, ...]:
        """Save run and Export page: they change nothing shared and answer the page that
        pressed (Open run replays on every page: not one of them)."""
        return (self.save, self.export)

    def remove(self) -> None:
        """Stop a replay and take its ghost away (the buttons go with the lesson's GUI)."""
        self.replay.remove()
