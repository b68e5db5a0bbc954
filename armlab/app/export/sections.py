"""The parts of the exported page a teacher reads (:mod:`armlab.app.export.html`): its
title, the measured figures with the live page's labels and units, the gains, the
commands summarised (their raw form folded away), which law ran and who ran it.

Everything from the run is escaped here; each part is bounded (a hostile run file's
commands, figures or texts cost at most a few hundred rows and 50 k characters)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from html import escape
from itertools import islice
from typing import TYPE_CHECKING, Any, TypeGuard

from armlab.control.laws import LAWS
from armlab.control.params import PARAM_SPECS

if TYPE_CHECKING:
    from armlab.control.runs import Run

#: Most commands listed (the first ones; the rest are counted), most figures and
#: parameters listed, most characters of any folded raw text (commands, a law's file).
MAX_COMMANDS = 200
MAX_TABLE_ROWS = 500
MAX_RAW_CHARS = 50_000
#: Most characters of one command's summary or one field shown.
MAX_SUMMARY_CHARS = 120

#: What the live page calls each figure a lesson measures, and its unit: key -> (label,
#: unit, format). The compliance lesson's step line ("Tp, %OS, Ts"), its Teach tab
#: (chapter 4's metric, C_f) and the hand's and the quadruped's panels.
FIGURE_LABELS: dict[str, tuple[str, str, str]] = {
    "overshoot_pct": ("%OS, overshoot", "%", ".3g"),
    "peak_time_s": ("Tp, peak time", "s", ".3g"),
    "settling_s": ("Ts, settling time", "s", ".3g"),
    "rise_time_s": ("Tr, rise time", "s", ".3g"),
    "step_joint": ("stepped joint", "", ""),
    "max_error_deg": ("max |θ_cmd − θ|, free line (chapter 4)", "°", ".3g"),
    "pushed_error_deg": ("max |θ_cmd − θ|, pushed line (chapter 4)", "°", ".3g"),
    "yield_deg": ("yield under the push, pushed − free", "°", ".3g"),
    "line_push_n": ("push during the line", "N", ".3g"),
    "push_n": ("push force", "N", ".3g"),
    "static_gain_rad_per_nm": ("C_f, compliance", "rad/N·m", ".3g"),
    "stiffness_nm_per_rad": ("1/C_f, stiffness", "N·m/rad", ".3g"),
    "grasp_force_n": ("grasp force, steady", "N", ".3g"),
    "grasp_peak_n": ("grasp force, peak", "N", ".3g"),
    "grasp_held": ("every finger held", "", ""),
    "eq41_error_pct": ("eq. 4.1 error over the walk", "%", ".3g"),
}
#: The gains that are not numbers, as the live page's Gains tab shows them.
SWITCH_LABELS = {"compliance": "Compliance", "feedforward": "Feed-forward θ̈_cmd"}
LAW_NAMES = {key: f"eq. {law.label}" for key, law in LAWS.items()}
#: How a figure's key names its unit, for figures the table above does not know.
FIGURE_UNITS = {"_pct": "%", "_deg": "°", "_s": "s", "_nm": "N·m", "_n": "N", "_mm": "mm",
                "_cm": "cm", "_m": "m", "_rad": "rad", "_hz": "Hz"}


def clip(text: str, most: int = MAX_SUMMARY_CHARS) -> str:
    """``text`` cut to ``most`` characters (an ellipsis says so)."""
    return text if len(text) <= most else text[: most - 1] + "…"


def number(value: float, fmt: str = ".4g") -> str:
    """A number as the page writes it."""
    return format(value, fmt) if math.isfinite(value) else str(value)


def joint_label(name: str) -> str:
    """What the live page calls a joint: "theta2" -> "θ2"."""
    return name.replace("theta", "θ")


def run_about(run: Run) -> Mapping[str, Any]:
    """The run's ``extra.run`` (label, state, times), or {} for a file without it."""
    about = run.extra.get("run")
    return about if isinstance(about, Mapping) else {}


def lesson_of(run: Run) -> str:
    """The lesson or experiment that made the run: "page:compliance" -> "compliance
    lesson", "experiment:thesis-line" -> "experiment thesis-line"."""
    kind, _, name = run.source.partition(":")
    if kind == "page" and name:
        return f"{name} lesson"
    return f"{kind} {name}".strip() if name else run.source


