"""The hand's contact force in the control loop's per-period record, and in run files.

The loop records ``f_contact`` (N, the wall's normal force on the hand at the period) and
``f_contact_peak`` (N, the largest at any plant step since the period before) when its
backend's world holds a wall (the simulated arm's :class:`~armlab.control.backend.Touchable`),
NaN otherwise; an arm started again (a challenge's restart) meets the same wall. A run
file holds them as one column each, in version 3; files of versions 1 and 2, written
before the contact force was recorded, still read.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from armlab.app.arm.backends import make_backend
from armlab.control.commands import Reset, RunTrajectory
from armlab.control.experiments.contact import contact_plan, recorded_contact
from armlab.control.loop import ControlLoop
from armlab.control.params import DEFAULT
from armlab.control.recorder import CONTACT_SIGNALS, SIGNALS
from armlab.control.restart import RestartableArm
from armlab.control.runs import Run, RunFileError, read_run, run_bytes, run_from_snapshot
from armlab.kinematics.catalog import load_robot

ARM = load_robot("receptionist_arm")
PERIOD = DEFAULT.period


def wall_run(backend, *, periods: int | None = None) -> dict[str, np.ndarray]:  # noqa: ANN001
    """The experiment's plan into a wall 4 cm ahead (2 cm of command behind it) on
    ``backend``, recorded by the loop: its snapshot."""
    run = contact_plan(ARM, PERIOD, wall=0.04, depth=0.02)
    backend.set_wall(run.origin, run.normal, stiffness=2e4, damping=50.0)
    loop = ControlLoop(ARM, backend, DEFAULT, realtime=False, history_s=30.0)
    loop.post(RunTrajectory(run.plan, approach=False))
    for _ in range(periods or run.periods):
        loop.step()
    assert loop.status.fault is None
    return loop.recorder.snapshot()


def test_the_loop_records_the_walls_force_every_period_and_nan_without_a_wall():
    backend = make_backend("sim", ARM, q0=contact_plan(ARM, PERIOD, wall=0.04,
                                                       depth=0.02).plan.q[0])
    snap = wall_run(backend)
    force, peak = snap["f_contact"], snap["f_contact_peak"]
    assert force.shape == peak.shape == snap["t"].shape  # one value a period
    assert np.all(np.isfinite(force)) and np.all(force >= 0.0)
    assert np.all(peak >= force - 1e-12)  # the peak of the steps up to the period
    assert force[0] == 0.0 and force.max() > 1.0  # free at first, then pressed
    # the record is what the plant says at the period (its ground truth)
    assert force[-1] == pytest.approx(backend.wall_force(), abs=1e-9)
    fig = recorded_contact(snap)
    assert fig["touched"] and fig["peak_force_n"] == pytest.approx(float(peak.max()))
    # the same arm without a wall: nothing to record (NaN, as on servos)
    backend.set_wall(None, stiffness=2e4, damping=50.0)
    loop = ControlLoop(ARM, backend, DEFAULT, realtime=False)
    loop.run_for(0.2)
    snap = loop.recorder.snapshot()
    assert np.all(np.isnan(snap["f_contact"])) and np.all(np.isnan(snap["f_contact_peak"]))
    assert set(run_from_snapshot(snap, robot=ARM.name, joint_names=ARM.joint_names,
                                 source="test", params={}).signals).isdisjoint(CONTACT_SIGNALS)


@pytest.mark.slow
def test_a_restarted_arm_meets_the_same_wall_and_records_the_same_force():
    """A challenge's restart makes a fresh simulated arm: the wall is the world's, so it is
    carried over, and the same plan from the restart records the same force, row for
    row."""
    run = contact_plan(ARM, PERIOD, wall=0.04, depth=0.02)
    q0 = run.plan.q[0]
    arm = RestartableArm(lambda q: make_backend("sim", ARM, q0=q), q0, period=PERIOD)
    arm.set_wall(run.origin, run.normal, stiffness=2e4, damping=50.0)
    loop = ControlLoop(ARM, arm, DEFAULT, realtime=False, history_s=30.0)
    records = []
    for _ in range(2):
        number = arm.restart(q0, [(0, RunTrajectory(run.plan, approach=False))], loop.post)
        loop.post(Reset())
        while arm.restarts < number:
            loop.step()
        t0 = arm.restarted_at
        for _ in range(run.periods + 2):
            loop.step()
        snap = loop.recorder.snapshot()
        rows = snap["t"] >= t0
        assert arm.wall_setting() is not None
        records.append(snap["f_contact_peak"][rows][:run.periods + 2])
    assert records[0].max() > 1.0
    assert np.array_equal(records[0], records[1])


def contact_sample(m: int = 40) -> Run:
    rng = np.random.default_rng(3)
    q = rng.normal(size=(m, ARM.n))
    force = np.abs(rng.normal(size=(m, 1)))
    force[0] = np.nan  # a period before the wall was placed
    return Run(robot=ARM.name, joint_names=ARM.joint_names, source="test:contact",
               lab_version="0.1.0", created="2026-12-02T12:00:00Z", params={"kp": 20.0},
               commands=(), figures={"peak_force_n": 3.5}, t=np.arange(m) * PERIOD,
               signals={"q": q, "f_contact": force, "f_contact_peak": force * 1.5})


def test_a_run_file_holds_the_contact_force_as_one_column_each_in_version_3():
    run = contact_sample()
    data = run_bytes(run)
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        meta = json.loads(zf.read("run.json"))
        header = zf.read("signals.csv").decode().splitlines()[0].split(",")
    assert meta["version"] == 3 == run.version
    assert meta["units"]["f_contact"] == meta["units"]["f_contact_peak"] == "N"
    assert header[-2:] == ["f_contact", "f_contact_peak"]
    back = read_run(data, robot=ARM.name)
    for name in ("q", *CONTACT_SIGNALS):
        assert np.array_equal(back.signals[name], run.signals[name], equal_nan=True), name
    assert back.signals["f_contact"].shape == (len(run.t), 1)


def old_file(version: int) -> bytes:
    """A run file as armlab wrote it before the contact force was recorded: version 1 (the
    recorder's signals) or 2 (with a lesson signal), no contact columns."""
    joints = list(ARM.joint_names)
    signals = ["q", "tau_ext"] + (["current"] if version == 2 else [])
    columns = ["t"] + [f"{s}.{j}" for s in signals for j in joints]
    meta = {"format": "armlab-run", "version": version, "robot": ARM.name,
            "joint_names": joints, "source": "page:compliance", "lab_version": "0.1.0",
            "created": "2026-11-28T03:00:00Z", "params": {"kp": 20.0}, "commands": [],
            "figures": {}, "extra": {},
            "units": {"t": "s", "q": "rad", "tau_ext": "N·m",
                      **({"current": "A"} if version == 2 else {})},
            "columns": columns}
    if version == 2:
        meta["lesson_signals"] = {"current": "A"}
    rows = [",".join(["t", *columns[1:]])]
    for k in range(5):
        rows.append(",".join([repr(k * PERIOD)] + ["0.25"] * (len(columns) - 1)))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("run.json", json.dumps(meta))
        zf.writestr("signals.csv", "\n".join(rows) + "\n")
    return buf.getvalue()


@pytest.mark.parametrize("version", [1, 2])
def test_an_old_run_file_without_the_contact_force_still_reads(version):
    run = read_run(old_file(version), robot=ARM.name)
    assert set(run.signals).isdisjoint(CONTACT_SIGNALS)
    assert run.signals["q"].shape == (5, ARM.n) and run.version == version
    assert np.all(run.signals["tau_ext"] == 0.25)


def test_a_contact_column_named_per_joint_or_a_lesson_signal_of_its_name_is_refused():
    data = run_bytes(contact_sample())
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        meta, csv = json.loads(zf.read("run.json")), zf.read("signals.csv").decode()
    meta["columns"] = [c if c != "f_contact" else "f_contact.theta1" for c in meta["columns"]]
    csv = csv.replace("f_contact,", "f_contact.theta1,", 1)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("run.json", json.dumps(meta))
        zf.writestr("signals.csv", csv)
    with pytest.raises(RunFileError, match="one column named 'f_contact'"):
        read_run(buf.getvalue())
    with pytest.raises(RunFileError, match="cannot name a lesson signal"):
        run_bytes(Run(**{**contact_sample().__dict__, "lesson_signals": {"f_contact": "N"}}))
    assert not set(CONTACT_SIGNALS) & set(SIGNALS)


def test_a_restart_can_name_the_wall_its_fresh_arm_meets_leaving_the_old_arm_free():
    """A contact challenge's wall is put into the restarted arm's world only: the arm in
    use, whose hand may be behind that wall, never meets it (no impossible force in the
    record before the restart)."""
    from armlab.control.backend import WallSetting

    run = contact_plan(ARM, PERIOD, wall=0.04, depth=0.02)
    q0 = run.plan.q[0]
    arm = RestartableArm(lambda q: make_backend("sim", ARM, q0=q), q0, period=PERIOD)
    loop = ControlLoop(ARM, arm, DEFAULT, realtime=False, history_s=30.0)
    loop.run_for(0.1)
    arm.meet_wall(WallSetting(run.origin, run.normal, 2e4, 50.0))
    assert arm.wall_setting() is None  # not yet: the old arm goes on without it
    number = arm.restart(q0, [(0, RunTrajectory(run.plan, approach=False))], loop.post)
    loop.post(Reset())
    while arm.restarts < number:
        loop.step()
    wall = arm.wall_setting()
    assert wall is not None and wall.stiffness == 2e4
    assert np.allclose(wall.origin, run.origin) and np.allclose(wall.normal, run.normal)
    snap = loop.recorder.snapshot()
    before = snap["t"] < arm.restarted_at
    assert np.all(np.isnan(snap["f_contact"][before]))
    for _ in range(run.periods + 2):
        loop.step()
    snap = loop.recorder.snapshot()
    assert np.nanmax(snap["f_contact_peak"]) > 1.0


def test_a_contact_column_in_a_file_of_an_older_version_is_refused():
    data = run_bytes(contact_sample())
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        meta, csv = json.loads(zf.read("run.json")), zf.read("signals.csv")
    meta["version"] = 2
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("run.json", json.dumps(meta))
        zf.writestr("signals.csv", csv)
    with pytest.raises(RunFileError, match="only version 3 holds"):
        read_run(buf.getvalue())
