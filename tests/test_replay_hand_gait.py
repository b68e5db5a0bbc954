"""Save run, Open run and Export page in the hand and quadruped lessons (issue 36).

A real lab (viser on a free port, the lesson's loop on the wall clock) driven by a headless
client sending what a browser sends: a grasp saved with the page's Save run reads back
with its robot, commands and the hand's own signals (voltage, current, force, ...); a
quadruped's walk with the goals and the angles the simulated servos read (finite); opened
again through Open run each plays on its ghost at the recorded angles; Export page gives
one HTML page. In a classroom a student's private hand and quadruped do the same.
The run format's lesson signals (a run's own named per-joint signals with declared units)
are checked first.
"""

from __future__ import annotations

import dataclasses
import io
import json
import re
import zipfile

import numpy as np
import pytest
from _helpers import my_arm_in, wait_for

from armlab.app.lessons.hand import RUN_SIGNALS
from armlab.app.testing.wsclient import HeadlessClient
from armlab.control.grip_loop import COLUMNS
from armlab.control.runs import Run, RunFileError, read_run, run_bytes

#: served labs whose loops run on the wall clock
served = pytest.mark.realtime


# ------------------------------------------------------------------ the format


def _hand_run(**changes: object) -> Run:
    t = np.arange(5) * 1e-3
    q = np.linspace(-0.35, 0.2, 15).reshape(5, 3)
    run = Run(robot="hand", joint_names=("finger1", "finger2", "finger3"), source="test",
              lab_version="0", created="2026-11-28T04:00:00Z", params={"force_limit": 0.8},
              commands=({"t": 0.0, "kind": "CloseHand"},), figures={}, t=t,
              signals={"current": q * 0.1 + 5e-324, "q": q, "force": np.full((5, 3), np.nan)},
              lesson_signals={"current": "A", "force": "N"})
    return dataclasses.replace(run, **changes)


def _members(data: bytes) -> tuple[dict, str]:
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return json.loads(z.read("run.json")), z.read("signals.csv").decode()


def _rezip(meta: dict, csv_text: str) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("run.json", json.dumps(meta))
        z.writestr("signals.csv", csv_text)
    return buf.getvalue()


def test_lesson_signals_are_columns_with_declared_units_and_read_back_exactly():
    run = _hand_run()
    meta, text = _members(run_bytes(run))
    assert meta["version"] == 2
    assert meta["lesson_signals"] == {"current": "A", "force": "N"}
    assert meta["units"] == {"t": "s", "q": "rad", "current": "A", "force": "N"}
    assert text.splitlines()[0] == ("t,q.finger1,q.finger2,q.finger3,current.finger1,"
                                    "current.finger2,current.finger3,force.finger1,"
                                    "force.finger2,force.finger3")
    back = read_run(run_bytes(run), robot="hand")
    assert back.lesson_signals == run.lesson_signals
    assert list(back.signals) == ["q", "current", "force"]
    for name, values in run.signals.items():
        assert np.array_equal(back.signals[name], values, equal_nan=True)


def test_a_run_without_lesson_signals_is_written_as_version_1_as_before():
    run = _hand_run(signals={"q": _hand_run().signals["q"]}, lesson_signals={})
    meta, _ = _members(run_bytes(run))
    assert meta["version"] == 1 and "lesson_signals" not in meta


@pytest.mark.parametrize("bad", [
    {"lesson_signals": {"q": "rad"}},  # a recorder signal's name
    {"lesson_signals": {"Current": "A"}},  # not lower case
    {"lesson_signals": {"current": "A" * 17}},  # too long a unit
    {"lesson_signals": {"current": "A", "cap": "N"}},  # declared, no columns
])
def test_a_bad_lesson_signal_is_refused_on_save(bad):
    run = _hand_run()
    if "q" in bad["lesson_signals"]:
        run = dataclasses.replace(run, signals={"q": run.signals["q"]})
    elif "Current" in bad["lesson_signals"]:
        run = dataclasses.replace(run, signals={"q": run.signals["q"],
                                                "Current": run.signals["current"]})
    with pytest.raises(RunFileError):
        run_bytes(dataclasses.replace(run, **bad))


