"""The compliance lesson served by a real viser server on a free port, driven over its
websocket by a headless client that sends what a browser sends (armlab.app.testing.wsclient).

One lab for the module (the control loop runs in real time at 16 ms); each test
leaves the arm reset and holding.
"""

from __future__ import annotations

import csv
import io
import math
import time
import urllib.request
from dataclasses import replace

import numpy as np
import pytest
from _emulator import emulator
from _helpers import settled, wait_for

import armlab.control.loop as loop_module
from armlab.app.lessons.compliance_teach import STALE
from armlab.app.page.inputs import LIMIT_TITLE
from armlab.app.testing.wsclient import HeadlessClient
from armlab.control.params import DEFAULT, PRESETS, REFUSED_ON_SERVOS, check_gains

pytestmark = pytest.mark.realtime  # a served lab whose loop runs on the wall clock

KP = "Kp (1/s²)"
FF = "Feed-forward θ̈_cmd"


@pytest.fixture
def client(lab):
    c = HeadlessClient(lab.url.replace("http://", "ws://")).connect()
    c.wait_for(lambda: any(e.label == "Run thesis line" for e in c.gui.values()),
               what="the lesson's GUI")
    settled(lab.server, c)  # and every control made after that one
    yield c
    c.close()
    lesson = lab.lesson
    lesson.gains.set_params(PRESETS["well-damped default"])
    lesson.reset()
    wait_for(lambda: lesson.rig.loop.status.active and not lesson.rig.loop.status.estopped,
             60.0, "the arm to hold again")


def loop_of(lab):  # noqa: ANN001, ANN201
    return lab.lesson.rig.loop


def hand(lab, q: np.ndarray) -> np.ndarray:  # noqa: ANN001
    return lab.lesson.rig.model.fk(q)[:3, 3]


def hand_in_world(lab) -> np.ndarray:  # noqa: ANN001
    """(3,) the hand now, in the scene's world frame (where a page's drag lands), m."""
    p = hand(lab, loop_of(lab).recorder.snapshot(0.1)["q"][-1])
    return (lab.lesson.rig.model.base_pose @ np.append(p, 1.0))[:3]


def test_page_loads_on_loopback(lab):
    assert lab.url.startswith("http://127.0.0.1:")
    with urllib.request.urlopen(lab.url, timeout=30) as reply:
        assert reply.status == 200
        assert b"<html" in reply.read(2000).lower()


def test_slider_changes_the_loop_params_at_the_next_period(lab, client):
    loop = loop_of(lab)
    client.set_value(KP, 12.5)
    # the loop takes the gains first, the panel's record of them right after
    wait_for(lambda: loop.params.kp == 12.5 and lab.lesson.gains.params.kp == 12.5, 30.0,
             "Kp to reach the loop and the panel")
    # The period is applied at a period boundary: status.period_ms shows the
    # parameters in force.
    client.set_value("period (ms)", 20.0)
    wait_for(lambda: abs(loop.status.period_ms - 20.0) < 1e-9, 30.0, "the 20 ms period")
    assert loop.params.period == pytest.approx(0.020)


def test_preset_sets_every_slider_and_the_loop(lab, client):
    loop = loop_of(lab)
    client.set_value("Preset", "thesis Table 4.1")
    t41 = PRESETS["thesis Table 4.1"]
    wait_for(lambda: loop.params == t41, 30.0, "Table 4.1 in the loop")
    client.wait_for(lambda: client.find(KP).value == pytest.approx(3.8), what="Kp slider 3.8")
    client.wait_for(lambda: client.find("Kv (1/s)").value == pytest.approx(0.2), what="Kv 0.2")
    client.wait_for(lambda: client.find("Law").value.startswith("2.26"), what="law 2.26")
    # the thesis has no feed-forward: its switch shows off, and it can be turned on
    client.wait_for(lambda: client.find(FF).value is False, what="feed-forward off")
    wait_for(lambda: "chapter 4 does not reproduce" in lab.lesson.equations.content, 30.0,
             "the Teach tab's note on Table 4.1")
    client.set_value(FF, True)
    wait_for(lambda: loop.params.feedforward, 30.0, "feed-forward on in the loop")
    assert loop.params == replace(t41, feedforward=True)
    client.wait_for(lambda: client.find("Preset").value == "(custom)", what="preset (custom)")


