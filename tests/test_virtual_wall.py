"""A wall the compliance law renders (``SetVirtualWall``): what real servos touch. The
hand driven into it stops there, its rendered force is recorded as a simulated wall's
is, a wall set with the hand inside it is refused, and PD renders none."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

from armlab.control.backend import WallSetting
from armlab.control.commands import RunTrajectory, SetVirtualWall
from armlab.control.experiments.contact import contact_plan, recorded_contact
from armlab.control.loop import ControlLoop
from armlab.control.params import DEFAULT
from armlab.control.virtual_wall import rendered_wall, wall_force
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.kinematics.catalog import load_robot

ARM = load_robot("receptionist_arm")


def test_the_wall_pushes_only_inside_and_never_pulls():
    wall = WallSetting(np.zeros(3), np.array([1.0, 0.0, 0.0]), 2e4, 50.0)
    assert wall_force(wall, np.array([0.01, 0, 0]), np.zeros(3)) == 0.0  # free side
    assert wall_force(wall, np.array([-0.002, 0, 0]), np.zeros(3)) == pytest.approx(40.0)
    # leaving fast: the damping would pull; the wall never does
    assert wall_force(wall, np.array([-0.001, 0, 0]), np.array([1.0, 0, 0])) == 0.0
    q = np.array([0.3, 0.5, 0.8])
    x = ARM.fk(q)[:3, 3]
    inside = WallSetting(x - np.array([0.001, 0, 0]), np.array([-1.0, 0, 0]), 1e4, 0.0)
    f, tau = rendered_wall(ARM, inside, q, np.zeros(3))
    assert f == pytest.approx(10.0)
    np.testing.assert_allclose(tau, -(ARM.jacobian(q)[:3].T @ (f * inside.normal)))


def _run(controller: str, *, stiffness: float = 2e4):
    run = contact_plan(ARM, DEFAULT.period, wall=0.04, depth=0.02)
    backend = SimBackend(ARM, q0=run.plan.q[0])  # its world holds no wall
    loop = ControlLoop(ARM, backend, DEFAULT, controller=controller, realtime=False,
                       history_s=run.plan.duration + 5.0)
    try:
        loop.step()
        loop.post(SetVirtualWall(WallSetting(run.origin, run.normal, stiffness, 50.0)))
        loop.post(RunTrajectory(run.plan, approach=False))
        for _ in range(run.periods):
            loop.step()
        snap = loop.recorder.snapshot()
        hand = np.array([ARM.fk(q)[:3, 3] for q in snap["q"]])
        return run, snap, hand, loop.status
    finally:
        loop.shutdown()
        backend.close()


def test_the_compliance_law_stops_the_hand_at_the_wall_and_records_its_force():
    run, snap, hand, status = _run("compliance")
    assert status.fault is None
    depth_in = -(hand - run.origin) @ run.normal  # m inside the wall, per period
    # without the wall the command ends 2 cm behind the surface; rendered, the hand stops
    # within a few millimetres of it
    assert depth_in.max() < 0.006
    figures = recorded_contact(snap, start=2)
    assert figures["touched"] and figures["peak_force_n"] > 0.0
    # the force recorded is the one rendered at each period's measured pose
    f = np.nan_to_num(snap["f_contact"])
    k = np.flatnonzero(f > 0)[-1]
    want, _ = rendered_wall(ARM, WallSetting(run.origin, run.normal, 2e4, 50.0),
                            snap["q"][k], np.zeros(3))  # its stiffness part: the damping
    assert f[k] == pytest.approx(want, rel=0.5)  # adds the hand's speed, not recorded


def test_pd_renders_no_wall_and_records_no_force():
    run, snap, hand, _ = _run("pd")
    assert np.isnan(snap["f_contact"]).all()


def test_a_wall_set_with_the_hand_inside_it_is_refused():
    q0 = np.array([0.3, 0.5, 0.8])
    backend = SimBackend(ARM, q0=q0)
    loop = ControlLoop(ARM, backend, DEFAULT, controller="compliance", realtime=False)
    try:
        loop.step()
        x = ARM.fk(q0)[:3, 3]
        loop.post(SetVirtualWall(WallSetting(x - np.array([0.03, 0, 0]),
                                             np.array([-1.0, 0, 0]), 2e4, 50.0)))
        loop.step()
        # the measured hand, a couple of millimetres below the command (its servos' sag)
        assert re.search(r"virtual wall not set: the hand is 3\.\d cm inside it; move the "
                         r"hand to its free side first", loop.status.message)
        loop.step()
        assert np.isnan(loop.recorder.snapshot()["f_contact"][-1])
        # a soft wall the hand is just inside (1 mm, some 0.5 N at 500 N/m; the hand
        # still settles a few mm) is set: the hand rests on it
        here = ARM.fk(loop.recorder.snapshot()["q"][-1])[:3, 3]
        loop.post(SetVirtualWall(WallSetting(here - np.array([0.001, 0, 0]),
                                             np.array([-1.0, 0, 0]), 500.0, 5.0)))
        loop.step()
        assert loop.status.message.startswith("virtual wall: the compliance law renders it")
    finally:
        loop.shutdown()
        backend.close()


@pytest.mark.realtime
@pytest.mark.slow
def test_armlab_experiment_contact_on_servos_runs_into_the_wall_the_law_renders():
    """``armlab experiment contact --backend serial``: the emulated RX-24Fs (no wall in
    their world) over the real serial path, paced by the clock; the wall is the one the
    compliance law renders, the hand stops at it and the figures are worked out from its
    recorded force, as on the simulated arm."""
    import math

    from _emulator import emulator

    from armlab.app.arm.backends import make_backend
    from armlab.control.experiments.contact import run_contact, wall_across_line
    from armlab.control.trajectory import thesis_line

    line = thesis_line(ARM)
    pose = ",".join(f"{n}={math.degrees(a):.2f}" for n, a in zip(ARM.joint_names, line.q[0],
                                                                 strict=True))
    kept = []
    with emulator("--pose", pose) as emu:
        figures = run_contact(ARM, lambda model, **kw: make_backend("serial", model,
                                                                    port=emu.port),
                              DEFAULT, controller="compliance", wall=0.04, depth=0.02,
                              stiffness=2e4, damping=50.0, keep=kept.append)
    assert figures["wall_kind"] == "virtual"
    assert figures["fault"] is None, figures["fault"]
    assert figures["touched"] and figures["peak_force_n"] > 0.0, figures
    _, _, origin, normal = wall_across_line(ARM, line.q[0], line.q[-1], 0.04)
    hand = np.array([ARM.fk(q)[:3, 3] for q in kept[-1].signals["q"]])
    inside = -(hand - origin) @ normal
    assert inside.max() < 0.008, inside.max()  # the command ends 2 cm behind the surface


@pytest.mark.realtime
@pytest.mark.slow
def test_the_contact_tab_on_servos_runs_the_hand_into_the_wall_the_law_renders():
    """The lab served on emulated RX-24Fs over the real serial path: the Contact tab's
    wall is the virtual one, its run measures the force the law rendered, and under PD a
    run into it is refused in one line."""
    import math

    from _emulator import emulator
    from _helpers import wait_for

    from armlab.app.lab.server import Lab, ServeOptions
    from armlab.control.trajectory import thesis_line

    line = thesis_line(ARM)
    pose = ",".join(f"{n}={math.degrees(a):.2f}" for n, a in zip(ARM.joint_names, line.q[0],
                                                                 strict=True))
    with emulator("--pose", pose) as emu, \
            Lab(ServeOptions(backend="serial", port=emu.port, http_port=0)) as lab:
        lesson = lab.lesson
        loop = lesson.rig.loop
        wait_for(lambda: loop.status.active and loop.status.torque_on, 60, "torque on")
        tab = lesson.contact
        tab.wall_on.value = True
        wait_for(lambda: tab.nodes()[0] is not None, 30.0, "the wall placed")
        wait_for(lambda: loop.status.message.startswith("virtual wall"), 30.0,
                 "the loop rendering the wall")
        tab.run()
        wait_for(lambda: tab.figures() is not None, 120.0, "the run into the wall measured")
        fig = tab.figures()
        assert fig["fault"] is None and fig["touched"], fig
        assert fig["peak_force_n"] > 0.0 and fig["steady_force_n"] is not None
        snap = loop.recorder.snapshot(2.0)
        assert np.nanmax(snap["f_contact"]) > 0.0  # the force it rendered, recorded
        lesson.gains.set_params(replace(lesson.gains.params, compliance=False))
        with pytest.raises(ValueError, match="PD renders none"):
            tab.run()
