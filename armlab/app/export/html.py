"""One run as one self-contained HTML page to hand in (``armlab export RUN --html OUT``,
the page's "Export page" button).

The page shows the arm moving through the run in 3D (orbit with a drag, zoom with the
wheel or two fingers, a time slider, play/pause), a chart per joint of the commanded
and the measured angle and one of the torques recorded (at least the live page's spans:
4° and 0.5 N·m, so a servo's one-step jitter at rest looks as small as it is), the
figures measured (with the live page's labels and units), gains and parameters as
text, the commands summarised (their raw JSON folded away), which law ran, and the
robot, lesson, run, student, backend, date and lab version; its title says robot,
lesson, run, student and UTC time (:mod:`armlab.app.export.sections`). It opens from a disk or
a course site, offline, in any current browser, and asks no server for anything.

Technique: the arm is drawn by a small hand-written script on a 2D ``<canvas>``
(:mod:`armlab.app.export.viewer`): the lab's own forward kinematics
(:meth:`armlab.kinematics.SerialChain.link_poses`) is computed here, in Python, for at
most :data:`MAX_FRAMES` evenly spaced samples, and the page gets the world position of
every joint frame, projects it in perspective and draws links as thick lines and joints
as discs. The charts are inline SVG made here (:mod:`armlab.app.export.charts`). Not
viser's scene serialiser and static client: that page fetches its recording file with a
request (which a browser refuses on ``file://``) and is megabytes of three.js; this
page is a few hundred kB, needs no WebGL (it draws on any machine, software rendering
included) and has no library, CDN or web font to fetch. The URDF's meshes are not drawn
(they would be megabytes): links are drawn as capsules between the joint frames.

Everything from the run (names, source, parameters, commands, ``extra``) is escaped, the
data block is JSON with ``<``, ``>`` and ``&`` escaped, and the page's Content Security
Policy allows its own script alone (by hash) and no request of any kind, so a hostile
run file can show text but run nothing and fetch nothing.
"""

from __future__ import annotations

import base64
import hashlib
import importlib.metadata
import json
import math
from html import escape
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from armlab.app.export import sections
from armlab.app.export.charts import Series, line_chart
from armlab.app.export.viewer import SCRIPT, STYLE
from armlab.app.page.plots import ANGLE_SPAN_DEG, COLORS, TORQUE_SPAN_NM
from armlab.control.runs import check_drawable, save_file, writable_path
from armlab.kinematics.catalog import RECEPTIONIST_PRESETS, ROBOT_FILES
from armlab.kinematics.catalog import load_robot as _load_robot
from armlab.kinematics.hand_statics import FingerGeometry, tip_positions
from armlab.kinematics.model import Joint, Quadruped, SerialChain
from armlab.kinematics.urdf_read import LEG_NAMES

if TYPE_CHECKING:
    from armlab.control.runs import Run

#: Most 3D frames embedded (evenly spaced over the run).
MAX_FRAMES = 1500
#: Time buckets of a chart (each keeps its lowest and highest sample of every line).
CHART_BUCKETS = 600
#: Most commands listed (the first ones; the rest are counted).
MAX_COMMANDS = sections.MAX_COMMANDS
#: Most figures and most parameters listed (the first ones; the rest are counted).
MAX_TABLE_ROWS = sections.MAX_TABLE_ROWS
#: Most characters of the run's ``extra`` shown.
MAX_EXTRA_CHARS = 50_000
#: m per stored position unit in the page's data (0.1 mm).
POSITION_SCALE = 1e-4

#: Chart lines (signal, legend, colour, dash): command and measured, in the lab's chart
#: colours for a command and an actual value, and the torques.
ANGLE_SERIES = (("q_cmd", "commanded", COLORS[0], "6 3"), ("q", "measured", COLORS[2], ""))
TORQUE_SERIES = (("load", "τ_dist (servo load)", COLORS[3], ""),
                 ("tau_dyn", "τ_dyn", COLORS[4], "6 3"),
                 ("tau_ext", "τ_ext", COLORS[5], "2 2"))