def test_unstable_gains_warn_before_run(lab, client):
    warning = lab.lesson.warning
    assert not warning.visible
    client.set_value("Kv (1/s)", 0.05)  # Kp 20, Kv 0.05: ζp = 0.006
    wait_for(lambda: warning.visible, 30.0, "the stability warning")
    assert "badly damped" in warning.content


def test_run_thesis_line_fills_the_plots(lab, client):
    loop = loop_of(lab)
    client.click("Run thesis line")
    wait_for(lambda: loop.status.trajectory is not None, 30.0, "the run to start")
    wait_for(lambda: loop.status.trajectory is None, 60.0, "the run to end")
    # The page got the joint-angle chart (θ2 shown by default) with the elbow's 53° sweep.
    def sweep() -> float:
        for e in client.gui.values():
            if e.kind == "GuiUplotMessage" and str(e.props.get("title", "")).startswith(
                    "Joint angle"):
                data = e.props.get("data")
                if data is not None and len(data) == 4 and len(data[0]) > 50:
                    return float(np.ptp(data[1]))  # command series, degrees
        return 0.0

    client.wait_for(lambda: sweep() > 40.0, 60.0, "a 40°+ sweep in the angle chart")
    # the run's figures are worked out at the chart frame after the run ended
    wait_for(lambda: "max |θ_cmd − θ|" in lab.lesson.last_run_text, 60.0, "the run's figures")


def test_teach_panel_reports_the_thesis_metric_free_and_pushed(lab, client):
    loop, lesson = loop_of(lab), lab.lesson
    for pushed in (False, True):
        if pushed:  # (set before the run: the push must land while the 1.3 s line runs)
            client.set_value("Direction", "against the line (−y)")
            client.set_value("Push force (N)", 4.0)
            client.set_value("Duration (s)", 2.0)
            wait_for(lambda: lesson.pushes.force == 4.0 and lesson.pushes.duration == 2.0,
                     30.0, "4 N for 2 s in the lesson")
        client.click("Run thesis line")
        wait_for(lambda: loop.status.trajectory is not None, 30.0, "the run to start")
        if pushed:  # run again from its end pose, the arm travels back first: push the line
            start = lesson.rig.line.q[0]
            wait_for(lambda s=start: np.max(np.abs(
                loop.recorder.snapshot(0.05)["q_cmd"][-1] - s)) < 0.02, 60.0,
                "the line itself to begin")
            client.click("Push")
        wait_for(lambda: loop.status.trajectory is None, 60.0, "the run to end")
        wait_for(lambda p=pushed: (lesson.chapter4.pushed if p else lesson.chapter4.free)
                 is not None and (not p or "yield" in lesson.last_run_text), 60.0,
                 "the run's figures and their text")
    ch4 = lesson.chapter4
    # the compliant arm falls far behind its command under the push (the thesis: > 15°)
    assert ch4.pushed[2] > ch4.free[2] + 5.0
    assert ch4.yield_deg is not None and ch4.yield_deg[2] > 3.0
    # the pushed run began at the free run's end pose (it travelled back first): its yield
    # and its error are over the same samples of the line, both from the line's start, so
    # |θ_pushed − θ_free| ≤ |θ_pushed − θ_cmd| + |θ_cmd − θ_free| (it read 72° beside 11°)
    for j in range(3):
        assert ch4.yield_deg[j] <= ch4.pushed[j] + ch4.free[j] + 0.5, (j, ch4)
    text = lesson.last_run_text
    assert "free: θ1" in text and "pushed" in text and "yield" in text
    push = lesson._push  # (the push outlasts the line: the next test starts from rest)
    end = push[1] if push is not None else loop.status.t
    wait_for(lambda: loop.status.t > end + 1.5, 60.0, "the push over and the arm settled")


