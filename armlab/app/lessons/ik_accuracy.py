"""Lesson: closed-form IK of a hobby-servo arm and where its accuracy goes (seed 004).

The planar three-link arm (6.5 / 10.5 / 6.5 cm) on graph paper. The student
drags a target in the arm's plane (or types it) and sees the paper's geometric
IK (:mod:`armlab.kinematics.planar_ik`): the elbow branch, the three 0–180° servo
ranges drawn on the joints (red when the solution leaves them), the whole-degree
servo command (none / round / truncate as the paper's software does) and the
target against the FK of what the servos are sent. "Run the paper's table"
recomputes Table 1 (``armlab experiment seed004-table``) beside the paper's
columns, with an error chart, the out-of-range rows explained with the lab's
in-range alternative, and a CSV download.

No control loop: every input is solved at once in the callback.
"""

from __future__ import annotations

import csv
import io
import math
from typing import Any

import numpy as np
import viser
import viser.uplot

from armlab.app.lessons import Lesson, LessonContext
from armlab.app.lessons._common import (
    INSET,
    LessonBase,
    esc,
    guarded,
    remove_quietly,
    send_download,
)
from armlab.app.page import theme
from armlab.app.page.arm_view import ArmView
from armlab.app.page.camera import View, show
from armlab.app.page.inputs import notify, tell_limit, typed_value
from armlab.app.page.plots import COLORS, SeriesSpec, add_chart, dash, fixed_x, uplot_series
from armlab.app.page.surface import Surface
from armlab.control.experiments.seed004 import EXPERIMENTS as SEED004_EXPERIMENTS
from armlab.control.experiments.seed004 import table
from armlab.control.experiments.seed004_data import TABLE1
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.planar_ik import (
    Alternative,
    PlanarArm,
    PlanarIKResult,
    in_range_alternative,
    solve,
)

NAME = "ik_accuracy"
TITLE = "IK accuracy"
HELP = ("The paper's planar arm with three 0–180° hobby servos: drag the target in its plane "
        "and see the closed-form IK, the elbow branch, the servo ranges on the joints (red when "
        "a solution leaves them) and the error that whole-degree servo commands make. Run the "
        "paper's Table 1 and compare its computed and measured columns with the lab's.")
#: The first action, shown under the status line.
TRY = ("Drag the target in the arm's plane, then press **Run the paper's table**.")
ROBOTS = ("planar_servo_arm",)
ORDER = 20
#: a student's page can hold a private copy (it simulates on its own; no servos, no ``ctx.arms``)
PRIVATE = True

ROUNDING_LABELS = {"none": "none (exact angles)", "round": "round to whole degrees",
                   "truncate": "truncate the servo command (the paper)"}
ELBOW_LABELS = {"down": "elbow down (the paper)", "up": "elbow up"}
TARGET_LIMIT_CM = 30.0  #: typed targets beyond ±30 cm are refused outright
ARC_RADII = (0.030, 0.024, 0.018)  #: m, radius of each joint's servo-range arc
ARC_Z = 0.012  #: m above the base plane
PAPER_M = 0.30  #: m, side of the square of graph paper under the arm
OK_RGB = (40, 170, 70)
BAD_RGB = (220, 30, 30)
GHOST_RGBA = (0.2, 0.8, 0.3, 0.35)
ARM_RGBA = (0.25, 0.35, 0.65, 1.0)  #: dark blue: contrast on the white graph paper
TABLE_COLUMNS = ("paper R", "paper |X1Y1 − target|", "lab |X1Y1 − target|")


def build(server: Surface, ctx: LessonContext) -> IKAccuracyLesson:
    """Open the lesson on ``server`` (see :mod:`armlab.app.lessons`)."""
    return IKAccuracyLesson(server, ctx)


def joint_ranges_deg(arm: PlanarArm) -> list[tuple[float, float]]:
    """Each joint's angle range (deg) that keeps its servo in travel: offset − servo."""
    return [(o - arm.servo_max_deg, o - arm.servo_min_deg) for o in arm.servo_offset_deg]