#: What a page draws: an arm, a quadruped, or the hand lesson's three fingers (run robot
#: "hand", joints finger1..3: each drawn from its hinge to its fingertip, the palm through
#: the hinges).
Drawn = SerialChain | Quadruped | FingerGeometry
HAND_ROBOT = "hand"

#: How a figure's key names its unit (suffix -> unit shown).
FIGURE_UNITS = sections.FIGURE_UNITS


def model_for(run: Run) -> Drawn:
    """The shipped robot model a run names (``run.robot``); the receptionist arm with the
    link lengths its run kept (``extra["link_lengths_cm"]``, a key of
    ``RECEPTIONIST_PRESETS``, as the compliance lesson saves it).

    Raises:
        ValueError: the run names no shipped robot (a run of a URDF of one's own needs
            that model: ``export_html(run, model=...)``, ``armlab export --robot URDF``).
    """
    if run.robot == HAND_ROBOT:
        return FingerGeometry()
    if run.robot not in ROBOT_FILES:
        raise ValueError(f"the run's robot {run.robot!r} is not one the lab ships "
                         f"({', '.join(ROBOT_FILES)}); give its URDF with --robot")
    lengths = run.extra.get("link_lengths_cm")
    if run.robot == "receptionist_arm" and isinstance(lengths, str) \
            and lengths in RECEPTIONIST_PRESETS:
        return _load_robot(run.robot, preset=lengths)
    return _load_robot(run.robot)


def _joints(model: Drawn) -> list[Joint]:
    if isinstance(model, FingerGeometry):
        return [Joint(name=f"finger{i + 1}", kind="revolute", origin=np.eye(4),
                      axis=np.array([0.0, 1.0, 0.0]), lower=model.open_angle,
                      upper=model.closed_angle, velocity=0.0, effort=0.0)
                for i in range(len(model.azimuths))]
    if isinstance(model, Quadruped):
        return [j for leg in LEG_NAMES for j in model.legs[leg].joints]
    return list(model.joints)


def _check_model(run: Run, model: Drawn) -> None:
    n = len(_joints(model))
    width = run.signals["q"].shape[1]
    if n != width:
        name = getattr(model, "name", run.robot)
        raise ValueError(f"the run has {width} joints, the robot {name!r} has {n}")