def test_a_column_no_one_declared_is_refused_on_read():
    meta, text = _members(run_bytes(_hand_run()))
    del meta["lesson_signals"]["force"]
    with pytest.raises(RunFileError, match="'force.finger1' is no signal"):
        read_run(_rezip(meta, text))
    meta["lesson_signals"] = ["current"]
    with pytest.raises(RunFileError, match="lesson_signals"):
        read_run(_rezip(meta, text))


# ------------------------------------------------------------------ the lessons


def _saved(page: HeadlessClient, button: object, suffix: str = ".armlab-run.zip"
           ) -> tuple[str, bytes]:
    """Press ``button`` and wait for the download it sends: (name, bytes)."""
    before = set(page.downloads)
    page.click(button)
    page.wait_for(lambda: any(n.endswith(suffix) for n in set(page.downloads) - before), 60.0,
                  what=f"the {suffix} download")
    name = next(n for n in set(page.downloads) - before if n.endswith(suffix))
    return name, page.downloads[name]


def _replays_the_recorded_poses(page: HeadlessClient, runs: object, name: str,
                                data: bytes) -> None:
    """Open ``data`` with ``runs``' Open run; the ghost shows the recorded angles of the
    first, middle and last samples (to 1e-9)."""
    run = read_run(data)
    page.upload(runs.open, name, data)
    replay = runs.replay
    wait_for(lambda: replay.run is not None and len(replay.run.t) == len(run.t), 60.0,
             "the run replayed")
    for k in (0, len(run.t) // 2, len(run.t) - 1):
        page.set_value(replay.time, float(run.t[k] - run.t[0]))
        wait_for(lambda k=k: replay.index == k, 30.0, f"the ghost at sample {k}")
        assert np.allclose(replay.ghost_q, run.signals["q"][k], rtol=0.0, atol=1e-9)


def _check_hand_run(run, lesson) -> None:  # noqa: ANN001
    assert run.robot == "hand" and run.joint_names == ("finger1", "finger2", "finger3")
    assert run.lesson_signals == RUN_SIGNALS
    assert run.lesson_signals["current"] == COLUMNS["current"] == "A"
    for name in ("q", *RUN_SIGNALS):
        assert run.signals[name].shape == (len(run.t), 3)
    kinds = [c["kind"] for c in run.commands]
    assert "CloseHand" in kinds
    assert run.params["force_limit"] == lesson.loop.params.force_limit
    # the fingers closed on the object: they turned, and pushed with about F
    assert np.ptp(run.signals["q"], axis=0).min() > 0.05
    assert run.signals["force"].max() > 0.5 * lesson.loop.params.force_limit
    assert np.isfinite(run.signals["current"]).all()


def _check_quadruped_run(run, lesson) -> None:  # noqa: ANN001
    assert run.robot == "quadruped" and len(run.joint_names) == 12
    assert run.joint_names[:3] == lesson.model.legs["RF"].joint_names
    assert np.isfinite(run.signals["q"]).all()  # the simulated servos' own readings
    assert "q_is" not in run.extra
    assert "Walk" in [c["kind"] for c in run.commands]
    assert run.params["gait"] == lesson.spec.gait and run.params["D_m"] == lesson.spec.params.D
    # the servos moved, and followed the goals (not a copy of them)
    assert np.ptp(run.signals["q"], axis=0).max() > 0.1
    goals = run.signals["q_cmd"]
    both = np.isfinite(goals).all(axis=1)
    assert not np.array_equal(goals[both], run.signals["q"][both])
    assert np.abs(goals[both] - run.signals["q"][both]).mean() < 0.1


def _walk(page: HeadlessClient, lesson) -> None:  # noqa: ANN001
    page.click(lesson.direction_buttons["forward"])
    wait_for(lambda: lesson.loop.status.walking, 60.0, "the robot walking")
    t0 = lesson.loop.status.t
    wait_for(lambda: lesson.loop.status.t > t0 + 2.0, 60.0, "two seconds of walking")


def _grasp(page: HeadlessClient, lesson) -> None:  # noqa: ANN001
    page.click(lesson.close_button)
    wait_for(lambda: set(lesson.loop.status.modes) == {"holding"}, 60.0, "the hand holding")
    t0 = lesson.loop.status.t
    wait_for(lambda: lesson.loop.status.t > t0 + 0.3, 30.0, "the grasp held a moment")


@served
def test_the_hand_lesson_saves_replays_and_exports_a_grasp():
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, lesson="hand")) as lab, \
            HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
        lesson = lab.lesson
        page.wait_for(lambda: page.shows("Save run") and page.shows("Open run"), 60.0,
                      what="the Files folder")
        _grasp(page, lesson)
        name, data = _saved(page, lesson.runs.save)
        assert re.fullmatch(r"hand-hand-\d{8}T\d{6}Z\.armlab-run\.zip", name)
        run = read_run(data, robot="hand")
        _check_hand_run(run, lesson)
        _replays_the_recorded_poses(page, lesson.runs, name, data)
        assert lesson.runs.replay.ghost.joint_names == run.joint_names
        html_name, html = _saved(page, lesson.runs.export, ".html")
        assert html_name.startswith("hand-hand-")
        text = html.decode()
        assert text.lstrip().lower().startswith("<!doctype html")
        assert "finger1" in text and "current (A)" in text and "CloseHand" in text
        assert lesson.loop.status.running  # the lab went on