def servo_in_range(servo_deg: tuple[float, float, float], arm: PlanarArm) -> list[bool]:
    """Per joint: is the servo command (deg) within the servo's travel?"""
    return [arm.servo_min_deg - 1e-9 <= s <= arm.servo_max_deg + 1e-9 for s in servo_deg]


def joint_frames(angles: tuple[float, float, float], arm: PlanarArm
                 ) -> list[tuple[np.ndarray, float]]:
    """(position (2,) m, parent link direction rad) of each joint, base frame."""
    lengths = (arm.l1, arm.l2)
    p = np.zeros(2)
    direction = 0.0
    out = [(p.copy(), direction)]
    for i in range(2):
        direction += angles[i]
        p = p + lengths[i] * np.array([math.cos(direction), math.sin(direction)])
        out.append((p.copy(), direction))
    return out


def arc_segments(center: np.ndarray, radius: float, a0: float, a1: float, *,
                 n: int = 36, z: float = ARC_Z) -> np.ndarray:
    """(n, 2, 3) line segments of the arc from angle a0 to a1 (rad) around ``center`` (2,)."""
    a = np.linspace(a0, a1, n + 1)
    pts = np.stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a),
                    np.full(n + 1, z)], axis=1)
    return np.stack([pts[:-1], pts[1:]], axis=1).astype(np.float32)


def workspace_message(X: float, Y: float, r: PlanarIKResult, arm: PlanarArm) -> str:
    """One sentence on why (X, Y) m is out of reach (cm and degrees)."""
    wx = X - arm.l3 * math.cos(r.theta0)
    wy = Y - arm.l3 * math.sin(r.theta0)
    return (f"Target ({X * 100:.1f}, {Y * 100:.1f}) cm is outside the workspace: with the "
            f"gripper pointing along the target direction (θ0 = {math.degrees(r.theta0):.1f}°) "
            f"the wrist point is {math.hypot(wx, wy) * 100:.1f} cm from the shoulder, and links "
            f"1 and 2 reach {abs(arm.l1 - arm.l2) * 100:.1f}–{(arm.l1 + arm.l2) * 100:.1f} cm. "
            f"The arm stretches towards it.")


