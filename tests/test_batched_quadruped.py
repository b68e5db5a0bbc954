"""The batched quadrupeds equal N ``QuadrupedSimBackend``: q, qd to 1e-9, reports exactly."""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest
from _helpers import wait_for

from armlab.control.backend import BackendError
from armlab.control.gait_loop import GaitLoop
from armlab.control.periodic import SharedClock
from armlab.control.walking import GaitSpec, Walker, plan_gait
from armlab.hardware.families.dynamixel1.batched_quadruped import (
    BatchedQuadrupedBackend,
    BatchedQuadrupeds,
    leg_groups,
    same_dynamics,
)
from armlab.hardware.families.dynamixel1.quadruped import G, QuadrupedSimBackend, total_mass
from armlab.hardware.servos.servo_spec import AX12A, RX24F
from armlab.kinematics.body_statics import (
    contact_forces,
    feet_and_com,
    feet_and_coms,
    floor_forces,
    implied_tilt_deg,
    implied_tilts_deg,
    rest_plane,
    rest_planes,
)
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import Quadruped

MODEL = load_robot("quadruped")
DT = 2e-3  #: the lesson's SIM_DT
PERIOD = 0.02  #: the lesson's gait-loop period
Q0 = Walker(plan_gait(GaitSpec())).state().q  # standing, feet on the floor
N = 4
#: per robot: its start offset from Q0 (12,) rad
OFFSETS = [np.zeros(12), np.full(12, 0.03), np.tile([0.05, -0.04, 0.06], 4),
           np.linspace(-0.05, 0.05, 12)]


def _goal(i: int, t: float) -> np.ndarray:
    """Robot i's goals at t s: a different slow sway per robot, rad."""
    phase = np.arange(12) * 0.4 + i
    return Q0 + (0.04 + 0.02 * i) * np.sin(2 * np.pi * (0.7 + 0.3 * i) * t + phase)


def _speed(i: int) -> np.ndarray:
    return np.full(12, 1.0 + i)


