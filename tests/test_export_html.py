"""The page to hand in (issue 36, item 4): ``armlab export RUN --html OUT`` and
:func:`armlab.app.export.html.export_html` write one self-contained HTML file that names
nothing outside itself, opens from disk in a real headless Chromium with every request
blocked (and asks for nothing), draws the arm in 3D (pixels that change with the time
slider), shows the run's figures as text and runs nothing a hostile run file holds.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from _helpers import expected_console, wait_for

from armlab.app.commands.cli import main
from armlab.app.export.charts import envelope_indices
from armlab.app.export.html import MAX_FRAMES, POSITION_SCALE, export_html, write_html
from armlab.control.runs import Run, RunFileError, lab_version, read_run, write_run
from armlab.kinematics import load_robot

ROBOT = "receptionist_arm"
#: Where the teacher's page's screenshot goes (ARMLAB_SHOTS, to look at it; else the
#: test's own folder).
SHOT_DIR = Path(os.environ["ARMLAB_SHOTS"]) if os.environ.get("ARMLAB_SHOTS") else None
FIGURES = {"overshoot_pct": 25.4, "settling_s": 0.71, "yield_deg": None}

#: Text of a run that tries to run script or fetch something when shown.
HOSTILE = '<img src=x onerror="window.__pwned=1"></script><script>window.__pwned=2</script>'


def step_run(*, m: int = 3000, robot: str = ROBOT, joint_names: tuple[str, ...] | None = None,
             source: str = "page:compliance", extra: dict | None = None,
             params: dict | None = None, figures: dict | None = None) -> Run:
    """A step on the receptionist arm's second joint, answered by a damped second-order
    response (25 % overshoot), with the first joint swinging and a torque recorded."""
    model = load_robot(ROBOT)
    t = np.arange(m) * 0.002
    n = model.n
    q_cmd = np.zeros((m, n))
    q_cmd[:, 0] = 0.3 * np.sin(t)
    q_cmd[t >= 0.5, 1] = 0.6
    wn, zeta = 12.0, 0.4
    s = np.clip(t - 0.5, 0.0, None)
    wd = wn * np.sqrt(1 - zeta**2)
    response = 1 - np.exp(-zeta * wn * s) * (np.cos(wd * s) + zeta / np.sqrt(1 - zeta**2)
                                             * np.sin(wd * s))
    q = q_cmd.copy()
    q[:, 1] = 0.6 * response * (t >= 0.5)
    q[:, 2] = -0.4 + 0.1 * np.cos(2 * t)
    tau = np.column_stack([0.1 * np.sin(3 * t), np.gradient(q[:, 1]), np.full(m, np.nan)])
    return Run(robot=robot, joint_names=joint_names or model.joint_names, source=source,
               lab_version=lab_version(), created="2026-11-28T03:20:00Z",
               params=params if params is not None else {"kp": 3.8, "kv": 2.5, "law": "2.26"},
               commands=({"t": 0.5, "kind": "Step", "joint": 1, "delta_rad": 0.6},),
               figures=figures if figures is not None else dict(FIGURES), t=t,
               signals={"q_cmd": q_cmd, "q": q, "tau_dyn": tau},
               extra=extra if extra is not None else {"challenge": {"name": "step"}})


def page_data(html: str) -> dict:
    """The page's JSON data block."""
    block = re.search(r'<script type="application/json" id="run-data">(.*?)</script>', html,
                      re.S)
    assert block is not None
    return json.loads(block.group(1))


# --------------------------------------------------------------------------- the file


def test_the_page_names_nothing_outside_itself():
    html = export_html(step_run())
    assert not re.search(r"https?:|//[a-z0-9]|\bsrc\s*=|\bhref\s*=|url\(|@import|@font-face",
                         html, re.I)
    assert "<link" not in html.lower()
    # and the browser is told to fetch nothing, whatever the page held
    csp = re.search(r'http-equiv="Content-Security-Policy" content="([^"]*)"', html)
    assert csp is not None and "default-src 'none'" in csp.group(1)
    assert "'unsafe-inline'" not in csp.group(1).split("script-src")[1].split(";")[0]