def test_push_raises_external_torque_and_the_compliant_arm_yields(lab, client):
    loop = loop_of(lab)

    def push_and_measure() -> tuple[float, float, float]:
        t_rest = loop.status.t + 0.5
        wait_for(lambda: loop.status.t > t_rest, 30.0, "half a second at rest")
        before = loop.recorder.snapshot(0.3)
        rest = float(np.max(np.abs(before["tau_ext"][-5:])))
        q0 = before["q"][-1].copy()
        client.set_value("Direction", "against the line (−y)")
        client.set_value("Push force (N)", 4.0)
        client.set_value("Duration (s)", 2.0)
        t_click = loop.status.t
        client.click("Push")

        ends: list[float] = []  # the loop time the push ends at, once pressed

        def pressed() -> bool:
            push = lab.lesson._push
            if push is not None and push[1] > t_click:
                ends.append(push[1])
            return bool(ends)

        wait_for(pressed, 30.0, "the push pressed")
        t_end = ends[0]
        # while it acts, the status line says so (not "holding")
        wait_for(lambda: "pushing 4 N" in str(lab.lesson.status.content), 30.0,
                 "the status to say pushing")
        wait_for(lambda: loop.status.t > t_end - 0.1, 60.0, "the push to run")
        snap = loop.recorder.snapshot(0.3)
        tau = float(np.max(np.abs(snap["tau_ext"][-5:])))
        dy = float(hand(lab, snap["q"][-1])[1] - hand(lab, q0)[1])  # along the push (−y)
        wait_for(lambda: loop.status.t > t_end + 1.5, 60.0, "the arm to settle")
        return rest, tau, -dy

    rest, tau_on, yield_on = push_and_measure()
    assert tau_on > 0.2 and tau_on > 4 * rest  # N·m: 4 N at ~12 cm lever
    client.set_value("Compliance on", False)
    wait_for(lambda: not loop.params.compliance, 30.0, "compliance off")
    _, tau_off, yield_off = push_and_measure()
    assert tau_off > 0.2
    # With compliance the hand gives way by centimetres; the PD loop holds it.
    assert yield_on > 0.01
    assert yield_on > 3 * abs(yield_off)


def test_dragging_the_hand_pulls_the_arm_with_a_spring(lab, client):
    loop = loop_of(lab)
    lesson = lab.lesson
    base = lesson.rig.model.base_pose
    p0 = hand(lab, loop.recorder.snapshot(0.1)["q"][-1])
    grab = lesson.rig.scene.hand.name
    start = (base @ np.append(p0, 1.0))[:3]
    anchor = (base @ np.append(p0 + np.array([0.0, -0.06, 0.0]), 1.0))[:3]
    client.drag(grab, "start", start=start, end=anchor)
    client.drag(grab, "update", start=start, end=anchor)
    wait_for(lambda: lesson._drag_anchor is not None, 30.0, "the spring")
    t0 = loop.status.t
    wait_for(lambda: loop.status.t > t0 + 1.5, 60.0, "1.5 s of pulling")
    p1 = hand(lab, loop.recorder.snapshot(0.1)["q"][-1])
    assert p0[1] - p1[1] > 0.01  # pulled more than 1 cm towards the hand's anchor
    assert lesson.rig.scene.force.visible  # the red arrow shows the pull
    client.drag(grab, "end", start=start, end=anchor)
    wait_for(lambda: lesson._drag_anchor is None, 30.0, "the spring to let go")