def _same_state(a, b) -> None:  # noqa: ANN001 - two JointStates
    assert a.t == b.t
    for name in ("position", "velocity", "load"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (a.errors, a.torque_on, a.alarms) == (b.errors, b.torque_on, b.alarms)


def _batch(n: int = N, **kw: object) -> tuple[BatchedQuadrupeds, list[BatchedQuadrupedBackend]]:
    batch = BatchedQuadrupeds(MODEL, dt=DT, **kw)
    lock = threading.RLock()
    backends = [BatchedQuadrupedBackend(batch, batch.add(Q0 + OFFSETS[i]), lock=lock,
                                        drive=True) for i in range(n)]
    return batch, backends


# -- the statics over robots ---------------------------------------------------------------

def test_the_statics_over_robots_equal_body_statics_per_robot() -> None:
    rng = np.random.default_rng(7)
    q = Q0 + rng.normal(0.0, 0.08, (60, 12))
    q[:5, 4] += 0.6  # LF lifted: three feet
    feet, com = feet_and_coms(MODEL, [q[:, 3 * k:3 * k + 3] for k in range(4)])
    n, d, contact, ok = rest_planes(feet, com)
    weight = rng.uniform(5.0, 15.0, 60)
    f = floor_forces(feet, com, weight, n, contact)
    assert ok.all() and {3, 4} <= set(contact.sum(axis=1).tolist())
    for r in range(60):
        feet_r, com_r = feet_and_com(MODEL, q[r])
        np.testing.assert_allclose(feet[r], feet_r, rtol=0, atol=1e-15)
        np.testing.assert_allclose(com[r], com_r, rtol=0, atol=1e-15)
        n_r, d_r, contact_r = rest_plane(feet_r, com_r)
        np.testing.assert_allclose(n[r], n_r, rtol=0, atol=1e-14)
        assert d[r] == pytest.approx(d_r, abs=1e-14)
        assert contact[r].tolist() == contact_r.tolist()
        want = np.zeros(4)
        want[contact_r] = contact_forces(feet_r[contact_r], com_r, weight[r], n_r)
        np.testing.assert_allclose(f[r], want, rtol=0, atol=1e-12)
    # the tilts the lesson's servo tab shows (seed 003: 3.6-5.7° on flat ground), all at once
    tilts = implied_tilts_deg(MODEL, q)
    np.testing.assert_allclose(tilts, [implied_tilt_deg(MODEL, qr) for qr in q],
                               rtol=0, atol=1e-9)
    assert implied_tilts_deg(MODEL, np.zeros((0, 12))).shape == (0,)


def test_fewer_than_three_contacts_share_as_contact_forces_does() -> None:
    feet = np.array([[[0.1, -0.1, -0.1], [0.1, 0.1, -0.1], [-0.1, -0.1, -0.1],
                      [-0.1, 0.1, -0.1]]] * 3)
    com = np.array([[0.02, 0.01, 0.0]] * 3)
    n = np.array([[0.0, 0.0, 1.0]] * 3)
    contact = np.array([[True, False, False, True], [False, True, False, False],
                        [False] * 4])
    f = floor_forces(feet, com, np.array([9.0, 4.0, 3.0]), n, contact)
    np.testing.assert_allclose(f[0, [0, 3]], contact_forces(feet[0, [0, 3]], com[0], 9.0, n[0]))
    assert f[0, [1, 2]].tolist() == [0.0, 0.0]
    assert f[1].tolist() == [0.0, 4.0, 0.0, 0.0] and f[2].tolist() == [0.0] * 4


# -- the batch against separate backends ---------------------------------------------------

@pytest.mark.slow
def test_the_batch_equals_separate_quadruped_backends_over_a_second_and_a_half() -> None:
    """Different goals per robot, the body load on, robot 1 torque off at 0.3 s (its body
    sits down), robot 2 pushed on its RH foot, robot 3 dragged by a spring; every period
    q and qd of every leg agree to 1e-9 and the reports exactly."""
    singles = [QuadrupedSimBackend(MODEL, q0=Q0 + OFFSETS[i], dt=DT) for i in range(N)]
    batch, backends = _batch()
    worst = 0.0
    tilts = []
    for k in range(1, 76):
        t = PERIOD * k
        for i in range(N):
            for b in (singles[i], backends[i]):
                if k == 15 and i == 1:
                    b.set_torque(False)
                if k == 20 and i == 2:
                    b.push(np.array([1.0, -2.0, 6.0]), link=8, point=np.array([0.0, -0.1, 0.0]),
                           duration=0.25)
                if k == 25 and i == 3:
                    b.set_spring(np.array([0.05, 0.15, -0.05]), stiffness=40.0, link=4,
                                 point=np.zeros(3))
                if k == 50 and i == 3:
                    b.set_spring(None, stiffness=0.0, link=4, point=np.zeros(3))
                b.write(_goal(i, t), _speed(i))
        for b in singles + backends:  # the first backend's sync steps the whole batch
            b.sync(t)
        q_single = np.array([s.body.q() for s in singles])
        qd_single = np.array([np.concatenate([leg.plant.qd for leg in s.legs])
                              for s in singles])
        worst = max(worst, float(np.max(np.abs(batch.q - q_single))),
                    float(np.max(np.abs(batch.qd - qd_single))))
        for s, b in zip(singles, backends, strict=True):
            _same_state(s.read(), b.read())
            assert b.body.contact.tolist() == s.body.contact.tolist()
            np.testing.assert_allclose(b.body.forces, s.body.forces, rtol=0, atol=1e-9)
            assert b.body.tilt_deg == pytest.approx(s.body.tilt_deg, abs=1e-9)
        tilts.append(batch.tilt_deg)
    assert worst <= 1e-9
    assert batch.t == pytest.approx(75 * PERIOD)
    weight = total_mass(MODEL) * G
    carried = batch.forces.sum(axis=1)
    assert carried[[0, 2, 3]] == pytest.approx([weight] * 3)  # standing on their feet
    assert carried[1] == 0.0 and not batch.contact[1].any()  # torque off: sat down
    assert np.max(np.array(tilts)[:, [0, 2, 3]]) > 0.1  # the bodies tilted as they swayed
    moved = np.abs(batch.q - (Q0 + np.array(OFFSETS)))
    assert np.all(moved.max(axis=1) > 0.05)


@pytest.mark.slow
def test_adding_and_removing_a_robot_leaves_the_others_unchanged() -> None:
    """The others as a batch that never had the robot; the one added mid-run (between two
    load renewals of the others) as a fresh QuadrupedSimBackend from the step it joined."""
    ref, _ = _batch()
    batch, _ = _batch()
    lone = None
    for k in range(400):
        if k == 103:
            extra = batch.add(Q0 + 0.02, torque_on=True)
            batch.push(extra, np.array([0.0, 0.0, 4.0]), link=2, point=np.zeros(3),
                       duration=0.2)
            lone = QuadrupedSimBackend(MODEL, q0=Q0 + 0.02, dt=DT)
            lone.push(np.array([0.0, 0.0, 4.0]), link=2, point=np.zeros(3), duration=0.2)
            batch.remove(1)
            ref.remove(1)
        if lone is not None and (k - 103) % 5 == 0:
            lone.sync((k - 103) * DT)
            row = batch.row(extra)
            np.testing.assert_allclose(batch.q[row], lone.body.q(), rtol=0, atol=1e-9)
            assert batch.forces[row] == pytest.approx(lone.body.forces, abs=1e-9)
            assert batch.time_of(extra) == pytest.approx(lone.legs[0].plant.t)
        if k == 300:
            batch.remove(extra)
            lone = None
        ref.step()
        batch.step()
    assert batch.ids.tolist() == ref.ids.tolist() == [0, 2, 3]
    assert [batch.row(r) for r in (0, 2, 3)] == [0, 1, 2]
    for gone in (1, extra):
        with pytest.raises(ValueError, match="robot"):
            batch.row(gone)
    assert np.array_equal(batch.q, ref.q) and np.array_equal(batch.qd, ref.qd)
    assert np.array_equal(batch.forces, ref.forces)
    assert np.array_equal(batch.tilt_deg, ref.tilt_deg)
    for a, b in zip(batch.legs, ref.legs, strict=True):
        assert np.array_equal(a.present_position(), b.present_position())


@pytest.mark.slow
def test_bad_input_raises_and_changes_nothing() -> None:
    batch, backends = _batch(2)
    ref, ref_backends = _batch(2)
    b = backends[0]
    for bb in (b, ref_backends[0]):
        bb.write(_goal(0, 0.1), _speed(0))
    goals = [leg.register("goal_position").copy() for leg in batch.legs]
    bad_goal = _goal(0, 0.3)
    bad_goal[7] = np.nan
    with pytest.raises(ValueError, match="position"):
        b.write(bad_goal, _speed(0))
    with pytest.raises(ValueError, match="speed"):
        b.write(_goal(0, 0.3), np.full(11, 1.0))
    assert all(np.array_equal(leg.register("goal_position"), g)
               for leg, g in zip(batch.legs, goals, strict=True))
    for link in (12, -1, True, 2.0):
        with pytest.raises(ValueError, match="link"):
            b.push(np.ones(3), link=link, point=np.zeros(3), duration=0.1)
        with pytest.raises(ValueError, match="link"):
            b.set_spring(np.zeros(3), stiffness=10.0, link=link, point=np.zeros(3))
    with pytest.raises(ValueError, match="force"):
        b.push(np.array([0.0, np.inf, 0.0]), link=5, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="duration"):
        b.push(np.ones(3), link=5, point=np.zeros(3), duration=-0.1)
    with pytest.raises(ValueError, match="robot"):
        batch.push(7, np.ones(3), link=0, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="q0"):
        batch.add(np.zeros(11))
    with pytest.raises(ValueError, match="robot"):
        batch.remove(5)
    with pytest.raises(ValueError, match="dt"):
        BatchedQuadrupeds(MODEL, dt=3e-3)
    with pytest.raises(ValueError, match="Quadruped"):
        BatchedQuadrupeds(load_robot("receptionist_arm"))  # type: ignore[arg-type]
    assert batch.n_robots == 2
    for bb in backends + ref_backends:
        bb.sync(0.5)
    assert np.array_equal(batch.q, ref.q) and np.array_equal(batch.qd, ref.qd)
    _same_state(b.read(), ref_backends[0].read())
    b.close()
    with pytest.raises(BackendError):
        b.read()
    with pytest.raises(BackendError):
        b.sync(0.6)
    assert b.estop() is True  # never raises


def test_without_drive_sync_waits_for_the_clock_and_never_steps() -> None:
    """A shared clock steps the batch (headless here: ``run_for``); ``sync`` only checks."""
    batch = BatchedQuadrupeds(MODEL, dt=DT)
    clock = SharedClock(batch.step, dt=DT, realtime=False)
    b = BatchedQuadrupedBackend(batch, batch.add(Q0), lock=clock.lock, wait_s=0.0)
    single = QuadrupedSimBackend(MODEL, q0=Q0, dt=DT)
    with pytest.raises(BackendError, match="clock"):
        b.sync(0.02)
    assert batch.steps == 0
    for k in range(1, 11):
        clock.run_for(PERIOD)
        for x in (single, b):
            x.sync(PERIOD * k)
            x.write(_goal(0, PERIOD * k), _speed(0))
        _same_state(single.read(), b.read())
    assert b.t == pytest.approx(0.2) and batch.steps == 100
    clock.run_for(0.03)
    b.sync(0.21)  # a batch past the loop's time is read where it is
    assert b.read().t == pytest.approx(0.23)


@pytest.mark.slow
def test_estop_torque_off_and_on_again_as_a_quadruped_backend() -> None:
    single = QuadrupedSimBackend(MODEL, q0=Q0, dt=DT)
    batch, (b,) = _batch(1)
    for k in range(1, 60):
        for x in (single, b):
            if k == 10:
                assert x.estop() is True
            if k == 30:
                x.set_torque(True)
            x.write(Q0, np.full(12, 2.0))
            x.sync(PERIOD * k)
        _same_state(single.read(), b.read())
    assert single.body.forces.sum() == pytest.approx(total_mass(MODEL) * G)
    np.testing.assert_allclose(batch.q[0], single.body.q(), rtol=0, atol=1e-9)


# -- legs of the same dynamics share a plant -------------------------------------------------

def _leg_changed(model: Quadruped, leg: str, **change: object) -> Quadruped:
    """A copy of ``model`` whose leg ``leg`` has one thing changed: ``link_mass`` (scale of
    the knee link's mass), ``com``/``inertia`` (of the knee link), ``axis``/``origin``/
    ``lower`` (of the knee joint), or a chain field (``tip``, ``gravity``, ``base_pose``,
    ``name``)."""
    chain = model.legs[leg]
    links, joints = list(chain.links), list(chain.joints)
    for key, value in change.items():
        if key == "link_mass":
            links[2] = dataclasses.replace(links[2], mass=links[2].mass * float(value))
        elif key in ("com", "inertia"):
            links[2] = dataclasses.replace(links[2], **{key: value})
        elif key in ("axis", "origin", "lower"):
            joints[2] = dataclasses.replace(joints[2], **{key: value})
        else:
            chain = dataclasses.replace(chain, **{key: value})
    chain = dataclasses.replace(chain, links=tuple(links), joints=tuple(joints))
    return dataclasses.replace(model, legs={**model.legs, leg: chain})


def _legs_alike(model: Quadruped) -> Quadruped:
    """``model`` with every leg built as RF is (its own name and hip mount kept)."""
    rf = model.legs["RF"]
    return dataclasses.replace(model, legs={
        name: dataclasses.replace(rf, name=chain.name, base_pose=chain.base_pose)
        for name, chain in model.legs.items()})


HEAVY_RH = _leg_changed(MODEL, "RH", link_mass=1.5)
ALIKE = _legs_alike(MODEL)


def test_legs_of_the_same_dynamics_share_a_plant() -> None:
    """The lab's model: RF with RH, LF with LH, two plants of 2N arms whose rows interleave
    by join order; each robot has one arm per leg, found by robot id."""
    batch = BatchedQuadrupeds(MODEL, dt=DT)
    assert batch.groups == ((0, 2), (1, 3)) and len(batch.plants) == 2
    assert [leg.name for leg in batch.legs] == ["RF", "LF", "RH", "LH"]
    assert [leg.plant for leg in batch.legs] == [batch.plants[i] for i in (0, 1, 0, 1)]
    robots = [batch.add(Q0 + OFFSETS[i]) for i in range(3)]
    batch.remove(robots[1])
    robots[1] = batch.add(Q0 + OFFSETS[3])
    assert [p.n_arms for p in batch.plants] == [6, 6]
    assert [leg.rows.tolist() for leg in batch.legs] == [[0, 2, 4], [0, 2, 4],
                                                         [1, 3, 5], [1, 3, 5]]
    for r, robot in enumerate(batch.ids.tolist()):
        arms = batch.arms_of(robot)
        assert [p for p, _ in arms] == [leg.plant for leg in batch.legs]
        assert [p.row(a) for p, a in arms] == [leg.rows[r] for leg in batch.legs]
        assert [leg.arm(robot) for leg in batch.legs] == [a for _, a in arms]
    np.testing.assert_array_equal(batch.q, Q0 + np.array([OFFSETS[i] for i in (0, 2, 3)]))
    for k, leg in enumerate(batch.legs):
        np.testing.assert_array_equal(leg.q, batch.q[:, 3 * k:3 * k + 3])
    with pytest.raises(ValueError, match="robot"):
        batch.arms_of(7)


@pytest.mark.parametrize(("change", "same"), [
    ({"link_mass": 1.0 + 1e-12}, False), ({"com": np.array([0.0, -0.05, 1e-9])}, False),
    ({"inertia": np.diag([2.536e-05, 7.2e-07, 2.6e-05])}, False),
    ({"axis": np.array([-1.0, 0.0, 0.0])}, False),
    ({"origin": np.eye(4)}, False),
    ({"lower": -2.0}, False), ({"tip": np.eye(4)}, False),
    ({"gravity": np.array([0.0, 0.0, -9.8])}, False),
    ({"base_pose": np.eye(4)}, True), ({"name": "elsewhere"}, True), ({}, True)])
def test_same_dynamics_compares_everything_but_names_and_the_hip_mount(
        change: dict[str, object], same: bool) -> None:
    changed = _leg_changed(MODEL, "RH", **change)
    assert same_dynamics(changed.legs["RF"], changed.legs["RH"]) is same
    batch = BatchedQuadrupeds(changed, dt=DT)
    assert batch.groups == (((0, 2), (1, 3)) if same else ((0,), (1, 3), (2,)))


def test_legs_with_other_servos_or_directions_get_plants_of_their_own() -> None:
    chains = [MODEL.legs["RF"], MODEL.legs["RH"], MODEL.legs["RF"], MODEL.legs["LF"]]
    specs = [(AX12A,) * 3, (AX12A,) * 3, (AX12A, RX24F, AX12A), (AX12A,) * 3]
    dirs = [(1.0,) * 3, (1.0, -1.0, 1.0), (1.0,) * 3, (1.0,) * 3]
    assert leg_groups(chains, specs, dirs) == ((0,), (1,), (2,), (3,))
    assert leg_groups(chains, [(AX12A,) * 3] * 4, [(1,) * 3] * 4) == ((0, 1, 2), (3,))
    assert len(BatchedQuadrupeds(ALIKE, dt=DT).plants) == 1


@pytest.mark.parametrize(("model", "groups"), [
    (MODEL, ((0, 2), (1, 3))), (HEAVY_RH, ((0,), (1, 3), (2,))), (ALIKE, ((0, 1, 2, 3),))],
    ids=["lab", "heavy-RH", "alike"])
@pytest.mark.slow
def test_robots_joining_and_leaving_mid_run_match_separate_backends(
        model: Quadruped, groups: tuple[tuple[int, ...], ...]) -> None:
    """However the legs are grouped, every robot equals a ``QuadrupedSimBackend`` of the
    model started when it joined (q, qd to 1e-9, the words exactly), as robots leave and
    join between load renewals (their arms' rows in the shared plants move and
    interleave), one pushed on its RH foot and one dragged by its LF knee."""
    batch = BatchedQuadrupeds(model, dt=DT)
    assert batch.groups == groups
    assert [p.model is model.legs[list(model.legs)[g[0]]]
            for p, g in zip(batch.plants, groups, strict=True)] == [True] * len(groups)
    lock = threading.RLock()
    live: dict[int, tuple[int, int, QuadrupedSimBackend, BatchedQuadrupedBackend]] = {}

    def join(i: int) -> None:  # robot i of OFFSETS, at this step
        q0 = Q0 + OFFSETS[i]
        robot = batch.add(q0)
        live[i] = (robot, batch.steps, QuadrupedSimBackend(model, q0=q0, dt=DT),
                   BatchedQuadrupedBackend(batch, robot, lock=lock))

    def leave(i: int) -> None:
        robot, _, _, backend = live.pop(i)
        backend.close()
        batch.remove(robot)

    events = {0: lambda: [join(0), join(1), join(2)], 63: lambda: leave(1),
              87: lambda: join(3), 151: lambda: leave(0), 173: lambda: join(1)}
    worst = 0.0
    checks = 0
    for k in range(320):
        if k in events:
            events[k]()
        for i, (robot, k0, single, backend) in live.items():
            own = k - k0
            if own % 5 == 0:  # a load renewal of its own: compare
                single.sync(own * DT)
                row = batch.row(robot)
                qd_single = np.concatenate([leg.plant.qd for leg in single.legs])
                worst = max(worst, float(np.max(np.abs(batch.q[row] - single.body.q()))),
                            float(np.max(np.abs(batch.qd[row] - qd_single))))
                _same_state(single.read(), backend.read())
                assert backend.body.forces == pytest.approx(single.body.forces, abs=1e-9)
                checks += 1
            for b in (single, backend):
                if own % 10 == 0:  # a gait period of its own: new goals
                    b.write(_goal(i, own * DT), _speed(i))
                if own == 20 and i == 2:
                    b.push(np.array([1.0, -2.0, 6.0]), link=8, point=np.array([0.0, -0.1, 0.0]),
                           duration=0.2)
                if own == 30 and i == 3:
                    b.set_spring(np.array([0.05, 0.15, -0.05]), stiffness=40.0, link=4,
                                 point=np.zeros(3))
        batch.step()
    assert worst <= 1e-9 and checks > 150
    assert sorted(live) == [1, 2, 3] and batch.n_robots == 3
    assert [p.n_arms for p in batch.plants] == [3 * len(g) for g in groups]
    moved = np.abs(batch.q - (Q0 + np.array([OFFSETS[i] for i in (2, 3, 1)])))
    assert np.all(moved.max(axis=1) > 0.02)


def test_a_diverged_robot_is_named_by_its_robot_id() -> None:
    batch = BatchedQuadrupeds(HEAVY_RH, dt=DT, body_mass=0.0)
    robots = [batch.add(Q0) for _ in range(3)]
    batch.remove(robots[0])
    rh = batch.legs[2]
    rh.plant.set_state(rh.arm(robots[2]), Q0[6:9], np.array([0.0, 1e300, 0.0]))
    with np.errstate(all="ignore"), pytest.raises(
            FloatingPointError, match=rf"robots \[{robots[2]}\] diverged"):
        batch.step()


# -- the gait loop ------------------------------------------------------------------------

@pytest.mark.slow
def test_a_gait_loop_walks_one_robot_of_a_batch_as_it_walks_a_quadruped_backend() -> None:
    plan = plan_gait(GaitSpec())
    alone = GaitLoop(Walker(plan), QuadrupedSimBackend(MODEL, q0=Q0, dt=DT), period=PERIOD,
                     realtime=False)
    batch = BatchedQuadrupeds(MODEL, dt=DT)
    lock = threading.RLock()
    batch.add(Q0 + OFFSETS[1])  # neighbours: one before, one after
    robot = batch.add(Q0)
    other = batch.add(Q0 + OFFSETS[2], torque_on=False)
    loop = GaitLoop(Walker(plan), BatchedQuadrupedBackend(batch, robot, lock=lock, drive=True),
                    period=PERIOD, realtime=False)
    for lp in (alone, loop):
        lp.go(plan)
        lp.run_for(2.5)  # 1.5 s standing up, then a cycle of the trot
    a, b = alone.snapshot(), loop.snapshot()
    assert a.keys() == b.keys() and len(a["t"]) == 125
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
    assert a["walking"][-1] == 1.0 and not alone.status.fault and not loop.status.fault
    ea, eb = alone.angle_error(), loop.angle_error()
    assert ea is not None and eb is not None and ea["samples"] == eb["samples"] > 0
    assert ea["mean_pct"] == eb["mean_pct"]
    assert batch.forces[batch.row(other)].sum() == 0.0  # torque off beside it: sat down
    assert batch.forces[batch.row(robot)].sum() == pytest.approx(total_mass(MODEL) * G)


@pytest.mark.slow
def test_a_gait_loop_on_the_class_clock_walks_as_on_a_quadruped_backend() -> None:
    """The classroom's way (armlab/app/workers/class_quadrupeds.py): the loop's periods
    run on the clock
    that steps the batch (``GaitLoop(clock=)``), the backend only checks the time. The
    record equals the loop's own on a QuadrupedSimBackend, row for row."""
    plan = plan_gait(GaitSpec())
    alone = GaitLoop(Walker(plan), QuadrupedSimBackend(MODEL, q0=Q0, dt=DT), period=PERIOD,
                     realtime=False)
    batch = BatchedQuadrupeds(MODEL, dt=DT)
    clock = SharedClock(batch.step, dt=DT, realtime=False)
    batch.add(Q0 + OFFSETS[1])  # a neighbour, walking nowhere
    robot = batch.add(Q0)
    loop = GaitLoop(Walker(plan), BatchedQuadrupedBackend(batch, robot, lock=clock.lock),
                    period=PERIOD, realtime=False, clock=clock)
    alone.go(plan)
    alone.run_for(2.5)
    loop.go(plan)
    loop.start()
    clock.run_for(2.5)
    a, b = alone.snapshot(), loop.snapshot()
    assert len(a["t"]) == len(b["t"]) == 125
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
    assert a["walking"][-1] == 1.0 and not loop.status.fault
    assert loop.angle_error()["mean_pct"] == alone.angle_error()["mean_pct"]


@pytest.mark.slow
def test_the_class_walks_each_students_robot_on_its_own() -> None:
    """armlab/app/workers/class_quadrupeds.py: robots on the class's clock (its step
    CLASS_DT); one walks,
    its neighbour stands; an E-STOP sits that one down alone; a freed robot is gone."""
    from armlab.app.workers.class_quadrupeds import CLASS_DT, ClassQuadrupeds

    hands_off = ClassQuadrupeds(realtime=False)
    try:
        walker = hands_off.add(GaitSpec(), speed=0.5, history_s=10.0)
        stander = hands_off.add(GaitSpec(gait="crawl"), speed=0.5, history_s=10.0)
        assert hands_off.batch.dt == CLASS_DT and hands_off.n_robots == 2
        walker.loop.go(plan_gait(GaitSpec()))
        wait_for(lambda: walker.loop.status.t > 3.0, 120, "three seconds of walking")
        assert walker.loop.status.walking and not stander.loop.status.walking
        assert not walker.loop.status.fault and not stander.loop.status.fault
        err = walker.loop.angle_error()
        assert err is not None and 0.3 < err["mean_pct"] < 5.0  # eq. 4.1, as on its own
        row = hands_off.batch.row
        assert hands_off.batch.forces[row(stander.robot)].sum() == pytest.approx(
            total_mass(MODEL) * G)
        walker.loop.estop()
        wait_for(lambda: not walker.loop.status.torque_on, 30, "the E-STOP")
        wait_for(lambda: hands_off.batch.forces[row(walker.robot)].sum() == 0.0, 30,
                 "the body sitting down")
        assert stander.loop.status.torque_on
        hands_off.free(walker)
        hands_off.free(walker)  # twice: nothing
        assert hands_off.n_robots == 1 and hands_off.batch.ids == (stander.robot,)
    finally:
        hands_off.close()
