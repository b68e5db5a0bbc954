"""The Files tab of a lesson: **Save run**, **Open run**, **Export page**.

- **Save run** sends the browser that pressed it the current run as a run file
  (:mod:`armlab.control.runs`), named ``<robot>-<lesson>-<UTC time>.armlab-run.zip``:
  the gains in force, the commands the lesson posted (with their loop times), every
  signal the recorder holds from the run's start (the loop rate), the lesson's figures
  (``run_figures()``), the robot, the lab's version.
- **Open run** takes a run file from the page (it arrives over the gated websocket;
  larger than :data:`armlab.control.runs.MAX_FILE_BYTES`, or past a page's or the lab's
  unfinished uploads, it is refused before it is kept, and a page's unfinished uploads
  go when it leaves: :mod:`armlab.app.viser_ext.uploads`), checks it with
  :func:`armlab.control.runs.read_run` for this lesson's robot, and plays it on a ghost
  arm (:class:`armlab.app.lessons.replay_view.ReplayView`). A bad file, and every
  upload that fails, gets one notification with the reason (at most 300 characters) on
  the page that sent it; the lab goes on.
- **Export page** sends the current run as one self-contained HTML page
  (:func:`armlab.app.export_html.export_html`).

A lesson posts its commands through :meth:`RunControls.post` (or tells
:meth:`RunControls.note` of one posted elsewhere), so that they go into the file.
The same code serves a student's private arm in a classroom: the lesson is built on
their page, its loop is the mirror of the worker's (whose recorder the worker's rows
are copied into), and the file goes to their browser.

A servo-arm lesson hands over its model and :class:`~armlab.control.loop.ControlLoop`
(``arm=``); a lesson with a loop of its own (the hand, the quadruped) hands over a
:class:`Recording` of it (``record=``): the robot, its record in the recorder's
layout, its parameters and the lesson's own signals (the hand's currents and forces,
:attr:`armlab.control.runs.Run.lesson_signals`).
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import viser

from armlab.app.export_html import export_html
from armlab.app.lessons import RunFigures
from armlab.app.lessons._common import send_download
from armlab.app.lessons.replay_view import GhostModel, ReplayView, ghost_robot
from armlab.app.page.inputs import notify
from armlab.app.page.surface import Surface
from armlab.app.viser_ext import HooksMissing
from armlab.app.viser_ext.uploads import limit_uploads
from armlab.control.loop import ControlLoop
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


def arm_recording(model: SerialChain, loop: ControlLoop) -> Recording:
    """A servo-arm lesson's :class:`Recording`: its loop's recorder and gains."""
    return Recording(model=model, robot=model.name, joint_names=model.joint_names,
                     snapshot=loop.recorder.snapshot(), params=loop.params.as_dict())


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
        record: () -> the lesson's :class:`Recording` now (instead of ``arm``).
        model: () -> what the lesson draws now (with ``record``: opening a run needs no
            record).
        figures: () -> the lesson's figures (``run_figures``).
        start: () -> loop time the current run started (None: from the first command the
            record still holds, or the whole record).
        extra: () -> free JSON for the file's ``extra`` (link lengths, backend, ...).
        ghost_root: scene node of the replay ghost.

    Attributes:
        replay: the replay (ghost, slider, chart).
    """

    def __init__(self, server: Surface, gui: viser.GuiApi, *, lesson: str,
                 arm: Callable[[], tuple[SerialChain, ControlLoop]] | None = None,
                 record: Callable[[], Recording] | None = None,
                 model: Callable[[], GhostModel] | None = None,
                 figures: Callable[[], RunFigures],
                 start: Callable[[], float | None] | None = None,
                 extra: Callable[[], Mapping[str, object]] | None = None,
                 ghost_root: str) -> None:
        if arm is not None:
            record, model = (lambda: arm_recording(*arm())), (lambda: arm()[0])
        if record is None or model is None:
            raise ValueError("RunControls needs arm=, or record= and model=")
        self.server = server
        self.lesson = lesson
        self._record = record
        self._model = model
        self._figures = figures
        self._start = start or (lambda: None)
        self._extra = extra or dict
        self._commands: deque[dict[str, Any]] = deque(maxlen=MAX_COMMANDS)
        self._commands_lock = threading.Lock()  # posted from callbacks, read by Save
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
        self.save.on_click(lambda e: send_download(e, self.save_file))
        self.export.on_click(lambda e: send_download(e, self.export_file))
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

    def post(self, loop: CommandedLoop, command: object) -> None:
        """Post ``command`` to ``loop`` and keep it for the file (at the loop's time)."""
        loop.post(command)
        self.note(command, t=loop.status.t)

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

    def current_run(self) -> Run:
        """The run now: from its start (or the oldest command the record holds) to the
        newest sample.

        Raises:
            ValueError: nothing recorded yet.
        """
        rec = self._record()
        snap = {k: np.asarray(v) for k, v in rec.snapshot.items()}
        t = snap["t"]
        if len(t) == 0 or not np.isfinite(snap["q"]).all(axis=1).any():
            raise ValueError("nothing recorded yet")
        commands = commands_in_record(self.commands, t)
        start = self._start()
        if start is None and commands:
            start = commands[0]["t"]
        if start is not None:
            keep = t >= start - LEAD_S
            if np.count_nonzero(keep) >= 2:
                snap = {k: v[keep] for k, v in snap.items()}
            commands = [c for c in commands if c["t"] >= start - LEAD_S]
        figures = dataclasses.asdict(self._figures())
        return run_from_snapshot(
            snap, robot=rec.robot, joint_names=rec.joint_names, source=f"page:{self.lesson}",
            params=dict(rec.params), commands=commands, figures=figures,
            extra={**rec.extra, **self._extra()}, lesson_signals=rec.lesson_signals)

    def file_name(self, run: Run, suffix: str) -> str:
        """``<robot>-<lesson>-<UTC time><suffix>``."""
        return f"{run.robot}-{self.lesson}-{file_stamp()}{suffix}"

    def save_file(self) -> tuple[str, bytes]:
        """(name, bytes) of the current run's file (ValueError: nothing recorded yet)."""
        run = self.current_run()
        return self.file_name(run, SUFFIX), run_bytes(run)

    def export_file(self) -> tuple[str, bytes]:
        """(name, bytes) of the current run's self-contained HTML page."""
        run = self.current_run()
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
