"""A classroom's SO-101 simulates its Feetech STS3215 servos (the firmware model
``armlab.hardware.families.feetech.firmware`` the single-user sim runs), not the thesis arm's
RX-24F:
a student's private arm (the class's clock) and the shared arm of ``serve --classroom``,
whose Servos panel names the model it simulates.
"""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import wait_for

from armlab.app.lessons.compliance_servos import read_health
from armlab.control.params import DEFAULT
from armlab.hardware.families.feetech.firmware import StsServoModel
from armlab.hardware.families.feetech.sim_backend import StsSimBackend
from armlab.hardware.families.feetech.table import STS3215
from armlab.kinematics import load_robot

pytestmark = pytest.mark.slow  # a class served and its arms driven

SO101 = load_robot("so101")


def test_a_private_so101_has_its_sts3215_servos():
    """A student's own SO-101 is an STS3215 firmware model on the class's clock: its
    servos are :class:`StsServoModel`, it turns to a goal, the Servos panel says STS3215;
    freeing it closes it."""
    from armlab.app.classroom.sandboxes import Sandboxes
    from armlab.control.commands import RunTrajectory
    from armlab.control.trajectory import minimum_jerk

    boxes = Sandboxes(realtime=False)
    try:
        backend, loop = boxes.seat("so101").arm_for(SO101, DEFAULT, preset="so101",
                                                    q0=SO101.neutral(), history_s=2.0)
        assert isinstance(backend, StsSimBackend) and backend.specs[0] is STS3215
        assert all(isinstance(s, StsServoModel) for s in backend.plant.servos)
        assert backend.gripper is None  # a private arm has no gripper
        assert read_health(backend, SO101.joint_names)[1] == "simulated servos (STS3215 model)"
        wait_for(lambda: loop.status.active and len(loop.recorder.snapshot(1.0)["t"]) > 20,
                 60, "the arm's loop running on the class clock")
        start = np.asarray(backend.read().position, dtype=float)
        goal = start + np.array([0.0, 0.3, 0.0, 0.0, 0.0])
        loop.post(RunTrajectory(minimum_jerk(start, goal, 1.0)))
        wait_for(lambda: abs(backend.read().position[1] - goal[1]) < np.radians(3.0), 60,
                 "the shoulder at its goal")
        assert loop.status.fault is None
    finally:
        boxes.close()
    assert boxes.n_arms == 0


def test_the_classroom_s_shared_so101_simulates_sts3215_servos():
    """``serve --classroom --robot so101``: the arm lesson's shared arm is an STS3215
    firmware model with its jaw's servo, in the server (the worker process simulates
    RX-24F only), and the Servos panel's words name the model."""
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, classroom=True, robot="so101", lesson="arm",
                          realtime=False)) as lab:
        backend = lab.lesson.backend
        assert isinstance(backend, StsSimBackend) and backend.specs[0] is STS3215
        assert all(isinstance(s, StsServoModel) for s in backend.plant.servos)
        assert backend.gripper is not None  # the jaw's servo, driven from the lesson
        assert read_health(backend, SO101.joint_names)[1] == "simulated servos (STS3215 model)"
        wait_for(lambda: lab.lesson.loop.status.t > 0.5, 60, "the shared arm's loop running")
        assert lab.lesson.loop.status.fault is None