@served
def test_the_quadruped_lesson_saves_measured_angles_replays_and_exports_a_walk():
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, robot="quadruped")) as lab, \
            HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
        lesson = lab.lesson
        assert lab.lesson_name == "quadruped"
        page.wait_for(lambda: page.shows("Save run"), 60.0, what="the Files tab")
        _walk(page, lesson)
        name, data = _saved(page, lesson.runs.save)
        assert re.fullmatch(r"quadruped-quadruped-\d{8}T\d{6}Z\.armlab-run\.zip", name)
        run = read_run(data, robot="quadruped")
        _check_quadruped_run(run, lesson)
        _replays_the_recorded_poses(page, lesson.runs, name, data)
        ghost = lesson.runs.replay.ghost
        assert ghost.view.root.position[2] == pytest.approx(run.params["D_m"])
        _, html = _saved(page, lesson.runs.export, ".html")
        text = html.decode()
        assert text.lstrip().lower().startswith("<!doctype html")
        assert "RF_hip_yaw" in text and "Walk" in text


@served
@pytest.mark.timeout(900)
def test_a_students_private_hand_and_quadruped_save_and_replay_their_own_runs():
    """In a classroom a student's hand and quadruped run in the class's worker process;
    their page's Save run holds that robot's record (the server's mirror of it), and Open
    run replays on that page only."""
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        before = set(lab.server.get_clients())
        with HeadlessClient(lab.local_url.replace("http://", "ws://")).connect() as page:
            page.wait_for(lambda: bool(set(lab.server.get_clients()) - before), 60.0,
                          what="the client")
            (cid,) = set(lab.server.get_clients()) - before
            mine = my_arm_in(lab, page, cid, "hand")
            assert type(mine.loop).__name__ == "RemoteHand"
            _grasp(page, mine)
            name, data = _saved(page, mine.runs.save)
            _check_hand_run(read_run(data, robot="hand"), mine)
            _replays_the_recorded_poses(page, mine.runs, name, data)
            assert lab.lesson.runs.replay.run is None  # the shared lesson shows none

            mine = my_arm_in(lab, page, cid, "quadruped")
            assert type(mine.loop).__name__ == "RemoteGait"
            _walk(page, mine)
            name, data = _saved(page, mine.runs.save)
            _check_quadruped_run(read_run(data, robot="quadruped"), mine)
            _replays_the_recorded_poses(page, mine.runs, name, data)
            assert lab.lesson.runs.replay.run is None
