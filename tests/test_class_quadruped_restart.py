"""A class's quadruped is started again for the walk challenge (issue 50 item 3): its row
of the batch reset in place (:meth:`BatchedQuadrupeds.reset`) is a robot that joined
then, and two students' private quadrupeds in one class's worker, with the same settings
after different earlier activity, give the same eq. 4.1 figure (every digit).

Real parts: the batched plant, the class's worker process, real lessons on real viser
servers; nothing mocked.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from _helpers import served_lesson, wait_for
from test_batched_quadruped import DT, MODEL, OFFSETS, Q0, _goal, _same_state, _speed
from test_challenge_restart import WALK, _run, _sim_to

from armlab.app.classroom.sandboxes import Sandboxes
from armlab.app.lessons import LessonContext
from armlab.app.lessons import quadruped as quad_lesson
from armlab.hardware.families.dynamixel1.batched_quadruped import (
    BatchedQuadrupedBackend,
    BatchedQuadrupeds,
)


@pytest.mark.slow
def test_a_reset_robot_is_a_robot_that_joined_then() -> None:
    """A robot that swayed, was pushed, held by a spring and let go, reset at Q0, moves
    from then on as a robot added at Q0 in the same step (q, qd to 1e-9, its reports, body
    and load exactly), its neighbour untouched; its id and row stay."""
    batch = BatchedQuadrupeds(MODEL, dt=DT)
    lock = threading.RLock()
    neighbour = batch.add(Q0 + OFFSETS[1])
    robot = batch.add(Q0 + OFFSETS[2])
    bn, br = (BatchedQuadrupedBackend(batch, r, lock=lock) for r in (neighbour, robot))
    br.push(np.array([0.0, 0.0, -5.0]), link=2, point=np.zeros(3), duration=10.0)
    br.set_spring(np.array([0.1, 0.0, -0.1]), stiffness=50.0, link=5, point=np.zeros(3))
    for k in range(300):  # earlier activity: a sway, then torque off (it sits down)
        if k % 10 == 0:
            bn.write(_goal(1, k * DT), _speed(1))
            br.write(_goal(2, k * DT), _speed(2))
        if k == 250:
            br.set_torque(False)
        batch.step()
    row = batch.row(robot)
    batch.reset(robot, Q0)
    fresh = batch.add(Q0)
    bf = BatchedQuadrupedBackend(batch, fresh, lock=lock)
    assert batch.row(robot) == row and batch.time_of(robot) == batch.time_of(fresh) == 0.0
    _same_state(br.read(), bf.read())
    for k in range(750):  # 1.5 s of the same goals
        if k % 10 == 0:
            goal = _goal(0, k * DT)
            br.write(goal, _speed(0))
            bf.write(goal, _speed(0))
            bn.write(_goal(1, k * DT), _speed(1))
            _same_state(br.read(), bf.read())
        batch.step()
    r, f = batch.row(robot), batch.row(fresh)
    np.testing.assert_allclose(batch.q[r], batch.q[f], atol=1e-9, rtol=0)
    np.testing.assert_allclose(batch.qd[r], batch.qd[f], atol=1e-9, rtol=0)
    _same_state(br.read(), bf.read())
    assert batch.tilt_deg[r] == batch.tilt_deg[f]
    assert np.array_equal(batch.contact[r], batch.contact[f])
    assert np.array_equal(batch.forces[r], batch.forces[f]) and batch.forces[r].sum() > 0.0
    assert all(br.read().torque_on)  # torque on again, as a new robot's


@pytest.mark.slow
def test_two_students_quadrupeds_in_one_class_score_a_walk_alike_after_other_walks():
    """Two students' private quadrupeds in the class's worker: Ana walked before (a turn
    left, going on when her run starts), Bo did not; the same gait and speed give both
    the same eq. 4.1 figure, every digit, Bo's run made while Ana walks back beside it;
    a slower gait gives another."""
    boxes = Sandboxes(realtime=False)
    try:
        ctx = {name: LessonContext(robot="quadruped", realtime=False, arms=boxes.seat(name))
               for name in ("ana", "bo")}
        with served_lesson(quad_lesson.build, ctx["ana"]) as ana, \
                served_lesson(quad_lesson.build, ctx["bo"]) as bo:
            assert ana.backend is None and bo.backend is None  # the worker's robots
            ana.walk("left")  # Ana's earlier activity
            _sim_to(ana, 1.5)
            ana_first = _run(ana, WALK)
            assert ana.loop.status.restarts == 1  # started again in the worker
            err = ana_first["eq41_error_pct"]
            assert err is not None and 0.0 < err < 10.0
            ana.walk("back")  # Ana walks on beside Bo's run
            bo_first = _run(bo, WALK)
            assert bo_first == ana_first  # every digit
            assert bo.loop.status.restarts == 1
            # Ana again, after her walk back: the same
            ana_again = _run(ana, WALK)
            assert ana_again == ana_first
            # another setting: another figure
            bo.set_speed(0.25)
            wait_for(lambda: bo.loop.status.speed == 0.25, 30, "the speed")
            slower = _run(bo, WALK)
            assert slower["eq41_error_pct"] != ana_first["eq41_error_pct"]
            assert bo.run_tags() == {"eq41_error_pct": "walk"}
    finally:
        boxes.close()