def _chain_points(chain: SerialChain, q: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """(world positions of the chain's base, each joint frame and its tip; the tip's
    rotation (3, 3)) at ``q``: the lab's forward kinematics (``link_poses``)."""
    poses = chain.base_pose @ chain.link_poses(q)
    tip = poses[-1] @ chain.tip
    return [chain.base_pose[:3, 3], *poses[:, :3, 3], tip[:3, 3]], tip[:3, :3]


def _pose_points(model: Drawn, q: np.ndarray) -> tuple[list[np.ndarray],
                                                                         np.ndarray | None]:
    """(every chain's points in order, the arm's tip rotation (3, 3), None for a
    quadruped: its legs hang from the body's hips; the hand: each finger from hinge to
    fingertip) at ``q``."""
    if isinstance(model, FingerGeometry):
        tips = tip_positions(model, q)
        return [p for hinge, tip in zip(_hinges(model), tips, strict=True)
                for p in (hinge, tip)], None
    if isinstance(model, Quadruped):
        points, start = [], 0
        for leg in LEG_NAMES:
            chain = model.legs[leg]
            points += _chain_points(chain, q[start:start + chain.n])[0]
            start += chain.n
        return points, None
    return _chain_points(model, q)


def _hinges(finger: FingerGeometry) -> list[np.ndarray]:
    """The hand's finger hinges on the palm, m."""
    r = finger.hinge_radius
    return [np.array([r * math.cos(az), r * math.sin(az), 0.0]) for az in finger.azimuths]


def _chain_counts(model: Drawn) -> list[int]:
    if isinstance(model, FingerGeometry):
        return [2] * len(model.azimuths)
    if isinstance(model, Quadruped):
        return [model.legs[leg].n + 2 for leg in LEG_NAMES]
    return [model.n + 2]


def _statics(model: Drawn) -> list[list[float]]:
    """Closed outlines drawn in every frame (a quadruped's body through its hips, the hand's
    palm through its hinges), m."""
    if isinstance(model, FingerGeometry):
        return [[round(float(v), 5) for p in _hinges(model) for v in p]]
    if not isinstance(model, Quadruped):
        return []
    order = ("RF", "LF", "LH", "RH")  # round the body
    return [[round(float(v), 5) for leg in order for v in model.legs[leg].base_pose[:3, 3]]]


def frame_indices(m: int, *, most: int = MAX_FRAMES) -> np.ndarray:
    """At most ``most`` evenly spaced row indices of m rows, the first and last included."""
    return np.unique(np.linspace(0, m - 1, min(m, most)).round().astype(int))


def _display_scale(joint: Joint) -> tuple[float, str]:
    """(factor from SI, unit) of a joint's value in the UI: degrees, or cm if prismatic."""
    return (100.0, "cm") if joint.kind == "prismatic" else (180.0 / math.pi, "°")


def viewer_data(run: Run, model: Drawn) -> dict[str, object]:
    """The page's JSON data: frame times, poses (positions in :data:`POSITION_SCALE` m),
    the commanded ghost poses, the tip frame's axes (×100) and the joints in UI units."""
    t = np.asarray(run.t, dtype=float)
    idx = frame_indices(t.size)
    q = np.asarray(run.signals["q"], dtype=float)
    q_cmd = run.signals.get("q_cmd")
    joints = _joints(model)
    factors = np.array([_display_scale(j)[0] for j in joints])

    def pose(row: np.ndarray) -> tuple[list[int] | None, list[int] | None]:
        if not np.all(np.isfinite(row)):
            return None, None
        points, rot = _pose_points(model, row)
        flat = np.rint(np.concatenate(points) / POSITION_SCALE).astype(int).tolist()
        return flat, (None if rot is None else np.rint(rot * 100).astype(int).ravel().tolist())

    frames, triads, ghosts, shown = [], [], [], []
    for i in idx:
        flat, rot = pose(q[i])
        frames.append(flat)
        triads.append(rot)
        shown.append(None if flat is None else [round(float(v), 1) for v in q[i] * factors])
        ghosts.append(pose(np.asarray(q_cmd[i], dtype=float))[0] if q_cmd is not None else None)
    return {
        "scale": POSITION_SCALE,
        "t": [round(float(v), 6) for v in t[idx]],
        "chains": _chain_counts(model),
        "frames": frames,
        "ghost": ghosts if any(g is not None for g in ghosts) else None,
        "triad": triads if any(r is not None for r in triads) else None,
        "statics": _statics(model),
        "q_display": shown,
    }


def _json_for_html(value: object) -> str:
    """JSON text safe inside a ``<script type="application/json">`` element."""
    text = json.dumps(value, separators=(",", ":"), allow_nan=False)
    return (text.replace("&", "\\u0026").replace("<", "\\u003c").replace(">", "\\u003e")
            .replace("\u2028", "\\u2028").replace("\u2029", "\\u2029"))


def _rows(rows: list[tuple[str, str]]) -> str:
    return "".join(f"<tr><th>{escape(k)}</th><td>{escape(v)}</td></tr>" for k, v in rows)


def _charts(run: Run, joints: list[Joint]) -> str:
    t = np.asarray(run.t, dtype=float)
    out = []
    for j, (name, joint) in enumerate(zip(run.joint_names, joints, strict=True)):
        factor, unit = _display_scale(joint)
        angle = [Series(label, color, np.asarray(run.signals[key], dtype=float)[:, j] * factor,
                        dash) for key, label, color, dash in ANGLE_SERIES if key in run.signals]
        kind = "position" if joint.kind == "prismatic" else "angle"
        span = 1.0 if joint.kind == "prismatic" else ANGLE_SPAN_DEG  # cm, or the live page's °
        shown = sections.clip(sections.joint_label(name), 80)
        out.append(line_chart(t, angle, title=f"{shown}: {kind}", y_label=f"{kind} ({unit})",
                              min_span=span, buckets=CHART_BUCKETS))
        torque = []
        for key, label, color, dash in TORQUE_SERIES:
            if key in run.signals:
                values = np.asarray(run.signals[key], dtype=float)[:, j]
                if np.isfinite(values).any():
                    torque.append(Series(label, color, values, dash))
        if torque:
            out.append(line_chart(t, torque, title=f"{shown}: torque",
                                  y_label="torque (N·m)", min_span=TORQUE_SPAN_NM,
                                  buckets=CHART_BUCKETS))
    for signal in run.lesson_signals:  # one chart each, a line per joint
        values = np.asarray(run.signals[signal], dtype=float)
        lines = [Series(joint, COLORS[k % len(COLORS)], values[:, k], "" if k == 0 else "6 3")
                 for k, joint in enumerate(run.joint_names) if np.isfinite(values[:, k]).any()]
        if lines:
            unit = run.lesson_signals[signal]
            out.append(line_chart(t, lines, title=signal, y_label=f"{signal} ({unit})",
                                  min_span=1e-3, buckets=CHART_BUCKETS))
    return "".join(out)


def _extra_text(extra: dict[str, object]) -> str:
    """``extra`` as indented JSON, cut after :data:`MAX_EXTRA_CHARS` characters (the law's
    source, shown apart, left out)."""
    law = extra.get("law")
    if isinstance(law, dict) and "source" in law:
        extra = {**extra, "law": {k: v for k, v in law.items() if k != "source"}}
    return sections.raw_json(extra, MAX_EXTRA_CHARS)


def _lab_version() -> str:
    try:
        return importlib.metadata.version("armlab")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def export_html(run: Run, *, model: Drawn | None = None) -> str:
    """The whole page for ``run`` as HTML text (see the module's docstring).

    Args:
        run: the run (:func:`armlab.control.runs.read_run`, or one just recorded).
        model: its robot; default the shipped robot ``run.robot`` names (a page passes
            the model it drives, which also covers a URDF of one's own).

    Raises:
        ValueError: no model for the run's robot, or its joints differ from the run's, or a
            value is beyond what can be drawn (:func:`armlab.control.runs.check_drawable`).
    """
    model = model_for(run) if model is None else model
    _check_model(run, model)
    check_drawable(run, "the run")
    joints = _joints(model)
    t = np.asarray(run.t, dtype=float)
    duration = float(t[-1] - t[0]) if t.size else 0.0
    period = duration / (t.size - 1) if t.size > 1 else math.nan
    about = sections.run_about(run)
    meta = [("Robot", run.robot), ("Lesson", sections.lesson_of(run)),
            ("Run", sections.run_label(run))]
    if sections.student_of(run):
        meta.append(("Student", sections.student_of(run)))
    if sections.backend_text(run):
        meta.append(("Backend", sections.backend_text(run)))
    if sections.gain_changes_text(run):
        meta.append(("Gain changes", sections.gain_changes_text(run)))
    if isinstance(about.get("cut"), str):
        meta.append(("Cut", sections.clip(about["cut"])))
    meta += [("Joints", ", ".join(run.joint_names)),
            ("Source", run.source), ("Recorded", sections.utc_time(run)),
            ("Duration", f"{duration:.3f} s, {t.size} samples"
             + (f" at {period * 1000:.3g} ms" if math.isfinite(period) else "")),
            ("Lab version", f"armlab {run.lab_version} (exported with armlab {_lab_version()})")]
    joint_rows = "".join(
        f"<tr><th>{escape(sections.joint_label(name))}</th><td class=\"num\" data-joint=\"{j}\" "
        f"data-unit=\"{escape(_display_scale(joint)[1])}\">–</td></tr>"
        for j, (name, joint) in enumerate(zip(run.joint_names, joints, strict=True)))
    ghost_note = ("The blue, see-through arm is the commanded pose; the solid one the "
                  "measured. " if "q_cmd" in run.signals else "")
    extra = ""
    if run.extra:
        text = _extra_text(run.extra)
        extra = ('<section><h2>More about the run</h2><details><summary>Everything else the '
                 f'run file says (JSON)</summary><pre id="extra">{escape(text)}</pre>'
                 "</details></section>")
    title = sections.title(run)
    script_hash = base64.b64encode(hashlib.sha256(SCRIPT.encode("utf-8")).digest()).decode()
    csp = (f"default-src 'none'; script-src 'sha256-{script_hash}'; "
           "style-src 'unsafe-inline'; base-uri 'none'; form-action 'none'")
    return f"""<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{csp}">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="armlab {escape(_lab_version())}">
<title>{escape(title)}</title>
<style>{STYLE}</style>
</head>
<body>
<main>
<h1>{escape(run.robot)}: {escape(sections.lesson_of(run))}, {escape(sections.run_label(run))}</h1>
<p class="sub">{escape(" · ".join(p for p in (sections.student_of(run), sections.utc_time(run),
                                               "armlab " + run.lab_version) if p))}</p>
<section>
<div class="viewer">
<div>
<canvas id="view" tabindex="0" aria-label="the arm in 3D: drag to orbit, wheel to zoom"></canvas>
<div class="controls">
<button id="play" type="button" aria-pressed="false">Play</button>
<input id="time" type="range" min="0" max="0" step="1" value="0" aria-label="time">
<span id="time-readout">t = {t[0]:.3f} s</span>
<label>speed <select id="speed"><option value="0.25">¼×</option><option value="0.5">½×</option>
<option value="1" selected>1×</option><option value="2">2×</option></select></label>
</div>
<p class="hint">{ghost_note}Drag to orbit, wheel or pinch to zoom, double-click to reset the view.
The grey line is the path of the tip.</p>
<noscript><p class="note">The 3D view needs JavaScript; the charts and figures below do
not.</p></noscript>
</div>
<table id="joints"><tr><th>joint</th><th>measured</th></tr>{joint_rows}</table>
</div>
</section>
<section><h2>Figures</h2>{sections.figures_table(run)}</section>
<section><h2>Law</h2>{sections.law_section(run)}</section>
<section><h2>Gains and parameters</h2>{sections.params_table(run.params)}</section>
<section><h2>Charts</h2><div class="charts">{_charts(run, joints)}</div></section>
<section><h2>Commands</h2>{sections.commands_section(run)}</section>
{extra}
<section><h2>About this run</h2><table id="meta">{_rows(meta)}</table>
<p class="note">Written by <code>armlab export</code>: one file, no network needed. The run file
holds every sample; this page shows up to {MAX_FRAMES} poses and thinned charts.</p></section>
</main>
<script type="application/json" id="run-data">{_json_for_html(viewer_data(run, model))}</script>
<script>{SCRIPT}</script>
</body>
</html>
"""


def write_html(run: Run, path: str | Path, *,
               model: Drawn | None = None) -> Path:
    """Write :func:`export_html` of ``run`` to ``path`` (UTF-8; a temporary file in the same
    folder renamed over it, so a reader never sees half a page); returns the path.

    Raises:
        ValueError: as :func:`export_html`.
        RunFileError: ``path`` is a folder, its folder is missing or cannot be written (one
            message saying which and what to do; nothing is left behind).
    """
    writable_path(path, what="write the page", example="run.html")  # before the work
    return save_file(path, export_html(run, model=model).encode("utf-8"),
                     what="write the page", example="run.html")