class IKAccuracyLesson(LessonBase):
    """The IK-accuracy lesson on ``server`` (a :class:`armlab.app.lessons.LessonHandle`).

    Attributes:
        result: the solve for the current target (commanded = rounded angles).
        alternative: the in-range alternative when ``result`` is out of servo range.
        table_result: the last "Run the paper's table" result (``seed004.table``), or None.
        message: "" or the workspace message of the current target.
    """

    def __init__(self, server: Surface, ctx: LessonContext) -> None:
        super().__init__(server, ctx)
        self.arm = PlanarArm()
        model = load_robot("planar_servo_arm")
        if not isinstance(model, SerialChain):
            raise ValueError("robot: planar_servo_arm is not a serial arm")
        self.model = model
        self.rounding = "truncate"
        self.elbow = "down"
        self.target = (0.02, 0.21)
        self.result: PlanarIKResult | None = None
        self.alternative: Alternative | None = None
        self.table_result: dict[str, Any] | None = None
        self.message = ""
        self._outside = False
        self._build_scene()
        try:
            self._build_gui()
            self.set_target(*self.target)
        except BaseException:
            self._remove()
            raise

    # ================================================================== scene

    def _build_scene(self) -> None:
        scene = self.server.scene
        self.root = scene.add_frame("/ik", show_axes=False)
        self.view = ArmView(self.server, self.model, root="/ik/arm", color=ARM_RGBA)
        self.ghost = ArmView(self.server, self.model, root="/ik/ghost", color=GHOST_RGBA)
        self.ghost.root.visible = False
        for view in (self.view, self.ghost):  # the board is drawn once, as graph paper
            for mesh in view.meshes():
                if mesh.name.endswith("/board/geometry_0"):
                    mesh.visible = False
        scene.add_grid("/ik/paper", width=PAPER_M, height=PAPER_M, plane="xy", cell_size=0.01,
                       section_size=0.05, cell_color=(170, 200, 230),
                       section_color=(90, 140, 200), plane_color=(250, 250, 245),
                       plane_opacity=1.0, position=(0.1, 0.1, -0.0001))
        half = PAPER_M / 2
        for i, (x, y) in enumerate(((-half, -half), (half, -half), (half, half), (-half, half))):
            # empty frames at the paper's corners: the camera frames the whole paper, not
            # only the arm on it (a grid is framed by its centre alone)
            scene.add_frame(f"/ik/paper/corner{i}", show_axes=False, position=(x, y, 0.0))
        base = np.asarray(self.model.base_pose, dtype=float)
        b = "/ik/base"
        self.base = scene.add_frame(b, show_axes=False, position=base[:3, 3])
        # the paper's 24 targets lie on X + Y = 23 cm
        scene.add_line_segments(f"{b}/paper_line", points=np.array(
            [[[0.0, 0.23, 0.001], [0.23, 0.0, 0.001]]], dtype=np.float32),
                                colors=(120, 120, 200), thickness=0.0015)
        # (centred on its point: hung to its right it ran out of a narrow view)
        theme.add_label(scene, f"{b}/paper_label", "Table 1 line X + Y = 23 cm",
                        position=(0.13, 0.11, 0.005), anchor="top-center")
        self.reach = scene.add_line_segments(
            f"{b}/reach", points=arc_segments(np.zeros(2), self.arm.reach, -math.pi / 2,
                                              3 * math.pi / 2, n=96, z=0.001),
            colors=(180, 180, 180), thickness=0.001)
        self.arcs = [scene.add_line_segments(f"{b}/range{i}", points=np.zeros((1, 2, 3)),
                                             colors=OK_RGB, thickness=0.0025)
                     for i in range(3)]
        self.needles = [scene.add_line_segments(f"{b}/angle{i}", points=np.zeros((1, 2, 3)),
                                                colors=OK_RGB, thickness=0.0035)
                        for i in range(3)]
        self.gizmo = scene.add_transform_controls(
            f"{b}/target", scale=0.06, disable_rotations=True, active_axes=(True, True, False),
            depth_test=False, position=(self.target[0], self.target[1], 0.0))
        scene.add_icosphere(f"{b}/target/dot", radius=0.004, color=(250, 160, 0))
        self.reached = scene.add_icosphere(f"{b}/reached", radius=0.003, color=(200, 20, 20))
        self.table_dots = scene.add_point_cloud(
            f"{b}/table_dots", points=np.zeros((1, 3), dtype=np.float32),
            colors=(30, 90, 200), point_size=0.004, visible=False)

        @self.gizmo.on_update  # a page's drag only: setting the position from Python is silent
        def _(event: viser.TransformControlsEvent) -> None:
            # viser runs callbacks in a thread pool: read the gizmo under the lock, so the
            # positions solved follow the order the lock is taken in (a position read
            # before waiting could be older than one already solved)
            if event.client is None:
                return
            with self._lock:
                p = np.asarray(self.gizmo.position, dtype=float)
                try:
                    self.set_target(float(p[0]), float(p[1]), client=event.client,
                                    dragging=True)
                except ValueError as exc:
                    notify(event.client, "Target refused", str(exc))

        # steeply down across the board's diagonal: the board fills a narrow view too
        show(self.server, View(roots=("/ik",), direction=(-0.1, 0.15, -0.4)))

    # ================================================================== GUI

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.readout = self._gui.add_status(try_this=TRY)
        folder = self._gui.add(gui.add_folder("Target and solution", order=-70.0))
        with folder:
            gui.add_markdown("Drag the target in the arm's plane, or type it.")
            lim = TARGET_LIMIT_CM
            self.x_input = gui.add_number("Target X (cm)", initial_value=self.target[0] * 100,
                                          min=-lim, max=lim, step=0.1)
            self.y_input = gui.add_number("Target Y (cm)", initial_value=self.target[1] * 100,
                                          min=-lim, max=lim, step=0.1)
            self.x_input.on_update(lambda e: self._on_typed(e, 0))
            self.y_input.on_update(lambda e: self._on_typed(e, 1))
            self.refused = 0  #: typed values refused (not numbers, beyond ±30 cm)
            self.elbow_input = gui.add_dropdown("Elbow", tuple(ELBOW_LABELS.values()),
                                                initial_value=ELBOW_LABELS[self.elbow])
            self.rounding_input = gui.add_dropdown(
                "Servo command", tuple(ROUNDING_LABELS.values()),
                initial_value=ROUNDING_LABELS[self.rounding],
                hint="The paper's software truncates the servo angle to whole degrees")
            rows = tuple(f"{int(r[0])}: ({r[1]:g}, {r[2]:g})" for r in TABLE1)
            self.row_input = gui.add_dropdown("Put the target on row", ("—", *rows),
                                              initial_value="—")

        @self.elbow_input.on_update
        def _(event: viser.GuiEvent) -> None:
            key = _key(ELBOW_LABELS, self.elbow_input.value)
            guarded(event, lambda: self.set_mode(elbow=key))

        @self.rounding_input.on_update
        def _(event: viser.GuiEvent) -> None:
            key = _key(ROUNDING_LABELS, self.rounding_input.value)
            guarded(event, lambda: self.set_mode(rounding=key))

        @self.row_input.on_update
        def _(event: viser.GuiEvent) -> None:
            value = str(self.row_input.value)
            if value == "—":
                return
            no = int(value.split(":")[0])
            _, X, Y, *_ = TABLE1[no - 1]
            guarded(event, lambda: self.set_target(X / 100, Y / 100, client=event.client))

        tab = self._gui.add(gui.add_folder("The paper's Table 1", order=-60.0))
        with tab:
            self.table_button = gui.add_button(
                "Run the paper's table", color="green", icon=viser.Icon.TABLE,
                hint="Solve the 24 targets with the elbow and rounding above")
            self.table_button.on_click(lambda e: guarded(e, self.run_table))
            self.download = gui.add_button("Download the table (CSV)", icon=viser.Icon.DOWNLOAD,
                                           disabled=True)
            self.download.on_click(lambda e: send_download(e, self.csv_bytes))
            self.summary = gui.add_markdown("")
            self.error_plot = add_chart(
                gui, data=(np.arange(1.0, 25.0), *(np.zeros(24) for _ in TABLE_COLUMNS)),
                series=({"label": "row"},
                        *(uplot_series(SeriesSpec(f"{label} (mm)", COLORS[i], dash(i)))
                          for i, label in enumerate(TABLE_COLUMNS))),
                scales={"x": fixed_x(1.0, 24.0), "y": {"auto": True}},
                x_label="row", y_label="mm", title="Error per row",
                height=180, visible=False)
            self.table_md = gui.add_markdown("")
            self.out_of_range_md = gui.add_markdown("")

    # ================================================================== actions

    def _on_typed(self, event: viser.GuiEvent, axis: int) -> None:
        """A typed target coordinate: refuse a bad number, else solve (a target out of
        reach is accepted and explained). The lesson's own writes (no client) are ignored."""
        if event.client is None:
            return
        handle = (self.x_input, self.y_input)[axis]
        name = str(handle.label)  # (as the page's screen names it)
        with self._lock:
            if self._closed:
                return
            raw = handle.value
            try:  # the page's one rule: past the range, its end (and the page told)
                cm, clamped = typed_value(raw, name=name, lo=-TARGET_LIMIT_CM,
                                          hi=TARGET_LIMIT_CM)
            except ValueError as exc:
                self.refused += 1
                notify(event.client, "Value refused",
                       f"{exc}; kept {self.target[axis] * 100:.2f}.")
                self._write_inputs()
                return
            if clamped is not None:
                tell_limit(event.client, name, clamped)
            v = cm / 100
            target = list(self.target)
            if v != round(target[axis], 4):
                target[axis] = v
                self.set_target(target[0], target[1], client=event.client, from_inputs=True)
            if clamped is not None:  # the input shows the end it was set to
                self._write_inputs()

    def _write_inputs(self) -> None:
        """Show the target in the typed inputs (their callbacks ignore writes from Python)."""
        self.x_input.value = round(self.target[0] * 100.0, 2)  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none
        self.y_input.value = round(self.target[1] * 100.0, 2)  # type: ignore[misc]  # viser: value's setter is apart from its getter, mypy sees none

    def set_mode(self, *, elbow: str | None = None, rounding: str | None = None) -> None:
        """Change the elbow branch or the rounding and solve the target again."""
        with self._lock:
            self.elbow = elbow or self.elbow
            self.rounding = rounding or self.rounding
            self.set_target(*self.target)

    def set_target(self, X: float, Y: float, *, client: viser.ClientHandle | None = None,
                   dragging: bool = False, from_inputs: bool = False) -> PlanarIKResult:
        """Solve for target (X, Y) m and show it.

        A target out of reach is still shown (the arm stretched towards it) with
        one message: the readout says why, and the client that moved it gets
        one notification (while dragging, only when the target first leaves).
        Raises ValueError for a non-finite target.
        """
        if not (math.isfinite(X) and math.isfinite(Y)):
            raise ValueError(f"target must be finite, got ({X}, {Y})")
        with self._lock:
            if self._closed:
                return self.result  # type: ignore[return-value]  # closed: the lesson's last result (None before any)
            r = solve(X, Y, arm=self.arm, elbow=self.elbow, rounding=self.rounding)
            self.target = (X, Y)
            self.result = r
            self.alternative = None
            if r.reachable and not r.in_servo_range:
                self.alternative = in_range_alternative(X, Y, arm=self.arm, elbow=self.elbow,
                                                        rounding=self.rounding)
            outside = not r.reachable
            self.message = workspace_message(X, Y, r, self.arm) if outside else ""
            if outside and (not dragging or not self._outside):
                notify(client, "Outside the workspace", self.message, color="yellow")
            self._outside = outside
            with self.server.atomic():
                self._show(r, from_inputs=from_inputs, dragging=dragging)
            return r

    def _show(self, r: PlanarIKResult, *, from_inputs: bool, dragging: bool) -> None:
        X, Y = self.target
        self.view.set_q(np.array(r.commanded))
        alt = self.alternative
        self.ghost.root.visible = alt is not None
        if alt is not None:
            self.ghost.set_q(np.array(alt.result.commanded))
        self.reached.position = (r.position[0], r.position[1], 0.004)
        if not dragging:
            self.gizmo.position = (X, Y, 0.0)
        if not from_inputs:
            self._write_inputs()
        ok = servo_in_range(r.servo_deg, self.arm)
        ranges = joint_ranges_deg(self.arm)
        for i, (center, parent) in enumerate(joint_frames(r.commanded, self.arm)):
            lo, hi = (math.radians(a) for a in ranges[i])
            color = OK_RGB if ok[i] else BAD_RGB
            arc = arc_segments(center, ARC_RADII[i], parent + lo, parent + hi)
            self.arcs[i].points = arc
            self.arcs[i].colors = _colors(color, len(arc))
            a = parent + r.angles[i]
            tip = center + 1.25 * ARC_RADII[i] * np.array([math.cos(a), math.sin(a)])
            self.needles[i].points = np.array([[[center[0], center[1], ARC_Z],
                                                [tip[0], tip[1], ARC_Z]]], dtype=np.float32)
            self.needles[i].colors = _colors(color, 1)
        self.readout.content = self._readout_html(r, ok)

    def _readout_html(self, r: PlanarIKResult, ok: list[bool]) -> str:
        X, Y = self.target
        err_mm = math.hypot(r.position[0] - X, r.position[1] - Y) * 1000.0
        deg = [math.degrees(a) for a in r.angles]
        cmd = [math.degrees(a) for a in r.commanded]
        cells = "".join(
            f"<tr><td>θ{i + 1}</td><td>{deg[i]:.2f}°</td><td>{cmd[i]:.2f}°</td>"
            f"<td style='color:{'#2e7d32' if ok[i] else '#b00020'}'>{r.servo_deg[i]:.2f}°"
            f"{'' if ok[i] else ' ✗'}</td></tr>" for i in range(3))
        lines = [
            f"<b>target</b> ({X * 100:.2f}, {Y * 100:.2f}) cm · <b>computed</b> "
            f"({r.position[0] * 100:.2f}, {r.position[1] * 100:.2f}) cm · "
            f"<b>error</b> {err_mm:.2f} mm",
            "<table style='font-size:0.9em'><tr><th></th><th>exact</th><th>commanded</th>"
            f"<th>servo</th></tr>{cells}</table>",
        ]
        if self.message:
            lines.append(f"<div style='color:#a15c00'>⚠ {esc(self.message)}</div>")
        elif not r.in_servo_range:
            bad = ", ".join(f"θ{i + 1}" for i in range(3) if not ok[i])
            text = (f"⚠ {bad} needs a servo angle outside 0–180°: the servo cannot go there.")
            alt = self.alternative
            if alt is not None:
                a = alt.result
                text += (f" In range instead (green ghost): turn the gripper by "
                         f"{math.degrees(alt.theta0_shift):+.1f}°, reaching "
                         f"({a.position[0] * 100:.2f}, {a.position[1] * 100:.2f}) cm, "
                         f"{alt.error * 1000:.2f} mm from the target.")
            lines.append(f"<div style='color:#b00020'>{esc(text)}</div>")
        return f"<div style='font-size:0.92em;{INSET}'>" + "<br>".join(lines) + "</div>"

    # ================================================================== the table

    def run_table(self) -> dict[str, Any]:
        """Recompute Table 1 with the current elbow and rounding and show it."""
        with self._lock:
            result = table(rounding=self.rounding, elbow=self.elbow)
            rows = result["rows"]
            paper_r = np.array([r["paper_r_cm"] for r in rows]) * 10.0
            paper_err = np.array([math.hypot(r["paper_computed_cm"][0] - r["target_cm"][0],
                                             r["paper_computed_cm"][1] - r["target_cm"][1])
                                  for r in rows]) * 10.0
            lab_err = np.array([_lab_error_cm(r) for r in rows]) * 10.0
            with self.server.atomic():
                self.error_plot.data = (np.arange(1.0, len(rows) + 1.0), paper_r, paper_err,
                                        lab_err)
                self.error_plot.visible = True
                self.table_md.content = table_markdown(result)
                self.out_of_range_md.content = out_of_range_markdown(result)
                matched = sum(1 for r in rows if r["in_servo_range"]
                              and r["computed_vs_paper_cm"] <= 0.01)
                in_range = sum(1 for r in rows if r["in_servo_range"])
                self.summary.content = (
                    f"**{ROUNDING_LABELS[self.rounding]}, {ELBOW_LABELS[self.elbow]}**: "
                    f"{in_range} of 24 rows in servo range, {matched} of them match the "
                    f"paper's X1/Y1 to 0.01 cm. Paper's mean error R: "
                    f"{result['paper_mean_r_cm'] * 10:.1f} mm.")
                pts = np.array([[r["paper_measured_cm"][0] / 100, r["paper_measured_cm"][1]
                                 / 100, 0.002] for r in rows], dtype=np.float32)
                self.table_dots.points = pts
                self.table_dots.visible = True
                self.download.disabled = False
            self.table_result = result  # last: a reader seeing it sees the shown table
            return result

    def csv_bytes(self) -> tuple[str, bytes]:
        """(file name, CSV) of the last table run: the ``seed004-table --csv`` columns."""
        result = self.table_result
        if result is None:
            raise ValueError("run the paper's table first")
        rows = SEED004_EXPERIMENTS[0].rows(result)  # type: ignore[misc]  # rows() of the paper's table experiment takes its result
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v)
                             for k, v in row.items()})
        name = f"seed004-table1-{result['elbow']}-{result['rounding']}.csv"
        return name, buf.getvalue().encode()

    # ================================================================== lifetime

    def _remove(self) -> None:
        self._gui.remove_all()
        for node in (self.view, self.ghost, self.root):
            remove_quietly(node)

    def close(self) -> None:
        """Remove the lesson's scene and GUI."""
        if self.mark_closed():
            self._remove()


