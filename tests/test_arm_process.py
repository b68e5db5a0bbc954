"""The students' private arms in a worker process
(armlab/app/workers/worker_process.py): what a lesson
reads of an arm is mirrored without a gap, what it asks is answered (a refusal raised
here), and a worker that dies leaves the server healthy and the next arm working."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from _helpers import wait_for

from armlab.app.classroom.sandboxes import Sandboxes
from armlab.app.workers.worker_process import ArmProcess, RemoteBackend, RemoteLoop
from armlab.control.backend import BackendError, Pushable, Touchable, WallSetting
from armlab.control.commands import EStop, RunTrajectory
from armlab.control.params import DEFAULT, Params
from armlab.control.trajectory import minimum_jerk
from armlab.kinematics import load_robot

Q0 = np.array([0.0, 0.3, 0.3])


@pytest.fixture(scope="module")
def model():
    return load_robot("receptionist_arm", preset="18.5/25")


@pytest.mark.slow
def test_a_private_arm_runs_in_the_worker_and_its_recording_is_mirrored_without_a_gap(model):
    """The arm's loop runs in another process; every period it records reaches the
    server's mirror once, in order, from its first (the loop times are 0, then one
    period apart), and the arm follows a trajectory posted from here to its goal."""
    boxes = Sandboxes(realtime=True)
    try:
        backend, loop = boxes.seat("s").arm_for(model, DEFAULT, preset="18.5/25", q0=Q0,
                                                history_s=30.0)
        assert isinstance(loop, RemoteLoop) and isinstance(backend, RemoteBackend)
        assert isinstance(backend, Pushable)
        assert boxes.process.pid != os.getpid()
        goal = Q0 + np.array([0.3, -0.2, 0.25])
        loop.post(RunTrajectory(minimum_jerk(Q0, goal, 0.8)))
        wait_for(lambda: loop.status.t > 2.0 and loop.status.trajectory is None, 60,
                 "the trajectory played in the worker")
        snap = loop.recorder.snapshot()
        t = snap["t"]
        assert len(t) > 100 and t[0] == 0.0  # (30 s kept: the first period is there)
        np.testing.assert_allclose(np.diff(t), DEFAULT.period, atol=1e-9)  # no row lost
        np.testing.assert_allclose(snap["q"][-1], goal, atol=np.radians(2.0))
        np.testing.assert_allclose(backend.read().position, goal, atol=np.radians(2.0))
        assert "q_theta1_rad" in loop.recorder.to_csv(DEFAULT)
        assert len(backend.plant.reports()) == 3  # the Servos panel's read
        assert loop.status.fault is None and loop.status.running
    finally:
        boxes.close()
    assert boxes.process.ended == "the arm's process was closed"


@pytest.mark.slow
def test_a_private_hand_and_quadruped_are_mirrored_from_their_first_period():
    """The worker mirrors a new hand's or quadruped's loop from its first period on,
    which may reach the server before the add's answer: those rows are kept too (a
    command posted at once then lies inside the record, not before it)."""
    from armlab.app.workers.class_quadrupeds import PERIOD
    from armlab.control.grip import GripParams
    from armlab.control.walking import GaitSpec
    from armlab.hardware.sim.hand_plant import GraspObject

    boxes = Sandboxes(realtime=True)
    try:
        seat = boxes.seat("s")
        hand = seat.hand_for(GraspObject(size=0.06, stiffness=1000.0), GripParams(),
                             history_s=30.0)
        quad = seat.quadruped_for(GaitSpec(), speed=0.5, history_s=30.0)
        for robot, period in ((hand, hand.dt), (quad, PERIOD)):
            wait_for(lambda robot=robot: robot.status.t > 1.0, 60, "a second mirrored")
            t = robot.snapshot()["t"]
            np.testing.assert_allclose(np.diff(t), period, atol=1e-9)  # no row lost
        assert quad.snapshot()["t"][0] == 0.0  # its loop's first period is there
    finally:
        boxes.close()


@pytest.mark.slow
def test_what_the_worker_refuses_is_raised_here_and_changes_nothing(model):
    """A refused command or gain raises in the server as it would in process; an
    argument that cannot be sent at all is refused before it goes."""
    proc = ArmProcess(realtime=True)
    try:
        arm = proc.add(model, DEFAULT, preset="18.5/25", q0=Q0, history_s=1.0)
        loop = arm.loop
        with pytest.raises(ValueError, match="not a loop command"):
            loop.post("run")  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="params must be"):
            loop.set_params({"kp": 200.0})  # type: ignore[arg-type]
        assert loop.params == DEFAULT
        with pytest.raises(ValueError, match="cannot be sent"):
            loop.post(lambda: None)  # type: ignore[arg-type]
        unstable = Params(kp=200.0, kv=0.0)  # a simulated arm takes them, with the warning
        gains = loop.set_params(unstable)
        assert gains.unstable and gains.warning.startswith("the PD loop diverges")
        assert loop.params == unstable and loop.gains == gains
        assert loop.status.fault is None
        # the arm's wall: a bad one refused there, raised here, the world as it was
        backend = arm.backend
        assert isinstance(backend, Touchable) and backend.wall_setting() is None
        with pytest.raises(ValueError, match="normal_base must not be zero"):
            backend.set_wall(np.zeros(3), np.zeros(3), stiffness=2e4, damping=50.0)
        with pytest.raises(ValueError, match="friction"):
            backend.set_wall(np.zeros(3), np.array([0.0, 0.0, 1.0]), stiffness=2e4,
                             damping=50.0, friction=9.0)
        with pytest.raises(ValueError, match="size"):
            backend.set_wall(np.zeros(3), np.array([0.0, 0.0, 1.0]), stiffness=2e4,
                             damping=50.0, size=(0.3, float("nan"), 0.02))
        assert backend.wall_setting() is None
        backend.set_wall(np.zeros(3), np.array([0.0, 0.0, 1.0]), stiffness=2e4,
                         damping=50.0, size=(0.3, 0.3, 0.02))  # a table top: taken
        kept = backend.wall_setting()
        assert kept is not None and kept.size == (0.3, 0.3, 0.02)
        backend.set_wall(None, stiffness=2e4, damping=50.0)
        assert backend.wall_setting() is None
        with pytest.raises(ValueError, match="a wall must be a WallSetting"):
            backend.meet_wall("a wall")  # type: ignore[arg-type]
        backend.set_wall(np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, 2.0]),
                         stiffness=2e4, damping=50.0, friction=0.3)
        wall = backend.wall_setting()
        assert wall is not None and np.array_equal(wall.normal, [0.0, 0.0, 1.0])
        assert (wall.stiffness, wall.damping, wall.friction) == (2e4, 50.0, 0.3)
        backend.set_wall(None, stiffness=2e4, damping=50.0)
        assert backend.wall_setting() is None
    finally:
        proc.close()


@pytest.mark.slow
def test_a_restart_in_the_worker_meets_the_wall_named_and_a_cancel_drops_its_plan(model):
    """A challenge's restart of a private arm: the fresh arm meets the wall ``meet_wall``
    named (the arm's own until then kept none), and ``cancel`` right after the restart
    drops the plan's command due 100 periods later, which then never plays."""
    proc = ArmProcess(realtime=True)
    try:
        arm = proc.add(model, DEFAULT, preset="18.5/25", q0=Q0, history_s=10.0)
        backend, loop = arm.backend, arm.loop
        wait_for(lambda: loop.status.t > 0.2, 60, "the arm running")
        hand = model.fk(Q0)[:3, 3]
        wall = WallSetting(hand + np.array([0.0, 0.0, -0.05]), np.array([0.0, 0.0, 1.0]),
                           2e4, 50.0)
        backend.meet_wall(wall)
        assert backend.wall_setting() is None  # (the arm in use keeps its own: none)
        goal = Q0 + np.array([0.3, -0.2, 0.25])
        number = backend.restart(Q0, [(100, RunTrajectory(minimum_jerk(Q0, goal, 0.5)))])
        wait_for(lambda: backend.restarted()[0] >= number, 30, "the restart")
        backend.cancel()
        at = backend.restarted()[1]
        met = backend.wall_setting()
        assert met is not None and np.array_equal(met.origin, wall.origin)
        assert met.stiffness == 2e4 and met.damping == 50.0
        wait_for(lambda: loop.status.t > at + 130 * DEFAULT.period, 60, "130 periods on")
        snap = loop.recorder.snapshot()
        after = snap["t"] >= at
        assert np.ptp(snap["q_cmd"][after], axis=0).max() < 1e-9  # nothing played
        assert np.all(snap["f_contact"][after] == 0.0)  # its wall 5 cm below the hand
    finally:
        proc.close()


@pytest.mark.slow
def test_the_servos_reports_are_mirrored_and_say_when_the_arm_is_gone(model):
    """The Servos panel's reports come with the mirror (a page's frame never waits for
    the worker): an E-STOP shows in them as torque off; a freed arm's, or an ended
    worker's, raise BackendError saying so."""
    proc = ArmProcess(realtime=True)
    try:
        arm = proc.add(model, DEFAULT, preset="18.5/25", q0=Q0, history_s=1.0)
        reports = arm.backend.plant.reports()
        assert len(reports) == 3 and all(r.torque_enable for r in reports)
        assert all(r.voltage == 120 for r in reports)  # Present Voltage: 12.0 V, in 0.1 V
        arm.loop.post(EStop())
        wait_for(lambda: not any(r.torque_enable for r in arm.backend.plant.reports()), 60,
                 "the E-STOP in the mirrored reports")
        proc.free(arm)
        with pytest.raises(BackendError, match="freed"):
            arm.backend.plant.reports()
        other = proc.add(model, DEFAULT, preset="18.5/25", q0=Q0, history_s=1.0)
        os.kill(proc.pid, signal.SIGKILL)
        wait_for(lambda: proc.ended is not None, 60, "the worker's end noticed")
        with pytest.raises(BackendError, match="stopped"):
            other.backend.plant.reports()
    finally:
        proc.close()


@pytest.mark.slow
def test_a_worker_that_dies_is_told_and_the_next_arm_gets_a_new_one(model):
    """The worker killed: the arm's status says so as a fault, calls raise BackendError
    (E-STOP still answers: nothing holds torque), the server goes on, and the next arm
    asked for runs in a new worker."""
    boxes = Sandboxes(realtime=True)
    try:
        backend, loop = boxes.seat("a").arm_for(model, DEFAULT, preset="18.5/25", q0=Q0,
                                                history_s=1.0)
        wait_for(lambda: loop.status.t > 0.1, 60, "the arm running")
        dead = boxes.process
        os.kill(dead.pid, signal.SIGKILL)
        wait_for(lambda: loop.status.fault is not None, 60, "the fault told")
        assert "stopped" in loop.status.fault and "reload the page" in loop.status.fault
        assert not loop.status.running
        with pytest.raises(BackendError, match="stopped"):
            loop.post(RunTrajectory(minimum_jerk(Q0, Q0 + 0.1, 0.5)))
        assert backend.estop() is True
        _, again = boxes.seat("a").arm_for(model, DEFAULT, preset="18.5/25", q0=Q0,
                                           history_s=1.0)
        assert again is not loop and boxes.process is not dead
        wait_for(lambda: again.status.t > 0.1 and again.status.fault is None, 60,
                 "the new arm running in a new worker")
        assert boxes.n_arms == 1
    finally:
        boxes.close()


@pytest.mark.slow
def test_a_classroom_runs_its_shared_simulated_arm_in_a_process_of_its_own():
    """With --classroom on the simulated backend the shared arm's loop runs in a worker
    of its own (not the server, not the class's): E-STOP reaches it, the lesson's Reset
    clears it, another lesson frees it, and closing the lab ends the worker. An arm with
    X-series servos and a gripper, and any arm without --classroom, stays in the server."""
    from armlab.app.lab.server import Lab, ServeOptions
    from armlab.app.lessons._loop_state import post_reset
    from armlab.control.loop import ControlLoop

    with Lab(ServeOptions(http_port=0, classroom=True)) as lab:
        loop = lab.lesson.rig.loop
        assert isinstance(loop, RemoteLoop) and lab.arm_process is not None
        assert lab.arm_process.pid not in (os.getpid(), lab.room.sandboxes.process.pid)
        wait_for(lambda: loop.status.t > 0.5 and loop.status.jitter_p99_ms is not None, 60,
                 "the shared arm's paced loop running")
        lab.estop()
        wait_for(lambda: loop.status.estopped and not loop.status.torque_on, 60,
                 "the shared arm E-STOPPED")
        post_reset(loop)
        wait_for(lambda: loop.status.active and not loop.status.estopped, 60, "reset")
        shared = lab.arm_process
        lab.switch("arm")  # the compliance arm freed; the OpenManipulator-X (X-series
        arm_loop = lab.lesson.loop  # servos, a gripper) runs in the server
        assert isinstance(arm_loop, ControlLoop) and not shared.holds(loop.arm_id)
        wait_for(lambda: arm_loop.status.t > 0.5 and arm_loop.status.fault is None, 60,
                 "the any-arm lesson's shared arm running")
    assert shared.ended == "the arm's process was closed"
    with Lab(ServeOptions(http_port=0)) as lab:
        assert lab.arm_process is None and isinstance(lab.lesson.rig.loop, ControlLoop)


@pytest.mark.slow
def test_each_worker_is_scheduled_as_it_says():
    """The shared arm's real-time worker asks for SCHED_FIFO (taken where the OS allows
    it, said otherwise); the class's worker is niced below the server; a worker run as
    fast as possible never holds a real-time priority. Read back from the OS."""
    from armlab.app.workers.worker import CLASS_NICE, SHARED_RT_PRIORITY

    own = ArmProcess(kind="own", realtime=True)
    fast = ArmProcess(kind="own", realtime=False)
    cls = ArmProcess(kind="class", realtime=True)
    try:
        for proc in (own, fast, cls):
            wait_for(lambda p=proc: p.scheduling is not None, 120, "the worker started")
        if own.scheduling == f"SCHED_FIFO {SHARED_RT_PRIORITY}":
            assert os.sched_getscheduler(own.pid) == os.SCHED_FIFO
            assert os.sched_getparam(own.pid).sched_priority == SHARED_RT_PRIORITY
        else:
            assert own.scheduling == "normal (real-time priority not allowed)"
            assert os.sched_getscheduler(own.pid) == os.SCHED_OTHER
        assert fast.scheduling == "normal" and os.sched_getscheduler(fast.pid) == os.SCHED_OTHER
        expected = min(19, os.getpriority(os.PRIO_PROCESS, 0) + CLASS_NICE)
        assert cls.scheduling == f"nice {expected}"
        assert os.getpriority(os.PRIO_PROCESS, cls.pid) == expected
    finally:
        for proc in (own, fast, cls):
            proc.close()


@pytest.mark.slow
def test_a_shared_urdf_arm_in_its_worker_follows_a_target_with_its_spare_joints():
    """The any-arm lesson's shared arm (a five-joint URDF arm, protocol-1.0 servos) in a
    simulated classroom runs in the worker: a hand target and the spare joints' aim go
    there, the aim comes back in the mirror, and the hand reaches the target."""
    from pathlib import Path

    from armlab.app.lab.server import Lab, ServeOptions
    from armlab.control.commands import SetTarget, UseSpareJoints

    urdf = Path(__file__).parent / "data" / "five_joint_arm.urdf"
    with Lab(ServeOptions(http_port=0, classroom=True, robot=str(urdf))) as lab:
        lab.switch("arm")
        lesson = lab.lesson
        loop, model = lesson.loop, lesson.model
        assert isinstance(loop, RemoteLoop)
        q = np.array([0.2, 0.5, 1.5, 2.2, 0.4])  # (away from the singular stretched arm)
        lesson.move_to(q)  # what a joint slider does

        def moving() -> float:
            return float(np.abs(loop.recorder.snapshot(0.1)["q"][-1] - q).max())

        wait_for(lambda: moving() < np.radians(2.0), 60,
                 lambda: f"the arm at its start ({np.degrees(moving()):.1f}° off)")
        goal = model.fk(q)[:3, 3] + np.array([0.03, -0.03, 0.02])
        loop.post(UseSpareJoints("limits"))
        loop.post(SetTarget(goal))
        wait_for(lambda: loop.spare_joints.aim == "limits", 60, "the aim mirrored")

        def hand_error() -> float:
            return float(np.linalg.norm(model.fk(loop.recorder.snapshot(0.1)["q"][-1])[:3, 3]
                                        - goal))

        wait_for(lambda: hand_error() < 0.003, 60,
                 lambda: f"the hand on the target ({hand_error():.4f} m away)")
        assert loop.status.fault is None


@pytest.mark.slow
def test_a_worker_that_stops_answering_is_told_and_its_estop_lands_when_it_resumes(model):
    """The worker frozen (SIGSTOP: a machine starved of CPU looks the same): the arm's
    status says it is not answering, an E-STOP gives up waiting and says it could not be
    sure, and the server goes on. Resumed, the worker applies the E-STOP it was sent."""
    boxes = Sandboxes(realtime=True)
    try:
        backend, loop = boxes.seat("a").arm_for(model, DEFAULT, preset="18.5/25", q0=Q0,
                                                history_s=1.0)
        wait_for(lambda: loop.status.t > 0.1 and loop.status.torque_on, 60, "the arm running")
        pid = boxes.process.pid
        os.kill(pid, signal.SIGSTOP)
        try:
            wait_for(lambda: loop.status.fault is not None, 60, "the silence told")
            assert "has not answered" in loop.status.fault
            with pytest.raises(BackendError, match="did not answer"):
                loop.post(EStop())
            assert backend.estop() is False  # not known to have landed: said so
        finally:
            os.kill(pid, signal.SIGCONT)

        def seen() -> str:
            st = loop.status
            return (f"the E-STOP applied on resuming (fault {st.fault!r}, estopped "
                    f"{st.estopped}, torque on {st.torque_on}, t {st.t:.2f} s, worker "
                    f"{boxes.process.ended or 'running'})")

        wait_for(lambda: loop.status.fault is None and loop.status.estopped
                 and not loop.status.torque_on, 120, seen)
    finally:
        boxes.close()