def test_quick_drags_leave_the_arm_free_once_the_hand_is_let_go(lab, client):
    """Drags sent back to back, as a quick hand does, are handled in the order they came:
    the last event is a let-go, so the arm ends free, the spring hidden; each drag's
    start, updates and end reach the loop in that order (a spring to each anchor, then
    none), none overtaking another (armlab.app.page.in_order)."""
    lesson = lab.lesson
    grab = lesson.rig.scene.hand.name
    base = lesson.rig.model.base_pose
    p0 = hand(lab, loop_of(lab).recorder.snapshot(0.1)["q"][-1])
    start = tuple((base @ np.append(p0, 1.0))[:3])
    before = len(lesson.runs.commands)
    sent: list[list[float] | None] = []
    for i in range(20):
        for j, phase in enumerate(("start", "update", "update", "end")):
            anchor = p0 + np.array([0.0, -0.002 * (i + 1), 0.001 * j])
            client.drag(grab, phase, start=start, end=tuple((base @ np.append(anchor, 1.0))[:3]))
            sent.append(None if phase == "end" else anchor.tolist())
    springs = lambda: [c["anchor"] for c in lesson.runs.commands[before:]  # noqa: E731
                       if c["kind"] == "Spring"]
    wait_for(lambda: len(springs()) >= len(sent), 60.0,
             lambda: f"the {len(sent)} drag events to reach the loop ({len(springs())} did)")
    got = springs()
    assert len(got) == len(sent)
    for g, s in zip(got, sent, strict=True):
        assert (g is None) == (s is None) and (s is None or np.allclose(g, s, atol=1e-9)), \
            (g, s)
    assert lesson._drag_anchor is None
    plant = lesson.rig.backend.plant
    wait_for(lambda: not np.any(plant.truth().external_torque), 30.0,
             "the loop to let the arm go (no spring on it)")
    wait_for(lambda: not lesson.rig.scene.spring.visible, 30.0, "the spring hidden")


def test_estop_switches_torque_off_and_reset_restores(lab, client):
    loop = loop_of(lab)
    plant = lab.lesson.rig.backend.plant
    assert all(r.torque_enable for r in plant.reports())
    client.click("E-STOP")
    wait_for(lambda: loop.status.estopped and not loop.status.torque_on, 30.0, "the e-stop")
    assert not any(r.torque_enable for r in plant.reports())
    client.wait_for(lambda: any("E-STOPPED" in str(e.props.get("content", ""))
                                for e in client.gui.values()), 30.0, "the E-STOPPED banner")
    client.click("Reset")
    wait_for(lambda: loop.status.torque_on and not loop.status.estopped, 30.0, "torque back on")
    assert all(r.torque_enable for r in plant.reports())


@pytest.mark.parametrize("typed,applied,says", [
    (1e6, 200.0, "Kp: 1e+06 is above the largest value, 200; set to 200."),
    (999999.0, 200.0, "Kp: 999999 is above the largest value, 200; set to 200."),
    (-5.0, 0.0, "Kp: -5 is below the smallest value, 0; set to 0.")])
def test_a_typed_value_past_the_range_is_applied_as_its_end(lab, client, typed, applied,
                                                            says):
    """One rule, one message: the value applied is the value the message names."""
    loop = loop_of(lab)
    kp = loop.params.kp
    n0 = len(client.notifications)
    client.set_value(KP, typed)
    client.wait_for(lambda: len(client.notifications) > n0, 30.0, "a notification")
    wait_for(lambda: loop.params.kp == applied, 30.0, "the end of the range in the loop")
    title, body = client.notifications[n0]
    assert (title, body) == (LIMIT_TITLE, says)
    assert all(t != "Value refused" for t, _ in client.notifications[n0:])
    client.set_value(KP, kp)
    wait_for(lambda: loop.params.kp == kp, 30.0, "Kp back")


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_bad_typed_value_is_refused_with_a_notification(lab, client, bad):
    loop = loop_of(lab)
    kp = loop.params.kp
    n0 = len(client.notifications)
    client.set_value(KP, bad)
    client.wait_for(lambda: len(client.notifications) > n0, 30.0, "a notification")
    title, body = client.notifications[-1]
    assert title == "Value refused" and "Kp" in body
    client.wait_for(lambda: client.find(KP).value == pytest.approx(kp), 30.0, "Kp put back")
    assert loop.params.kp == kp and math.isfinite(lab.lesson.gains.params.kp)
    # The server goes on serving and taking good values.
    client.set_value(KP, kp + 1.0)
    wait_for(lambda: loop.params.kp == kp + 1.0, 30.0, "a good value after the bad one")
    with urllib.request.urlopen(lab.url, timeout=30) as reply:
        assert reply.status == 200