def run_label(run: Run) -> str:
    """The run's label ("step θ2", "thesis line", "live window"), with "unfinished" when
    it was saved while it went on; a file of an older lab: the lesson's own label, or
    "run"."""
    about = run_about(run)
    label = about.get("label") if isinstance(about.get("label"), str) else run.extra.get("run")
    text = label if isinstance(label, str) and label else "run"
    if about.get("state") == "unfinished":
        text += " (unfinished)"
    return clip(text, 80)


def student_of(run: Run) -> str:
    """Who saved the run (the page's name in a class), "" when the file does not say."""
    who = run.extra.get("student")
    return clip(who, 80) if isinstance(who, str) else ""


def utc_time(run: Run) -> str:
    """The run's creation time as "2026-12-01 22:03 UTC" (the file's text otherwise)."""
    text = run.created
    if len(text) >= 16 and text[10] == "T" and text.endswith("Z"):
        return f"{text[:10]} {text[11:16]} UTC"
    return clip(text, 40)


def title(run: Run) -> str:
    """The page's title: robot · lesson · run · student · UTC time."""
    parts = [run.robot, lesson_of(run), run_label(run), student_of(run), utc_time(run)]
    return " · ".join(clip(p, 200) for p in parts if p)


def figure_label(key: str) -> tuple[str, str, str]:
    """(label, unit, format) of a figure key; an unknown key from its name:
    "max_yield_deg.theta1" (one per joint) -> ("max yield (θ1)", "°", ".4g")."""
    base, _, which = key.partition(".")
    if base in FIGURE_LABELS:
        label, unit, fmt = FIGURE_LABELS[base]
    else:
        unit, fmt = "", ".4g"
        for suffix, named in FIGURE_UNITS.items():
            if base.endswith(suffix) and len(base) > len(suffix):
                base, unit = base[: -len(suffix)], named
                break
        label = base.replace("_", " ")
    return (f"{label} ({joint_label(which)})" if which else label), unit, fmt


def measured_figures(run: Run) -> list[tuple[str, str, str]]:
    """(key, label, value shown) of every figure measured (a null is not listed), the
    first :data:`MAX_TABLE_ROWS`."""
    out = []
    for key, value in run.figures.items():
        if not _measured(value):
            continue
        label, unit, fmt = figure_label(str(key))
        v = float(value)
        if key == "step_joint" and v.is_integer() and 0 <= v < len(run.joint_names):
            shown = joint_label(run.joint_names[int(v)])
        elif key == "grasp_held":
            shown = "yes" if v == 1.0 else "no"
        else:
            shown = f"{number(v, fmt or '.4g')} {unit}".strip()
        out.append((str(key), label, shown))
        if len(out) >= MAX_TABLE_ROWS:
            break
    return out


def _measured(value: object) -> TypeGuard[float]:
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(float(value)))


def figures_table(run: Run) -> str:
    """The measured figures as a table (a note when none was measured)."""
    rows = measured_figures(run)
    if not rows:
        why = (" (it was saved while it went on)" if run_about(run).get("state")
               == "unfinished" else "")
        return f'<p class="note">No figures were measured in this run{why}.</p>'
    body = "".join(f'<tr><th title="{escape(k)}">{escape(label)}</th>'
                   f'<td class="num" data-figure="{escape(k)}">{escape(shown)}</td></tr>'
                   for k, label, shown in rows)
    more = sum(1 for v in run.figures.values() if _measured(v)) - len(rows)
    note = f'<p class="note">… and {more} more (in the run file).</p>' if more > 0 else ""
    return f'<table id="figures">{body}</table>{note}'