def _lab_error_cm(row: dict[str, Any]) -> float:
    """The lab's distance to the target, cm: the solution if in range, else the alternative."""
    if row["in_servo_range"] or row["alternative"] is None:
        c = row["computed_cm"]
        return math.hypot(c[0] - row["target_cm"][0], c[1] - row["target_cm"][1])
    return float(row["alternative"]["error_cm"])


def table_markdown(result: dict[str, Any]) -> str:
    """Table 1 with the paper's columns beside the lab's (cm)."""
    head = ("| No | target X, Y | paper X1, Y1 | lab X1, Y1 | Δ | paper X2, Y2 | paper R "
            "| lab R |\n|---:|---|---|---|---:|---|---:|---:|\n")
    lines = []
    for r in result["rows"]:
        t, p, c, m = r["target_cm"], r["paper_computed_cm"], r["computed_cm"], \
            r["paper_measured_cm"]
        flag = "" if r["in_servo_range"] else " ⚠"
        lines.append(
            f"| {r['no']} | {t[0]:g}, {t[1]:g} | {p[0]:.2f}, {p[1]:.2f} | "
            f"{c[0]:.2f}, {c[1]:.2f}{flag} | {r['computed_vs_paper_cm']:.2f} | "
            f"{m[0]:g}, {m[1]:g} | {r['paper_r_cm']:.2f} | {r['r_cm']:.2f} |")
    return ("Lengths in cm. Δ = lab X1/Y1 to paper X1/Y1; R = X1/Y1 to the measured X2/Y2. "
            "⚠ = a servo out of its 0–180° range.\n\n" + head + "\n".join(lines))