def test_garbage_message_does_not_kill_the_server(lab, client):
    loop = loop_of(lab)
    scene = lab.lesson.rig.scene
    nan = float("nan")
    client.send({"type": "TransformControlsUpdateMessage", "name": scene.target.name,
                 "wxyz": (1.0, 0.0, 0.0, 0.0), "position": (nan, 0.0, 0.0), "owner": ""})
    client.drag(scene.hand.name, "start", start=(0.0, 0.0, 1.0), end=(nan, nan, nan))
    client.drag(scene.hand.name, "end", start=(0.0, 0.0, 1.0), end=(nan, nan, nan))
    # a good drag after them: once it has taken hold and let go, the server has handled
    # the drag events sent before it (they start in the order they came)
    where = tuple(hand_in_world(lab))  # (held where it is: no pull)
    client.drag(scene.hand.name, "start", start=where, end=where)
    wait_for(lambda: lab.lesson._drag_anchor is not None, 30.0, "the good drag to hold")
    client.drag(scene.hand.name, "end", start=where, end=where)
    wait_for(lambda: lab.lesson._drag_anchor is None, 30.0, "the good drag to let go")
    assert loop.status.fault is None and loop.status.active
    client.set_value(KP, "not a number")  # viser cannot even cast it
    client.send({"type": "NoSuchMessage", "x": 1})  # viser drops this client's connection
    steps = loop.status.steps
    wait_for(lambda: loop.status.steps > steps + 10, 30.0, "the loop to keep running")
    with HeadlessClient(lab.url.replace("http://", "ws://")).connect() as other:
        other.wait_for(lambda: any(e.label == KP for e in other.gui.values()),
                       what="a fresh page")


def test_disconnect_mid_run_and_mid_drag_leaves_the_server_healthy(lab, client):
    loop = loop_of(lab)
    lesson = lab.lesson
    c2 = HeadlessClient(lab.url.replace("http://", "ws://")).connect()
    c2.wait_for(lambda: any(e.label == "Push" for e in c2.gui.values()), what="GUI")
    c2.click("Run thesis line")
    wait_for(lambda: loop.status.trajectory is not None, 30.0, "the run")
    grab = lesson.rig.scene.hand.name
    world = hand_in_world(lab)
    pull = world + np.array([0.0, 0.0, 0.05])
    c2.drag(grab, "start", start=tuple(world), end=tuple(pull))
    c2.drag(grab, "update", start=tuple(world), end=tuple(pull))
    wait_for(lambda: lesson._drag_anchor is not None, 30.0, "the spring to attach")
    c2.close()  # the tab closes mid-run, mid-drag
    wait_for(lambda: lesson._drag_anchor is None, 30.0, "the spring to be released")
    steps = loop.status.steps
    wait_for(lambda: loop.status.steps > steps + 20, 30.0, "the loop to keep running")
    assert loop.status.fault is None and loop.status.running
    frames = lesson.publisher.stats.pose_frames
    wait_for(lambda: lesson.publisher.stats.pose_frames > frames + 5, 30.0, "the publisher")
    assert lesson.publisher.stats.errors == 0
    b0 = client.bytes_received
    client.wait_for(lambda: client.bytes_received > b0, 30.0, "updates to the other page")


def test_csv_download_has_the_parameters_and_the_rows(lab, client):
    loop = loop_of(lab)
    client.click("Run thesis line")
    wait_for(lambda: loop.status.trajectory is not None, 30.0, "the run")
    wait_for(lambda: loop.status.trajectory is None, 60.0, "the run to end")
    client.click("Download the last run (CSV)")
    client.wait_for(lambda: client.downloads, 60.0, "the CSV download")
    name, data = next(iter(client.downloads.items()))
    assert name.endswith(".csv") and "thesis-line" in name
    text = data.decode()
    header = [ln for ln in text.splitlines() if ln.startswith("#")]
    assert any(f"kp={DEFAULT.kp}" in ln and "law=2.6" in ln for ln in header), header
    assert any("run: thesis line" in ln for ln in header)
    rows = list(csv.reader(io.StringIO("\n".join(ln for ln in text.splitlines()
                                                 if not ln.startswith("#")))))
    cols = rows[0]
    assert cols[0] == "t_s" and "q_cmd_theta2_rad" in cols and "tau_ext_theta1_Nm" in cols
    assert cols[1] == "wall_time_s"  # beside the period count: skipped periods show as gaps
    body = np.array([[float(v) if v else np.nan for v in r] for r in rows[1:]])
    assert len(body) > 70  # the 1.28 s line at 16 ms is 81 rows, plus its approach
    t, wall = body[:, 0], body[:, 1]
    assert np.all(np.diff(wall) > 0) and abs(wall[-1] - time.time()) < 600
    assert wall[-1] - wall[0] >= 0.9 * (t[-1] - t[0])  # wall time never runs short of t
    q2 = body[:, cols.index("q_cmd_theta2_rad")]
    assert np.degrees(np.nanmax(q2) - np.nanmin(q2)) > 40.0