def params_table(params: Mapping[str, object]) -> str:
    """The gains and parameters with the live page's labels and units."""
    if not params:
        return '<p class="note">No parameters were recorded.</p>'
    body = []
    for key, value in islice(params.items(), MAX_TABLE_ROWS):
        key = str(key)
        spec = PARAM_SPECS.get(key)
        hint = f' title="{escape(spec.help)}"' if spec else ""
        if spec is not None and isinstance(value, int | float) and not isinstance(value, bool):
            name, shown = spec.label, f"{number(float(value))} {spec.unit}".strip()
        elif key in SWITCH_LABELS and isinstance(value, bool):
            name, shown = SWITCH_LABELS[key], "on" if value else "off"
        elif key == "law":
            name, shown = "Law", LAW_NAMES.get(str(value), clip(str(value)))
        else:
            name, shown = clip(key.replace("_", " "), 60), clip(str(value))
        body.append(f"<tr><th{hint}>{escape(name)}</th>"
                    f'<td class="num">{escape(shown)}</td></tr>')
    more = len(params) - MAX_TABLE_ROWS
    note = f'<p class="note">… and {more} more (in the run file).</p>' if more > 0 else ""
    return f'<table id="params">{"".join(body)}</table>{note}'


def _vector(value: object, scale: float, unit: str, names: tuple[str, ...] = ()) -> str:
    if not isinstance(value, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value[:16]):
        return ""
    parts = [number(float(v) * scale, ".3g") for v in value[:16]]
    if names and len(names) == len(parts):
        return ", ".join(f"{joint_label(n)} {p}{unit}" for n, p in zip(names, parts,
                                                                       strict=True))
    return "(" + ", ".join(parts) + f") {unit}".rstrip()


def command_target(command: Mapping[str, Any], joints: tuple[str, ...]) -> str:
    """What a command aims at, in the live page's units: a trajectory's name, length and
    final angles (°), a target (cm), a push's force (N) and length, a spring's anchor."""
    kind = command.get("kind")
    if kind == "RunTrajectory" and isinstance(command.get("trajectory"), Mapping):
        traj = command["trajectory"]
        q, times = traj.get("q"), traj.get("times")
        name = str(traj.get("name") or "trajectory")
        length = ""
        if isinstance(times, list) and times and isinstance(times[-1], int | float):
            length = f", {number(float(times[-1]), '.3g')} s"
        goal = _vector(q[-1], 180.0 / math.pi, "°", joints) if isinstance(q, list) and q \
            else ""
        return clip(f"{name}{length}" + (f" to {goal}" if goal else ""))
    if kind == "SetTarget":
        xyz = _vector(command.get("xyz"), 100.0, "cm")
        return f"hand to {xyz}" if xyz else "target cleared"
    if kind == "Push":
        force = command.get("force")
        size = (math.hypot(*(float(v) for v in force[:3]))  # (never overflows: inf)
                if isinstance(force, list) and len(force) >= 3 and all(
                    isinstance(v, int | float) for v in force[:3]) else None)
        dur = command.get("duration")
        text = f"{number(size, '.3g')} N" if size is not None else "push"
        if isinstance(dur, int | float) and not isinstance(dur, bool):
            text += f" for {number(float(dur), '.3g')} s"
        return text
    if kind == "Spring":
        anchor = _vector(command.get("anchor"), 100.0, "cm")
        k = command.get("stiffness")
        stiff = f", {number(float(k), '.3g')} N/m" if isinstance(k, int | float) else ""
        return f"hand pulled to {anchor}{stiff}" if anchor else "spring let go"
    fields = [f"{k} {clip(json.dumps(v, ensure_ascii=False), 30)}" for k, v in
              islice(command.items(), 8) if k not in ("t", "kind")]
    return clip(", ".join(fields))


def commands_section(run: Run) -> str:
    """The commands summarised (time from the run's start, kind, target), the first
    :data:`MAX_COMMANDS`; their raw JSON folded away in a ``<details>``."""
    commands = run.commands
    if not commands:
        return '<p class="note">No commands were recorded.</p>'
    t0 = float(run.t[0]) if len(run.t) else 0.0
    body = []
    for cmd in commands[:MAX_COMMANDS]:
        t = cmd.get("t")
        when = (f"{float(t) - t0:.2f} s" if isinstance(t, int | float)
                and not isinstance(t, bool) else "")
        body.append(f'<tr><td class="num">{escape(when)}</td>'
                    f'<td>{escape(clip(str(cmd.get("kind", "")), 40))}</td>'
                    f"<td>{escape(command_target(cmd, run.joint_names))}</td></tr>")
    more = len(commands) - MAX_COMMANDS
    note = f'<p class="note">… and {more} more (in the run file).</p>' if more > 0 else ""
    raw = raw_json(list(commands[:MAX_COMMANDS]))
    return ('<table id="commands"><tr><th>time</th><th>kind</th><th>target</th></tr>'
            f'{"".join(body)}</table>{note}'
            f'<details><summary>The commands as recorded (JSON)</summary>'
            f'<pre id="commands-raw">{escape(raw)}</pre></details>')


