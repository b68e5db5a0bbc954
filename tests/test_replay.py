"""Save run, Open run and Export page on a served lesson (issue 36, items 2-5, the page).

A real lab (viser on a free port, the compliance lesson's loop on the wall clock) driven
by a headless client that sends what a browser sends: a run saved with the page's button
reads back with its gains, robot, commands and signals; opened again through the upload
button it plays on a ghost whose joint angles are the recorded ones; a bad file gets one
notification with the reason and the lab goes on.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import viser
from _helpers import new_page_client, settled, wait_for

from armlab.app.lessons.replay_view import chart_index, sample_at
from armlab.app.lessons.run_files import REFUSED, commands_in_record
from armlab.app.testing.wsclient import HeadlessClient
from armlab.app.viser_ext.handles import uuid_of
from armlab.control.runs import MAX_FILE_BYTES, RunFileError, read_run, run_bytes

pytestmark = pytest.mark.realtime  # a served lab whose loop runs on the wall clock

ROBOT = "receptionist_arm"


@pytest.fixture(scope="module")
def page(lab):
    """A page on the module's lab with the lesson's Files tab on it."""
    known = set(lab.server.get_clients())
    c = HeadlessClient(lab.url.replace("http://", "ws://")).connect()
    c.wait_for(lambda: c.shows("Save run") and c.shows("Open run"), what="the Files tab")
    settled(lab.server, c)
    c.handle = new_page_client(lab, known)  # type: ignore[attr-defined]  # the server's
    yield c
    c.close()


@pytest.fixture(scope="module")
def saved(lab, page):
    """(file name, bytes) of a thesis-line run saved with the page's Save run button."""
    lesson = lab.lesson
    page.click("Run thesis line")
    wait_for(lambda: lesson.experiment is not None and lesson.experiment.done, 90.0,
             "the line to end")
    page.click("Save run")
    page.wait_for(lambda: any(n.endswith(".armlab-run.zip") for n in page.downloads),
                  what="the run file's download")
    name = next(n for n in page.downloads if n.endswith(".armlab-run.zip"))
    return name, page.downloads[name]


def refusals(page: HeadlessClient) -> list[str]:
    return [body for title, body in page.notifications if title == REFUSED]


def test_saved_run_holds_gains_robot_commands_and_signals(lab, saved):
    name, data = saved
    assert re.fullmatch(rf"{ROBOT}-compliance-\d{{8}}T\d{{6}}Z\.armlab-run\.zip", name)
    run = read_run(data, robot=ROBOT)
    loop = lab.lesson.rig.loop
    assert run.robot == ROBOT and run.source == "page:compliance"
    assert run.joint_names == lab.lesson.rig.model.joint_names
    assert run.params["kp"] == loop.params.kp and run.params["k_env"] == loop.params.k_env
    assert run.lab_version
    kinds = [c["kind"] for c in run.commands]
    assert "RunTrajectory" in kinds
    line = next(c for c in run.commands if c["kind"] == "RunTrajectory")
    assert run.t[0] <= line["t"] <= run.t[-1]
    assert np.allclose(line["trajectory"]["q"], lab.lesson.rig.line.q)
    for signal in ("q", "q_cmd", "tau_ext"):
        assert run.signals[signal].shape == (len(run.t), 3)
    # the loop's rate: one row per period, from before the line's start to after its end
    assert np.allclose(np.diff(run.t), loop.params.period, rtol=1e-6)
    assert run.t[-1] - line["t"] > lab.lesson.rig.line.duration
    assert run.figures["max_error_deg"] is not None
    assert run.extra["link_lengths_cm"] == lab.lesson.rig.preset