def test_share_request_is_refused(lab, client):
    n0 = len(client.notifications)
    client.send({"type": "ShareUrlRequest"})
    client.wait_for(lambda: len(client.notifications) > n0, 30.0, "the refusal")
    assert client.notifications[-1][0] == "Sharing is off"
    assert lab.server._share_tunnel is None
    assert client.theme is not None and client.theme["show_share_button"] is False


def test_step_test_measures_the_pd_loop_beside_the_formulas(lab, client):
    lesson = lab.lesson
    lesson.measured_pd = None
    client.set_value("Joint", "θ2")
    client.click("Step")
    wait_for(lambda: lesson.measured_pd is not None, 30.0, "the step to be measured")
    m = lesson.measured_pd
    assert "step of θ2 by" in m.what
    # Kp 20, Kv 5: the formulas say Tr = 1.8/√20 = 0.40 s and Tp = 0.85 s; the servo's
    # own lag changes the figures but not their size.
    assert 0.2 < m.rise_time_s < 0.8
    # ζ = 0.56 < 1 must overshoot (12 % by the formula; about 4 % through the servos' lag)
    assert m.peak_time_s is not None and 0.4 < m.peak_time_s < 1.6
    assert m.overshoot_pct is not None and 1.0 < m.overshoot_pct < 24.0, m
    client.wait_for(lambda: any(
        "PD measured on: step of θ2" in str(e.props.get("_markdown", e.props.get("content", "")))
        for e in client.gui.values()), 60.0, "the measured column on the page")
    # and beside the Step button, without another click: its Tp and %OS
    client.wait_for(lambda: any(
        str(e.props.get("_markdown", "")).startswith("**Measured** (step of θ2")
        and "Tp " in str(e.props["_markdown"]) and "%OS " in str(e.props["_markdown"])
        for e in client.gui.values()), 60.0, "the figures beside the Step button")
    # a gain change leaves that step measured with the old gains: marked so on the page
    assert m.params is not None and m.params.kp == lesson.gains.params.kp
    kp = lesson.gains.params.kp
    client.set_value("Kp (1/s²)", kp + 5.0)

    def teach() -> str:
        return " ".join(str(e.props.get("_markdown", "")) for e in client.gui.values())

    client.wait_for(lambda: f"{STALE} Measured with Kp {kp:g}, not the gains in use" in teach(),
                    60.0, "the measured column marked stale")
    client.set_value("Kp (1/s²)", kp)
    client.wait_for(lambda: f"{STALE} Measured with" not in teach(), 60.0, "no longer stale")


def test_a_step_is_measured_with_no_page_open(lab):
    """The measurement waits for the step to end, not for a page: with every page closed
    (or its page behind, where a private lesson makes no frames) the figures come all the
    same, and a page opened later shows them."""
    lesson = lab.lesson
    wait_for(lambda: not lab.server.get_clients(), 30.0, "every page closed")
    wait_for(lambda: lesson.rig.loop.status.active, 60.0, "the arm holding")
    lesson.measured_pd = None
    lesson.run_step(joint=1, step_deg=10.0)
    wait_for(lambda: lesson.measured_pd is not None, 60.0,
             lambda: f"the step measured; said: {lesson.last_run_text!r}")
    assert f"step of {lesson.joint_labels[1]} by +10°" in lesson.measured_pd.what
    assert lesson.publisher.stats.skipped_idle > 0  # no frame was made meanwhile