def raw_json(value: object, most: int = MAX_RAW_CHARS) -> str:
    """``value`` as indented JSON, cut after ``most`` characters: written piece by piece
    and stopped there, so a huge value costs no whole text of it."""
    encoder = json.JSONEncoder(indent=1, ensure_ascii=False, default=str)
    parts: list[str] = []
    length = 0
    for chunk in encoder.iterencode(value):
        parts.append(chunk)
        length += len(chunk)
        if length > most:
            return "".join(parts)[:most] + "\n… (cut: the whole of it is in the run file)"
    return "".join(parts)


def law_section(run: Run) -> str:
    """Which law ran: the lab's (which equation), or the student's file (its name,
    SHA-256, exercise; its text folded away)."""
    law = run.extra.get("law")
    if not isinstance(law, Mapping):
        name = LAW_NAMES.get(str(run.params.get("law")), "")
        return ('<p id="law">The file does not say whose law ran'
                + (f"; the lab's gains name {escape(name)}" if name else "") + ".</p>")
    if law.get("by") != "student":
        name = LAW_NAMES.get(str(law.get("law")), clip(str(law.get("law", ""))))
        return f'<p id="law">The lab\'s own law{": " + escape(name) if name else ""}.</p>'
    rows = [("file", clip(str(law.get("file", "")), 200)),
            ("SHA-256", clip(str(law.get("sha256", "not read")), 80))]
    if isinstance(law.get("exercise"), str):
        rows.append(("exercise", clip(law["exercise"], 80)))
    if isinstance(law.get("error"), str):
        rows.append(("note", clip(law["error"], 200)))
    table = "".join(f"<tr><th>{escape(k)}</th><td>{escape(v)}</td></tr>" for k, v in rows)
    source = law.get("source")
    folded = ""
    if isinstance(source, str):
        text = source if len(source) <= MAX_RAW_CHARS else source[:MAX_RAW_CHARS] + "\n…"
        folded = (f'<details><summary>The student\'s file</summary>'
                  f'<pre id="law-source">{escape(text)}</pre></details>')
    return (f'<p id="law">The student\'s own law ran (<code>armlab serve --exercise</code>).'
            f'</p><table id="law-file">{table}</table>{folded}')


def backend_text(run: Run) -> str:
    """The backend the run ran on, as one line ("" when the file does not say)."""
    b = run.extra.get("backend")
    if isinstance(b, str):
        return clip("simulated arm" if b == "sim" else b)
    if not isinstance(b, Mapping):
        return ""
    kind = b.get("kind")
    servos = b.get("servos")
    text = "simulated arm" if kind == "simulated" else f"{clip(str(kind), 20)} servos"
    if isinstance(servos, str) and servos:
        text += f" ({clip(servos, 40)}{' model' if kind == 'simulated' else ''})"
    if isinstance(b.get("port"), str):
        text += f" on {clip(b['port'], 60)}"
    return text


def gain_changes_text(run: Run) -> str:
    """Every gain change during the run, one per line ("" with none)."""
    changes = run.extra.get("gain_changes")
    if not isinstance(changes, list) or not changes:
        return ""
    t0 = float(run.t[0]) if len(run.t) else 0.0
    lines = []
    for c in changes[:MAX_COMMANDS]:
        if not isinstance(c, Mapping) or not isinstance(c.get("t"), int | float):
            continue
        what = ", ".join(f"{PARAM_SPECS[k].label if k in PARAM_SPECS else k} "
                         f"{clip(str(v), 20)}" for k, v in islice(c.items(), 12) if k != "t")
        lines.append(f"{float(c['t']) - t0:.2f} s: {clip(what)}")
    return "; ".join(lines)