def test_opened_run_replays_the_recorded_poses(lab, page, saved):
    name, data = saved
    run = read_run(data, robot=ROBOT)
    replay = lab.lesson.runs.replay
    page.upload("Open run", name, data)
    wait_for(lambda: replay.run is not None and len(replay.run.t) == len(run.t), 60.0,
             "the replay to open")
    page.wait_for(lambda: page.find("Replay").props.get("visible") is True,
                  what="the Replay folder")
    t = run.t - run.t[0]
    for k in (0, 1, len(t) // 3, len(t) // 2, len(t) - 2, len(t) - 1):
        page.set_value("Run time (s)", float(t[k]))
        wait_for(lambda k=k: replay.index == k, 30.0, f"the ghost at sample {k}")
        assert np.allclose(replay.ghost_q, run.signals["q"][k], rtol=0.0, atol=1e-9)
    # the line under the slider says the sample's time and angles
    shown = page.gui[uuid_of(replay.at)]
    page.wait_for(lambda: f"sample {len(t)} of {len(t)}" in shown.props.get("_markdown", ""),
                  what="the pose line on the page")
    label = run.joint_names[2].replace("theta", "θ")
    assert f"{label} {np.degrees(run.signals['q'][-1, 2]):+.1f}°" in shown.props["_markdown"]
    # between two samples: the nearest one, exactly as recorded
    k = len(t) // 4
    page.set_value("Run time (s)", float(t[k] + 0.4 * (t[k + 1] - t[k])))
    wait_for(lambda: replay.index == k, 30.0, "the ghost at the nearest sample")
    assert np.array_equal(replay.ghost_q, run.signals["q"][k])
    # the chart the page got: the recorded angles in degrees, against time from the start
    rows = chart_index(len(t))

    def chart():  # noqa: ANN202
        return next(e for e in page.gui.values() if e.kind == "GuiUplotMessage"
                    and e.props.get("title") == "Recorded angles (the run)")

    page.wait_for(lambda: chart() is not None, what="the replay chart")
    x, *ys = chart().props["data"]
    assert np.allclose(x, t[rows], atol=1e-5)
    for j, y in enumerate(ys):
        assert np.allclose(y, np.degrees(run.signals["q"][rows, j]), atol=1e-4)
    # the live arm went on meanwhile
    assert lab.lesson.rig.loop.status.running and lab.lesson.rig.loop.status.active


def test_play_moves_the_ghost_through_the_run_and_pause_stops_it(lab, page, saved):
    name, data = saved
    replay = lab.lesson.runs.replay
    if replay.run is None:
        page.upload("Open run", name, data)
        wait_for(lambda: replay.run is not None, 60.0, "the replay to open")
    page.set_value("Run time (s)", 0.0)
    wait_for(lambda: replay.index == 0, 30.0, "the ghost at the start")
    button = page.gui[uuid_of(replay.play)]
    page.click(replay.play)
    page.wait_for(lambda: button.props.get("label") == "Pause", what="Play to become Pause")
    wait_for(lambda: replay.index > 10, 60.0, "the ghost to move on")
    page.click(replay.play)
    page.wait_for(lambda: button.props.get("label") == "Play", what="Pause to become Play")
    k = replay.index
    assert np.array_equal(replay.ghost_q, replay.run.signals["q"][k])
    wait_for(lambda: float(replay.time.value) > 0.0, 5.0, "the slider moved")
    at = float(replay.time.value)
    page.wait_for(lambda: abs(page.gui[uuid_of(replay.time)].value - at) < 1e-9,
                  what="the page's slider at the paused time")
    assert replay.index == k  # paused: it stays


@pytest.mark.parametrize("bad", ["other robot", "garbage", "truncated"])
def test_a_bad_file_gets_its_message_and_the_lab_goes_on(lab, page, saved, bad):
    name, data = saved
    if bad == "other robot":
        run = read_run(data, robot=ROBOT)
        other = dataclasses.replace(run, robot="open_manipulator_x")
        content, fname = run_bytes(other), "other.armlab-run.zip"
    elif bad == "garbage":
        content, fname = b"this is not a zip file\x00\xff" * 40, "garbage.armlab-run.zip"
    else:
        content, fname = data[: len(data) // 2], "half.armlab-run.zip"
    with pytest.raises(RunFileError) as said:
        read_run(content, robot=ROBOT, name=fname)
    before = len(refusals(page))
    page.upload("Open run", fname, content)
    page.wait_for(lambda: len(refusals(page)) > before, what="the refusal")
    assert refusals(page)[before:] == [str(said.value)]
    assert lab.lesson.runs.replay.run is None or lab.lesson.runs.replay.run.robot == ROBOT
    # the lab goes on: its loop runs and the page still gets answers
    assert lab.lesson.rig.loop.status.running
    shown = lab.lesson.runs.replay.run  # (a good file of an earlier test, or none)
    page.upload("Open run", name, data)
    wait_for(lambda: (run := lab.lesson.runs.replay.run) is not None and run is not shown,
             60.0, "a good file after it")


def test_an_upload_is_opened_once_however_many_callbacks_read_it(lab, page, saved):
    """viser calls back on a pool of threads with the button, not the file: a callback
    of an earlier upload that runs late reads the newest file. That file is opened (or
    refused) once: the late call, made here as viser would make it, says nothing more."""
    name, data = saved
    runs = lab.lesson.runs
    content, fname = data[: len(data) // 3], "third.armlab-run.zip"
    before = len(refusals(page))
    page.upload("Open run", fname, content)
    page.wait_for(lambda: len(refusals(page)) > before, what="the refusal")
    client = page.handle
    runs._on_upload(viser.GuiEvent(client, client.client_id, runs.open))  # the late call
    settled(client, page)  # a notification queued by it would have arrived
    assert len(refusals(page)) == before + 1, refusals(page)[before:]
    assert refusals(page)[-1].startswith(fname)


def test_a_files_own_text_shows_as_plain_words(lab, page, saved):
    """A run file's names reach the page without markup of their own: no link, no HTML."""
    name, data = saved
    run = read_run(data, robot=ROBOT)
    hostile = dataclasses.replace(run, source="[click](https://example.com) <img src=x>",
                                  params={**run.params, "<b>kp</b>": "*bold* `code`"})
    page.upload("Open run", "[odd] <name>.zip", run_bytes(hostile))
    replay = lab.lesson.runs.replay
    wait_for(lambda: replay.run is not None and replay.run.source == hostile.source, 60.0,
             "the file replayed")
    text = replay.about.content
    assert "click(https://example.com)" in text and "odd" in text
    assert not set("[]<>`") & set(text)


def test_a_run_of_other_joints_is_refused(lab, page, saved):
    """Same robot name, other joints (another chain of a URDF): refused, not replayed."""
    name, data = saved
    run = read_run(data, robot=ROBOT)
    renamed = dataclasses.replace(run, joint_names=("a", "b", "c"))
    before = len(refusals(page))
    page.upload("Open run", "renamed.armlab-run.zip", run_bytes(renamed))
    page.wait_for(lambda: len(refusals(page)) > before, what="the refusal")
    assert refusals(page)[-1].startswith("renamed.armlab-run.zip: its joints (a, b, c)")
    assert lab.lesson.runs.replay.run is None or lab.lesson.runs.replay.run.joint_names \
        == run.joint_names


def test_a_file_over_the_limit_is_refused_before_it_is_kept(lab, page):
    before = len(refusals(page))
    acks = page.counts["FileTransferPartAck"]
    page.upload("Open run", "huge.armlab-run.zip", b"x" * 1024, declared=MAX_FILE_BYTES + 1)
    page.wait_for(lambda: len(refusals(page)) > before, what="the refusal")
    page.wait_for(lambda: page.counts["FileTransferPartAck"] > acks,
                  what="the page's progress bar ended")
    assert "MiB" in refusals(page)[-1] and "huge" in refusals(page)[-1]
    # parts that add up to more than the page declared: dropped at the one that overflows
    before = len(refusals(page))
    page.upload("Open run", "liar.armlab-run.zip", b"y" * 4096, part_bytes=1024, declared=2048)
    page.wait_for(lambda: len(refusals(page)) > before, what="the refusal of the liar")
    assert lab.server.gui._current_file_upload_states == {}  # nothing kept of either


def test_export_page_downloads_the_run_as_one_html_file(lab, page, saved):
    page.click("Export page")
    page.wait_for(lambda: any(n.endswith(".html") for n in page.downloads),
                  what="the exported page")
    name = next(n for n in page.downloads if n.endswith(".html"))
    assert re.fullmatch(rf"{ROBOT}-compliance-\d{{8}}T\d{{6}}Z\.html", name)
    html = page.downloads[name].decode()
    assert html.lstrip().lower().startswith("<!doctype html")
    assert ROBOT in html


def test_sample_at_picks_the_nearest_sample():
    t = np.array([0.0, 0.016, 0.032, 0.048])
    assert [sample_at(t, x) for x in (-1.0, 0.0, 0.007, 0.008, 0.009, 0.05, 9.0)] == \
        [0, 0, 0, 0, 1, 3, 3]


def test_a_command_posted_the_period_before_the_records_first_sample_is_in_the_run():
    """A command is stamped with the loop's last period and applied at the next: one
    posted at once to a new hand (status at 0.001, first sample at 0.002) is the run's;
    one whose period the record no longer holds is not."""
    t = 0.001 * np.arange(2, 50)
    posted = [{"t": 0.0, "kind": "old"}, {"t": 0.001, "kind": "CloseHand"},
              {"t": 0.010, "kind": "OpenHand"}]
    assert [c["kind"] for c in commands_in_record(posted, t)] == ["CloseHand", "OpenHand"]
    assert [c["kind"] for c in commands_in_record(posted, t[:2])] == ["CloseHand", "OpenHand"]


def test_a_students_private_arm_saves_and_replays_its_own_run():
    """In a classroom a student's "My arm" runs in the class's worker process; its page's
    Save run holds that arm's record (the server's mirror of it), and Open run replays on
    that page only, with no "only the presenter" refusal for the page's own upload."""
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        before = set(lab.server.get_clients())
        with HeadlessClient(lab.local_url.replace("http://", "ws://")).connect() as page:
            page.wait_for(lambda: bool(set(lab.server.get_clients()) - before), 60.0,
                          what="the client")
            (cid,) = set(lab.server.get_clients()) - before
            page.wait_for(lambda: page.shows("View"), 60.0, what="the View switch")
            page.set_value("View", "My arm")
            wait_for(lambda: lab.room.private_lesson(cid) is not None, 60.0, "My arm")
            mine = lab.room.private_lesson(cid)
            loop = mine.rig.loop
            assert loop is not lab.lesson.rig.loop
            assert type(loop).__name__ == "RemoteLoop"  # the worker process's arm
            wait_for(lambda: loop.status.running and loop.status.t > 0.3, 60.0, "its loop")
            page.wait_for(lambda: page.shows("Save run"), 60.0, what="its Files tab")
            mine.run_step()
            wait_for(lambda: mine.measured_pd is not None, 90.0, "the step measured")
            page.click(mine.runs.save)
            page.wait_for(lambda: any(n.endswith(".armlab-run.zip") for n in page.downloads),
                          60.0, what="the student's run file")
            name = next(n for n in page.downloads if n.endswith(".armlab-run.zip"))
            run = read_run(page.downloads[name], robot=ROBOT)
            assert [c["kind"] for c in run.commands][:1] == ["RunTrajectory"]
            assert run.figures["overshoot_pct"] == mine.run_figures()["overshoot_pct"]
            assert run.params["kp"] == loop.params.kp
            assert run.t[0] <= run.commands[0]["t"] <= run.t[-1]
            refused, told = lab.roles.refused, len(page.notifications)
            page.upload(mine.runs.open, name, page.downloads[name])
            replay = mine.runs.replay
            wait_for(lambda: replay.run is not None, 60.0, "the student's replay")
            k = len(run.t) // 2
            page.set_value(replay.time, float(run.t[k] - run.t[0]))
            wait_for(lambda: replay.index == k, 30.0, "the ghost at the middle sample")
            assert np.allclose(replay.ghost_q, run.signals["q"][k], rtol=0.0, atol=1e-9)
            assert lab.lesson.runs.replay.run is None  # the shared lesson shows none
            assert lab.roles.refused == refused
            assert not [t for t, _ in page.notifications[told:] if "presenter" in t.lower()]


def test_the_arm_lesson_saves_and_replays_too():
    """The any-arm lesson (the SO-101 here) has the same Files tab: the push saved as its
    run, which replays on its own ghost."""
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, robot="so101")) as lab, \
            HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
        lesson = lab.lesson
        assert lab.lesson_name == "arm"
        page.wait_for(lambda: page.shows("Save run"), 60.0, what="the Files tab")
        wait_for(lambda: lesson.loop.status.active, 60.0, "the arm holding")
        slider = lesson.sliders[1]
        page.set_value(slider, float(slider.value) + 10.0)
        wait_for(lambda: any(c["kind"] == "RunTrajectory" for c in lesson.runs.commands),
                 30.0, "the move posted")
        lesson.controls.push()
        wait_for(lambda: lesson.loop.status.t > lesson.runs.commands[-1]["t"] + 0.5, 30.0,
                 "half a second of the push recorded")
        page.click("Save run")
        page.wait_for(lambda: any(n.endswith(".armlab-run.zip") for n in page.downloads),
                      60.0, what="the run file")
        name = next(n for n in page.downloads if n.endswith(".armlab-run.zip"))
        assert name.startswith("so101-arm-")
        run = read_run(page.downloads[name], robot="so101")
        # the push is a run of its own (the Push tab's figures with it): the file holds it,
        # with the slider's move before it when the push came while the move still played
        kinds = [c["kind"] for c in run.commands]
        assert kinds in (["Push"], ["RunTrajectory", "Push"]), kinds
        assert run.joint_names == lesson.model.joint_names
        page.upload("Open run", name, page.downloads[name])
        replay = lesson.runs.replay
        wait_for(lambda: replay.run is not None, 60.0, "the replay")
        k = len(run.t) - 1
        page.set_value("Run time (s)", float(run.t[k] - run.t[0]))
        wait_for(lambda: replay.index == k, 30.0, "the ghost at the last sample")
        assert np.allclose(replay.ghost_q, run.signals["q"][k], rtol=0.0, atol=1e-9)
        with pytest.raises(RunFileError) as said:
            read_run(run_bytes(dataclasses.replace(run, robot=ROBOT)), robot="so101",
                     name="thesis.armlab-run.zip")
        page.upload("Open run", "thesis.armlab-run.zip",
                    run_bytes(dataclasses.replace(run, robot=ROBOT)))
        page.wait_for(lambda: str(said.value) in refusals(page), what="the other robot refused")


@pytest.mark.browser
@pytest.mark.timeout(600)
def test_in_chromium_save_run_downloads_and_open_run_replays(browser, lab, tmp_path):
    """What a person does: Save run downloads the file; choosing it in Open run's file
    dialog replays it; a file that is not a run gets its message on the page."""
    pg = browser.new_page(viewport={"width": 1440, "height": 900}, accept_downloads=True)
    try:
        pg.goto(lab.url)
        pg.get_by_role("tab", name="Files", exact=True).click(timeout=300_000)
        with pg.expect_download(timeout=120_000) as info:
            pg.get_by_role("button", name="Save run").click()
        path = tmp_path / info.value.suggested_filename
        info.value.save_as(path)
        assert path.name.startswith(f"{ROBOT}-compliance-") and path.name.endswith(".zip")
        run = read_run(path, robot=ROBOT)
        replay = lab.lesson.runs.replay
        replay.close_run()
        pg.locator("input[type=file]").first.set_input_files(str(path))
        wait_for(lambda: replay.run is not None and len(replay.run.t) == len(run.t), 120.0,
                 "the chosen file replayed")
        assert np.array_equal(replay.ghost_q, run.signals["q"][0])
        pg.get_by_text("Recorded angles (the run)").first.wait_for(timeout=120_000)
        bad = tmp_path / "notes.armlab-run.zip"
        bad.write_bytes(b"my notes, not a run")
        pg.locator("input[type=file]").first.set_input_files(str(bad))
        pg.get_by_text(REFUSED).first.wait_for(timeout=120_000)
        assert lab.lesson.rig.loop.status.running
    finally:
        pg.close()