def test_link_length_preset_rebuilds_the_arm(lab, client):
    lesson = lab.lesson
    old_loop = lesson.rig.loop
    client.set_value("Link lengths (cm)", "18.5/18.5")
    wait_for(lambda: lesson.rig is not None and lesson.rig.preset == "18.5/18.5", 60.0,
         "the 18.5/18.5 arm")
    assert lesson.rig.model.tip[0, 3] == pytest.approx(0.185)
    assert not old_loop.status.running
    wait_for(lambda: lesson.rig.loop.status.active, 60.0, "the new loop to hold")
    client.set_value("Link lengths (cm)", "18.5/25")
    wait_for(lambda: lesson.rig is not None and lesson.rig.preset == "18.5/25", 60.0,
         "the 18.5/25 arm back")
    wait_for(lambda: lesson.rig.loop.status.active, 60.0, "the loop to hold")


def counted_rule(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """The Params the control loop holds to the rule on gains from now on, one entry per
    time the rule is applied (the real :func:`check_gains` still decides)."""
    checked: list[object] = []

    def rule(params, *, servos):  # noqa: ANN001, ANN202
        checked.append(params)
        return check_gains(params, servos=servos)

    monkeypatch.setattr(loop_module, "check_gains", rule)
    return checked


def test_a_gain_change_is_analysed_once_and_a_preset_applied_once(lab, client, monkeypatch):
    """A slider's new Params meets the rule on gains exactly once on its way to the servos
    (the lesson's warning shows the verdict the loop got, the swap reuses it), and the
    preset picker set by a slider applies nothing again."""
    loop = loop_of(lab)
    lesson = lab.lesson
    applied: list[object] = []
    apply = lesson.gains._apply
    lesson.gains._apply = lambda p: (applied.append(p), apply(p))
    checked = counted_rule(monkeypatch)
    try:
        client.set_value("Kv (1/s)", 0.05)  # Kp 20: badly damped, so a warning shows
        wait_for(lambda: loop.params.kv == 0.05, 30.0, "Kv 0.05 in the loop")
        steps = loop.status.steps
        wait_for(lambda: loop.status.steps > steps + 3, 30.0, "the swap")
        assert checked == [loop.params] and len(applied) == 1
        assert loop.gains.params is loop.params  # what reached the loop is what was checked
        assert lesson.warning.visible and "badly damped" in lesson.warning.content
        assert loop.gains.warning.split(";")[0] in lesson.warning.content
        client.set_value("Kv (1/s)", 4.5)
        wait_for(lambda: loop.params.kv == 4.5, 30.0, "Kv 4.5 in the loop")
        assert len(checked) == 2 and len(applied) == 2
        wait_for(lambda: not lesson.warning.visible, 30.0, "the warning gone")
        checked.clear()
        applied.clear()
        # Back to the default by the slider: the picker shows the preset, nothing re-applies.
        client.set_value("Kv (1/s)", DEFAULT.kv)
        wait_for(lambda: loop.params == DEFAULT, 30.0, "the default again")
        client.wait_for(lambda: client.find("Preset").value == "well-damped default",
                        what="the picker to show the preset")
        assert len(applied) == 1 and checked == [DEFAULT]
        client.set_value("Preset", "thesis Table 4.1")  # every field at once: one change
        wait_for(lambda: loop.params == PRESETS["thesis Table 4.1"], 30.0, "Table 4.1")
        assert len(applied) == 2 and checked == [DEFAULT, PRESETS["thesis Table 4.1"]]
    finally:
        lesson.gains._apply = apply


def test_unstable_gains_on_servos_are_refused_with_one_message_and_the_slider_back(
        tmp_path, monkeypatch):
    """On (emulated) servos a change to gains whose sampled loop diverges is refused by
    the loop's rule, applied once: one notification says why, the slider goes back, the
    loop keeps its gains. (A simulated arm takes them: the lab's other tests.)"""
    from armlab.app.lab.server import Lab, ServeOptions

    with emulator(log_dir=tmp_path) as emu, \
            Lab(ServeOptions(backend="serial", port=emu.port, http_port=0)) as lab, \
            HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
        loop = loop_of(lab)
        page.wait_for(lambda: page.shows("Kv (1/s)") and loop.status.active, 60.0,
                      "the Gains tab and the arm holding")
        checked = counted_rule(monkeypatch)
        page.set_value("period (ms)", 50.0)  # Kv 5: T·Kv = 0.25, converges
        wait_for(lambda: loop.params.period == 0.05, 30.0, "a 50 ms period in the loop")
        assert checked == [loop.params]
        seen = len(page.notifications)
        page.set_value("Kv (1/s)", 50.0)  # T·Kv = 2.5: diverges even on an ideal servo
        page.wait_for(lambda: len(page.notifications) > seen, 30.0, "the refusal")
        page.wait_for(lambda: page.find("Kv (1/s)").value == pytest.approx(DEFAULT.kv), 30.0,
                      "the Kv slider put back")
        assert len(checked) == 2 and checked[1].kv == 50.0  # the rule, once, said no
        (title, body), = page.notifications[seen:]
        assert title == "Value refused"
        assert body.startswith(f"{REFUSED_ON_SERVOS}: the PD loop diverges at "
                               "T = 50 ms"), body
        assert body.endswith(f"; kept {DEFAULT.kv:g}.")
        assert loop.params.kv == DEFAULT.kv and lab.lesson.gains.params == loop.params


def test_push_from_the_run_tab_shows_its_figures_beside_the_button(lab, client):
    loop = loop_of(lab)
    client.click("Push the hand")  # the Push tab's defaults: 4 N against the line, 2 s
    wait_for(lambda: "pushing 4 N" in str(lab.lesson.status.content), 30.0,
             "the status to say pushing")

    def measured() -> list[str]:
        return [str(e.props.get("_markdown")) for e in list(client.gui.values())
                if str(e.props.get("_markdown") or "").startswith("**Measured** (push")]

    client.wait_for(lambda: len(measured()) == 2, 90.0,
                    "the push's figures beside both Push buttons")
    text = lab.lesson.push_result_run.content
    assert "push of 4 N against the line" in text and "Tp" in text and "C_f" in text
    assert loop.status.fault is None


def test_home_brings_the_arm_back_to_the_line_start_at_the_approach_speed(lab, client):
    """After a step far from it, **Home** moves the arm back to the thesis line's start,
    its command never faster than the lab's approach speed (Reset only holds it)."""
    from armlab.control.trajectory import APPROACH_SPEED

    lesson = lab.lesson
    loop = lesson.rig.loop
    wait_for(lambda: loop.status.active, 60, "the arm held")
    lesson.run_step(joint=2, step_deg=-25.0)
    step = lesson.experiment
    # the step's trajectory lasts one period: wait on its command, not on its name
    wait_for(lambda: loop.status.trajectory is None and abs(
        loop.recorder.snapshot(0.1)["q_cmd"][-1][step.joint] - step.q1) < 1e-9, 60,
        "the step done")
    start = lesson.rig.line.q[0]
    t0 = loop.status.t
    client.click("Home")
    wait_for(lambda: loop.status.trajectory is not None, 30, "the move home")
    wait_for(lambda: loop.status.trajectory is None, 60, "the arm home")
    snap = loop.recorder.snapshot(loop.status.t - t0)
    assert np.abs(snap["q_cmd"][-1] - start).max() < 1e-6
    ok = np.isfinite(snap["q_cmd"]).all(axis=1)
    speed = np.abs(np.diff(snap["q_cmd"][ok], axis=0)) / np.diff(snap["t"][ok])[:, None]
    assert speed.max() <= APPROACH_SPEED * 1.01, speed.max()


def test_the_status_names_joints_as_the_page_does(lab):
    """A fault the loop words with the model's joint names ("joint theta2") is shown with
    the page's ("θ2"), as in every other control of the lesson."""
    lesson = lab.lesson
    rig = lesson.rig
    st = replace(rig.loop.status, fault="unstable: the reference speed of joint theta2 "
                 "reached the servo's limit (4.8 rad/s); torque off (lower the gains)")
    lesson._update_status(st, rig.loop.recorder.snapshot(0.2), rig)
    shown = str(lesson.status.content)
    assert "joint θ2 reached" in shown and "theta" not in shown