def test_the_poses_are_the_lab_forward_kinematics():
    run = step_run(m=5000)
    model = load_robot(ROBOT)
    data = page_data(export_html(run))
    frames, ghost, t = data["frames"], data["ghost"], data["t"]
    assert 100 < len(frames) <= MAX_FRAMES and len(ghost) == len(frames) == len(t)
    assert t[0] == run.t[0] and t[-1] == pytest.approx(run.t[-1])
    for k in (0, len(frames) // 3, len(frames) - 1):
        i = int(np.argmin(np.abs(run.t - t[k])))
        for rows, q in ((frames, run.signals["q"][i]), (ghost, run.signals["q_cmd"][i])):
            points = np.array(rows[k], dtype=float).reshape(-1, 3) * POSITION_SCALE
            poses = model.base_pose @ model.link_poses(q)
            tip = (poses[-1] @ model.tip)[:3, 3]
            expected = np.vstack([model.base_pose[:3, 3], poses[:, :3, 3], tip])
            np.testing.assert_allclose(points, expected, atol=POSITION_SCALE)


def test_a_chart_keeps_a_one_sample_peak():
    values = np.zeros((20_000, 2))
    values[12_345, 0] = 9.0
    values[777, 1] = -3.0
    kept = envelope_indices(values, buckets=300)
    assert len(kept) <= 2 + 300 * 4
    assert 12_345 in kept and 777 in kept and kept[0] == 0 and kept[-1] == 19_999


def test_a_quadruped_run_is_drawn_leg_by_leg():
    model = load_robot("quadruped")
    names = tuple(j.name for leg in ("RF", "LF", "RH", "LH") for j in model.legs[leg].joints)
    t = np.arange(200) * 0.01
    q = np.tile([0.0, 0.4, -0.8], 4) + 0.1 * np.sin(t)[:, None]
    run = Run(robot="quadruped", joint_names=names, source="page:quadruped",
              lab_version=lab_version(), created="2026-11-28T03:20:00Z", params={},
              commands=(), figures={}, t=t, signals={"q": q})
    data = page_data(export_html(run))
    assert data["chains"] == [5, 5, 5, 5] and len(data["statics"]) == 1
    assert data["ghost"] is None and data["triad"] is None


def test_a_run_of_an_unknown_robot_needs_its_model():
    run = step_run(robot="my_own_arm")
    with pytest.raises(ValueError, match="--robot"):
        export_html(run)
    assert "my_own_arm" in export_html(run, model=load_robot(ROBOT))
    with pytest.raises(ValueError, match="3 joints"):
        export_html(run, model=load_robot("so101"))


# --------------------------------------------------------------------------- the command


def test_the_command_writes_the_page_and_exits_0(tmp_path, capsys):
    run_file = write_run(step_run(), tmp_path / "step.armlab-run.zip")
    out = tmp_path / "step.html"
    assert main(["export", str(run_file), "--html", str(out)]) == 0
    html = out.read_text(encoding="utf-8")
    assert html.startswith("<!doctype html>") and "25.4 %" in html
    assert str(out) in capsys.readouterr().out
    assert {p.name for p in tmp_path.iterdir()} == {"step.armlab-run.zip", "step.html"}


def test_the_command_refuses_a_bad_run_file_with_its_one_message(tmp_path, capsys):
    bad = tmp_path / "bad.armlab-run.zip"
    bad.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(RunFileError) as refused:
        read_run(bad)
    out = tmp_path / "out.html"
    assert main(["export", str(bad), "--html", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"armlab export: {refused.value}"]
    assert not out.exists()


@pytest.mark.parametrize("where", ["missing folder", "a folder", "a read-only folder"])
def test_the_command_refuses_an_unwritable_out(tmp_path, capsys, where):
    run_file = write_run(step_run(m=300), tmp_path / "step.armlab-run.zip")
    if where == "missing folder":
        out = tmp_path / "no" / "such" / "page.html"
    elif where == "a read-only folder":  # (chmod does not stop root, which runs the suite)
        if not Path("/proc/self").is_dir():
            pytest.skip("needs Linux's /proc")
        out = Path("/proc/armlab-page.html")
    else:
        out = tmp_path / "a folder"
        out.mkdir()
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert main(["export", str(run_file), "--html", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"armlab export: cannot write the page to {out}")
    said = {"missing folder": "does not exist", "a folder": "it is a folder",
            "a read-only folder": "choose a folder you can write to"}[where]
    assert said in err[0]
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # no half-written file


def test_the_command_draws_a_named_robot_for_a_run_of_a_urdf(tmp_path, capsys):
    run_file = write_run(step_run(robot="my_own_arm", m=300), tmp_path / "own.armlab-run.zip")
    out = tmp_path / "own.html"
    assert main(["export", str(run_file), "--html", str(out)]) == 2
    assert "--robot" in capsys.readouterr().err
    assert main(["export", str(run_file), "--html", str(out), "--robot", ROBOT]) == 0
    assert out.is_file()


# --------------------------------------------------------------------------- in Chromium

#: Every canvas pixel's colour count and a digest of the pixels.
CANVAS_JS = """() => {
  const c = document.getElementById('view');
  const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  const colours = new Set();
  let h = 0;
  for (let i = 0; i < px.length; i += 4) {
    const v = (px[i] << 16) | (px[i + 1] << 8) | px[i + 2];
    colours.add(v);
    h = (Math.imul(h, 31) + v) | 0;
  }
  return [colours.size, h, c.width, c.height];
}"""

SET_SLIDER_JS = """(fraction) => {
  const s = document.getElementById('time');
  s.value = String(Math.round(+s.max * fraction));
  s.dispatchEvent(new Event('input', {bubbles: true}));
  return +s.value;
}"""


def open_offline(browser, path: Path):
    """A page of a fresh context that lets the browser read ``path`` and aborts every
    other request; returns (page, every request the page made, console errors)."""
    url = path.resolve().as_uri()
    context = browser.new_context(viewport={"width": 1200, "height": 900})
    context.route("**/*", lambda route: route.continue_() if route.request.url == url
                  else route.abort())
    page = context.new_page()
    requests: list[str] = []
    errors: list[str] = []
    page.on("request", lambda r: requests.append(r.url))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error"
            and not expected_console(m.text) else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_selector("body[data-ready='1']")
    return page, requests, errors, url


@pytest.mark.browser
@pytest.mark.timeout(900)
def test_the_page_opens_offline_and_draws_the_run(browser, tmp_path):
    out = write_html(step_run(), tmp_path / "step.html")
    page, requests, errors, url = open_offline(browser, out)
    colours, first, width, height = page.evaluate(CANVAS_JS)
    assert width > 100 and height > 100
    assert colours > 3, "the 3D view is blank"
    assert page.evaluate(SET_SLIDER_JS, 1.0) > 0
    wait_for(lambda: page.evaluate(CANVAS_JS)[1] != first, timeout=60,
             what="the 3D view to change with the time slider")
    assert page.inner_text("#time-readout") == "t = 5.998 s"
    at_end = page.evaluate(CANVAS_JS)[1]
    box = page.locator("#view").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] / 2 + 120, box["y"] + box["height"] / 2 + 40,
                    steps=5)
    page.mouse.up()
    wait_for(lambda: page.evaluate(CANVAS_JS)[1] != at_end, timeout=60,
             what="the 3D view to turn when dragged")
    page.evaluate(SET_SLIDER_JS, 0.0)
    page.click("#play")
    wait_for(lambda: page.evaluate("() => +document.getElementById('time').value") > 0,
             timeout=60, what="Play to move the time slider")
    assert page.inner_text("#time-readout") != "t = 0.000 s"
    figures = page.inner_text("#figures")
    assert "%OS, overshoot" in figures and "25.4 %" in figures and "0.71 s" in figures
    assert "not measured" not in figures and "yield" not in figures  # only what was measured
    params = page.inner_text("#params")
    assert "Kp" in params and "3.8" in params and "2.26" in params
    assert page.locator("svg.chart").count() == 5  # 3 angle charts, 2 with a torque
    page.close()
    assert requests == [url]
    assert errors == []


@pytest.mark.browser
@pytest.mark.timeout(900)
def test_a_hostile_run_is_shown_as_text_and_runs_nothing(browser, tmp_path):
    names = (HOSTILE, "theta0</title><script>window.__pwned=3</script>", "theta2")
    run = step_run(robot=HOSTILE, joint_names=names, source=HOSTILE,
                   params={"kp": 3.8, HOSTILE: HOSTILE}, figures={HOSTILE: 1.5},
                   extra={"note": HOSTILE, "x": "</script><svg onload=window.__pwned=4>"})
    run_file = write_run(run, tmp_path / "hostile.armlab-run.zip")
    out = tmp_path / "hostile.html"
    assert main(["export", str(run_file), "--html", str(out), "--robot", ROBOT]) == 0
    page, requests, errors, url = open_offline(browser, out)
    assert page.evaluate("() => window.__pwned") is None
    assert page.locator("img, main script, svg[onload], [onerror]").count() == 0
    assert HOSTILE in page.inner_text("h1")
    assert HOSTILE in page.inner_text("#joints")
    assert HOSTILE in page.inner_text("#params")
    assert page.get_attribute("#figures th", "title") == HOSTILE  # the key, whole
    assert page.get_attribute("#figures td", "data-figure") == HOSTILE
    assert '<img src=x onerror="window' in page.text_content("#figures th")  # its label
    assert "window.__pwned=4" in page.text_content("#extra")
    assert page.title().startswith(f"{HOSTILE} · {HOSTILE}")
    assert page.evaluate(CANVAS_JS)[0] > 3  # the page's own script still ran
    page.close()
    assert requests == [url]
    assert errors == []



def test_figures_read_with_their_units_and_joints():
    html = export_html(step_run(m=300, figures={"max_yield_deg.theta1": 7.331,
                                                "overshoot_pct": 12.0, "grip_n": None}))
    assert '>max yield (θ1)</th><td class="num" data-figure="max_yield_deg.theta1">' \
        '7.331 °</td>' in html
    assert ">%OS, overshoot</th>" in html and ">12 %</td>" in html
    assert "grip" not in html and "not measured" not in html  # a null is not a figure


def test_the_receptionist_arm_is_drawn_with_the_link_lengths_its_run_kept():
    for preset in ("18.5/25", "18.5/18.5", "17/25"):
        run = step_run(m=50, extra={"link_lengths_cm": preset})
        model = load_robot(ROBOT, preset=preset)
        tip = np.array(page_data(export_html(run))["frames"][0][-3:]) * POSITION_SCALE
        expected = (model.base_pose @ model.link_poses(run.signals["q"][0])[-1] @ model.tip)
        np.testing.assert_allclose(tip, expected[:3, 3], atol=POSITION_SCALE)


def handed_in_run() -> Run:
    """A step test as the lab saves it (issue 51): at rest but for one servo step of
    0.29° on θ2, figures partly not measured, the lab's run facts in ``extra``."""
    run = step_run(m=2000, figures={"overshoot_pct": 8.21, "peak_time_s": 0.91,
                                    "settling_s": 1.62, "rise_time_s": None,
                                    "step_joint": 2.0, "max_error_deg": None,
                                    "stiffness_nm_per_rad": None})
    q = np.zeros_like(run.signals["q"])
    q[1000:, 2] = np.radians(0.29)  # one position unit of the RX-24F
    trajectory = {"name": "step θ2", "times": list(np.linspace(0, 3, 400)),
                  "q": [[0.0, 0.0, float(x)] for x in np.linspace(0, -0.349, 400)]}
    commands = ({"t": 0.5, "kind": "RunTrajectory", "trajectory": trajectory,
                 "approach": False},
                {"t": 2.0, "kind": "Push", "force": [0.0, -4.0, 0.0], "link": 2,
                 "point": [0.0, 0.0, 0.1], "duration": 2.0})
    extra = {"link_lengths_cm": "18.5/25", "student": "Ada Lovelace",
             "run": {"label": "step θ2", "state": "finished", "t0_s": 0.5},
             "law": {"by": "student", "file": "compliance_law.py", "sha256": "ab" * 32,
                     "source": "def compliance_accel(...):\n    return 0\n",
                     "exercise": "compliance_law"},
             "backend": {"kind": "simulated", "servos": "RX-24F"},
             "gain_changes": [{"t": 1.0, "kp": 25.0}]}
    params = {"kp": 20.0, "kv": 5.0, "compliance": True, "law": "2.6", "feedforward": False}
    return Run(robot=run.robot, joint_names=run.joint_names, source="page:compliance",
               lab_version=run.lab_version, created="2026-12-01T22:03:41Z", params=params,
               commands=commands, figures=run.figures, t=run.t,
               signals={"q_cmd": q.copy(), "q": q, "tau_dyn": run.signals["tau_dyn"] * 0.01},
               extra=extra)


@pytest.mark.browser
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_teacher_reads_the_page(browser, tmp_path):
    out = write_html(handed_in_run(), tmp_path / "handed-in.html")
    page, requests, errors, url = open_offline(browser, out)
    assert page.title() == ("receptionist_arm · compliance lesson · step θ2 · Ada Lovelace"
                            " · 2026-12-01 22:03 UTC")
    figures = page.inner_text("#figures")
    assert "not measured" not in figures and "rise" not in figures
    for shown in ("%OS, overshoot\t8.21 %", "Tp, peak time\t0.91 s",
                  "Ts, settling time\t1.62 s", "stepped joint\tθ2"):
        assert shown in figures
    params = page.inner_text("#params")
    assert "Compliance\ton" in params and "Feed-forward θ̈_cmd\toff" in params
    assert "eq. 2.6" in params and "Kp\t20 1/s²" in params
    assert "stiffness nm per" not in page.inner_text("main") and "True" not in params
    law = page.inner_text("#law") + page.inner_text("#law-file")
    assert "student's own law" in law and "compliance_law.py" in law and "ab" * 32 in law
    assert not page.locator("#law-source").is_visible()  # folded away
    commands = page.inner_text("#commands")
    assert "0.50 s\tRunTrajectory\tstep θ2, 3 s to θ1 0°, θ0 0°, θ2 -20°" in commands
    assert "Push\t4 N for 2 s" in commands
    assert not page.locator("#commands-raw").is_visible()  # the raw JSON folded away
    assert page.locator("#commands").bounding_box()["height"] < 200
    meta = page.inner_text("#meta")
    assert "Ada Lovelace" in meta and "simulated arm (RX-24F model)" in meta
    assert "Kp 25" in meta  # the gain change, with its time
    # the charts at rest keep the live page's 4° span: a 0.29° step is a small one
    ticks = page.evaluate("""() => [...document.querySelectorAll('svg.chart')].filter(
        svg => svg.querySelector('text.title').textContent === 'θ2: angle').map(svg =>
        [...svg.querySelectorAll('text.tick[text-anchor=end]')].map(
            t => parseFloat(t.textContent.replace('\u2212', '-'))))""")
    (y,) = ticks
    assert max(y) - min(y) >= 3.0  # ticks over 4° at least (round ones inside it)
    titles = page.locator("svg.chart text.title").all_text_contents()
    assert "θ1: torque" in titles and "θ2: angle" in titles  # the live page's joint names
    page.screenshot(path=str(SHOT_DIR / "handed-in.png") if SHOT_DIR else
                    str(tmp_path / "handed-in.png"), full_page=True)
    page.close()
    assert requests == [url]
    assert errors == []


@pytest.mark.browser
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_the_labs_export_page_of_a_step_names_it_and_shows_its_figures(browser, tmp_path):
    """The lab's Export page of a step test (a headless lab on loop time): its title, and
    the figures the page showed beside the Step button."""
    from _helpers import served_lesson

    from armlab.app.lessons import LessonContext
    from armlab.app.lessons.compliance import build

    with served_lesson(build, LessonContext(realtime=False)) as lesson:
        wait_for(lambda: lesson.rig.loop.status.active, 60.0, "the arm to hold")
        lesson.run_step()
        wait_for(lambda: lesson.experiment.done, 120.0, "the step to be measured")
        shown = lesson.measured_pd
        name, data = lesson.runs.export_file()
    out = tmp_path / name
    out.write_bytes(data)
    page, requests, errors, url = open_offline(browser, out)
    assert re.fullmatch(r"receptionist_arm · compliance lesson · step θ2 · "
                        r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", page.title())
    figures = page.inner_text("#figures")
    assert f"%OS, overshoot\t{shown.overshoot_pct:.3g} %" in figures
    assert f"Ts, settling time\t{shown.settling_time_s:.3g} s" in figures
    assert "not measured" not in figures and "max |θ_cmd − θ|" not in figures
    assert "The lab's own law: eq. 2.6" in page.inner_text("#law")
    assert "simulated arm" in page.inner_text("#meta")
    assert "RunTrajectory" in page.inner_text("#commands")
    if SHOT_DIR:
        page.screenshot(path=str(SHOT_DIR / "lab-step.png"), full_page=True)
    page.close()
    assert requests == [url]
    assert errors == []


def test_odd_commands_and_facts_are_summarised_without_failing():
    """A run file's commands and run facts of any shape: summarised in bounded text."""
    commands = ({"t": 0.1, "kind": "Push", "force": [1e200, 1e300, 1e300], "duration": 1e31},
                {"t": 0.2, "kind": "RunTrajectory", "trajectory": {"name": "x" * 5000,
                                                                   "times": "no", "q": [[]]}},
                {"t": 0.3, "kind": "SetTarget", "xyz": None},
                {"t": 0.4, "kind": "Spring", "anchor": [0.1, 0.2, 0.3], "stiffness": 200.0},
                {"t": 0.5, "kind": "Other", "a": {"b": [1] * 10_000}})
    extra = {"run": "a label", "law": {"by": "student", "source": 5}, "backend": [1],
             "gain_changes": [{"t": "x"}, 3, {"t": 1.0, "kp": "y" * 1000}], "student": 4}
    run = step_run(m=50, extra=extra)
    run = Run(**{**run.__dict__, "commands": commands})
    html = export_html(run)
    assert "1e+300 N for 1e+31 s" in html and "hand pulled to (10, 20, 30) cm" in html
    assert "x" * 200 not in html.split('id="commands-raw"')[0]  # the summary is short
    assert "<title>receptionist_arm · compliance lesson · a label · 2026-11-28 03:20 UTC" in html