def out_of_range_markdown(result: dict[str, Any]) -> str:
    """Why the ⚠ rows are out of range, and the lab's in-range alternative for each."""
    bad = [r for r in result["rows"] if not r["in_servo_range"]]
    if not bad:
        return "Every row is within the servos' range."
    lines = [f"**Out of range ({len(bad)} rows).** The paper says these were "
             "\"recalculated\" without saying how. The lab keeps the position and turns the "
             "gripper (θ0, free for a 3-joint arm reaching a 2-D point) until every servo is "
             "in range:", ""]
    for r in bad:
        servo = r["servo_deg"]
        worst = max(range(3), key=lambda i: max(servo[i] - 180.0, -servo[i]))
        why = (f"θ{worst + 1} = {r['angles_deg'][worst]:.1f}° needs servo {worst + 1} at "
               f"{servo[worst]:.0f}°")
        alt = r["alternative"]
        fix = "no in-range orientation" if alt is None else (
            f"θ0 {alt['theta0_shift_deg']:+.1f}° ({alt['elbow']}), lands at "
            f"({alt['computed_cm'][0]:.2f}, {alt['computed_cm'][1]:.2f}), "
            f"{alt['error_cm'] * 10:.2f} mm off")
        lines.append(f"- row {r['no']} ({r['target_cm'][0]:g}, {r['target_cm'][1]:g}): "
                     f"{why}; {fix}")
    return "\n".join(lines)


def _colors(rgb: tuple[int, int, int], n: int) -> np.ndarray:
    """(n, 2, 3) uint8: one colour for both ends of ``n`` line segments."""
    return np.broadcast_to(np.array(rgb, dtype=np.uint8), (n, 2, 3)).copy()


def _key(labels: dict[str, str], value: object) -> str:
    for k, v in labels.items():
        if v == value:
            return k
    raise ValueError(f"unknown choice {value!r}")


#: This lesson, as the lab lists it (:data:`armlab.app.lessons.catalog.LESSONS`).
LESSON = Lesson(name=NAME, title=TITLE, help=HELP, first_step=TRY, robots=ROBOTS, build=build,
                order=ORDER, private=PRIVATE)

__all__ = ["IKAccuracyLesson", "build", "NAME", "TITLE", "HELP", "ROBOTS", "LESSON"]
