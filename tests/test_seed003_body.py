"""Seed 003: the quadruped carries its body (quasi-static), so it tilts and its servos err.

Seed 003 reports 3.6–5.7° of body tilt on flat ground and a 1.201 % mean servo error
(eq. 4.1) with servo 2 (hip pitch) the worst, both from the servos giving way under
the robot's weight.
"""

import io
import json
import math
from contextlib import redirect_stdout
from dataclasses import replace

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.control.experiments.seed003 import walk_on_servos
from armlab.control.gait_loop import GaitLoop
from armlab.control.walking import GaitSpec, Walker, plan_gait
from armlab.hardware.families.dynamixel1.quadruped import G, QuadrupedSimBackend, total_mass
from armlab.kinematics.body_statics import (
    contact_forces,
    implied_tilt_deg,
    rest_plane,
    tilt_deg,
)
from armlab.kinematics.catalog import load_robot

#: Seed 003's published figures (../shared/seed-notes.md, 003: "Reported"): body tilt on
#: flat ground, degrees, and the mean eq. 4.1 servo error, percent (servo 2 the worst).
SEED_TILT_DEG = (3.6, 5.7)
SEED_EQ41_PCT = 1.201

#: Feet of a trot on its RF-LH diagonal: the other two lifted by H, body frame, m.
H = 0.02
FEET = np.array([[0.08, -0.16, -0.09], [0.08, 0.16, -0.09 + H],
                 [-0.08, -0.16, -0.09 + H], [-0.08, 0.16, -0.09]])


def test_standing_on_four_level_feet_the_body_is_level_and_shares_its_weight():
    feet = FEET.copy()
    feet[:, 2] = -0.09
    n, d, contact = rest_plane(feet, np.zeros(3))
    assert np.allclose(n, [0, 0, 1]) and d == pytest.approx(-0.09) and contact.all()
    f = contact_forces(feet, np.zeros(3), 10.0, n)
    np.testing.assert_allclose(f, 2.5)  # least-norm: the symmetric share


@pytest.mark.parametrize("side,leaning_on", [(1.0, 1), (-1.0, 2)])
def test_off_the_diagonal_the_body_tips_onto_the_swing_foot_on_that_side(side, leaning_on):
    com = np.array([0.0, 0.0, 0.0]) + side * 0.005 * np.array([1.0, 0.5, 0.0])
    n, _, contact = rest_plane(FEET, com)
    assert contact.tolist() == [True, leaning_on == 1, leaning_on == 2, True]
    # the plane through the diagonal and the touching swing foot, H above the others:
    # tilt = atan(H / distance of that foot from the diagonal line)
    a, b, c = FEET[0, :2], FEET[3, :2], FEET[leaning_on, :2]
    dist = abs((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0]) / np.linalg.norm(b - a)
    assert tilt_deg(n) == pytest.approx(math.degrees(math.atan(H / dist)), abs=0.05)
    f = contact_forces(FEET[contact], com, 10.0, n)
    assert f.sum() == pytest.approx(10.0) and np.all(f >= 0)
    # moment balance: the forces' centre is the centre of mass (in the floor plane)
    centre = (f[:, None] * FEET[contact]).sum(axis=0) / f.sum()
    off = centre - com
    assert np.linalg.norm(off - (off @ n) * n) < 1e-9


def test_two_feet_share_by_the_lever_rule():
    feet = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]])
    f = contact_forces(feet, np.array([0.1, 0.05, 0.2]), 9.0, np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(f, [6.0, 3.0])


@pytest.fixture(scope="module")
def walked():
    """Two trot cycles on the simulated legs carrying the body; the backend's own tilt."""
    model = load_robot("quadruped")
    plan = plan_gait(GaitSpec())
    walker = Walker(plan)
    backend = QuadrupedSimBackend(model, q0=walker.state().q, dt=2e-3)
    loop = GaitLoop(walker, backend, period=0.02, realtime=False)
    loop.go(plan)
    tilts = []
    for _ in range(175):  # 1.5 s standing up, then 2 cycles at 0.5 cycles/s
        loop.run_for(0.02)
        if loop.status.t > 1.6:
            tilts.append(backend.body.tilt_deg)
    return model, backend, loop, np.array(tilts)


@pytest.mark.slow
def test_the_legs_carry_the_whole_robot(walked):
    model, backend, _, _ = walked
    assert backend.body.weight == pytest.approx(total_mass(model) * G)  # 1.19 kg
    assert backend.body.forces.sum() == pytest.approx(total_mass(model) * G)
    assert 3 <= backend.body.contact.sum() <= 4  # a diagonal and the foot it leans on


@pytest.mark.slow
def test_the_body_tilts_as_seed_003_reports(walked):
    _, _, _, tilts = walked
    # seed 003: 3.6-5.7° on flat ground; the lab: up to 7.3°, 3.9° on average
    assert SEED_TILT_DEG[0] <= tilts.mean() <= SEED_TILT_DEG[1]
    assert 1.0 < tilts.max() < 10.0
    # the lab's own figures (regression pins, not a source)
    assert tilts.max() == pytest.approx(7.27, abs=0.7)
    assert tilts.mean() == pytest.approx(3.86, abs=0.5)


@pytest.mark.slow
def test_the_servos_reports_imply_the_same_tilt(walked):
    model, backend, loop, _ = walked
    snap = loop.snapshot(0.02)
    truth = implied_tilt_deg(model, backend.body.q())
    # what the lab computes from the 10-bit reports (AX-12A: 0.29° a count)
    assert implied_tilt_deg(model, snap["q"][-1]) == pytest.approx(truth, abs=0.6)


@pytest.mark.slow
def test_eq_4_1_error_as_seed_003_reports_with_servo_2_worst(walked):
    _, _, loop, _ = walked
    err = loop.angle_error(None)
    # seed 003: 1.201 %, servo 2 worst; the lab: 1.37 %
    assert err["mean_pct"] == pytest.approx(SEED_EQ41_PCT, rel=0.25)
    # the lab's own figures (regression pins, not a source)
    assert err["mean_pct"] == pytest.approx(1.37, abs=0.15)
    assert int(np.argmax(err["per_servo_pct"])) == 1
    assert err["per_servo_pct"][1] == pytest.approx(2.72, abs=0.3)


@pytest.mark.slow
def test_the_servos_giving_way_set_the_size_of_the_lean():
    """On a diagonal the body leans onto a swing foot (geometry); the stance legs' servos
    give way under the weight (the body sags towards the stance feet), so the swing foot
    sits lower and the lean is smaller: rigid 6.5° on average, loaded 4.0° (seed 003:
    3.6-5.7°). The unloaded servos barely err."""
    rigid = walk_on_servos(lambda m, **kw: QuadrupedSimBackend(m, body_mass=0.0, **kw))
    loaded = walk_on_servos(lambda m, **kw: QuadrupedSimBackend(m, **kw))
    # loaded: inside seed 003's range; rigid: above it (the giving way is what brings it in)
    assert SEED_TILT_DEG[0] <= loaded["body_tilt_mean_deg"] <= SEED_TILT_DEG[1]
    assert rigid["body_tilt_mean_deg"] > SEED_TILT_DEG[1]
    # the lab's own figures (regression pins, not a source)
    assert rigid["body_tilt_mean_deg"] == pytest.approx(6.55, abs=0.6)
    assert loaded["body_tilt_mean_deg"] == pytest.approx(3.96, abs=0.5)
    assert rigid["body_tilt_deg"] == pytest.approx(11.5, abs=1.0)
    assert rigid["eq41_error_pct"]["overall"] == pytest.approx(0.66, abs=0.15)
    assert loaded["eq41_error_pct"]["overall"] > 1.8 * rigid["eq41_error_pct"]["overall"]
    assert loaded["eq41_error_pct"]["servo2"] > 2.5 * rigid["eq41_error_pct"]["servo2"]


@pytest.mark.slow
def test_cli_reports_eq41_and_tilt():
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["experiment", "seed003-gait", "--json"]) == 0
    r = json.loads(out.getvalue())
    assert set(r["eq41_error_pct"]) == {"servo1", "servo2", "servo3", "overall"}
    e = r["eq41_error_pct"]
    assert e["overall"] == pytest.approx(SEED_EQ41_PCT, rel=0.25)  # seed 003's figure
    assert SEED_TILT_DEG[0] <= r["body_tilt_mean_deg"] <= SEED_TILT_DEG[1]
    assert e["overall"] == pytest.approx(1.37, abs=0.15)  # the lab's own (a regression pin)
    assert e["servo2"] == max(e["servo1"], e["servo2"], e["servo3"])
    assert r["body_tilt_deg"] == pytest.approx(8.0, abs=0.8)
    assert r["body_tilt_mean_deg"] == pytest.approx(3.96, abs=0.5)


@pytest.mark.realtime
def test_over_the_emulator_the_legs_carry_the_body_too(capsys):
    """``seed003-gait --backend serial`` on the emulator's 12 AX-12A walks as the simulated
    legs do (``--backend sim``, run here): the same eq. 4.1 error, servo 2 the worst, and
    the same tilt, within what the bus's timing adds (the emulator's physics runs on the
    wall clock in another process, goals and reports cross a real pseudo-terminal)."""
    from _emulator import emulator

    # a 4 ms plant step: twelve servos' physics at 1 kHz take a whole core of a slow machine,
    # whose replies then come too late for the gait loop (the class's robots step at 5 ms)
    with emulator("--robot", "quadruped", "--dt", "0.004") as emu:
        code = main(["experiment", "seed003-gait", "--backend", "serial", "--port", emu.port,
                     "--cycles", "1", "--json"])
        _, err = emu.stop()
    assert code == 0
    r = json.loads(capsys.readouterr().out)
    assert main(["experiment", "seed003-gait", "--backend", "sim", "--cycles", "1",
                 "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    e, s = r["eq41_error_pct"], sim["eq41_error_pct"]
    seen = (f"emulator: {e}, tilt {r['body_tilt_deg']} (mean {r['body_tilt_mean_deg']}); "
            f"simulated: {s}, tilt {sim['body_tilt_deg']} (mean {sim['body_tilt_mean_deg']});"
            f" the emulator: {err.strip()}")  # its last line: how far its plant slipped
    assert e["servo2"] == max(e["servo1"], e["servo2"], e["servo3"]), seen  # the weight's
    # the bus's timing only adds to the error (a goal a cycle late on a busy machine: a
    # loaded CI run measured 1.75 % overall beside the simulation's 1.39 %), never halves it
    assert s["overall"] - 0.3 <= e["overall"] <= s["overall"] + 0.6, seen
    assert s["servo2"] - 0.5 <= e["servo2"] <= s["servo2"] + 1.0, seen
    assert r["body_tilt_mean_deg"] == pytest.approx(sim["body_tilt_mean_deg"], abs=1.0), seen
    assert r["body_tilt_deg"] == pytest.approx(sim["body_tilt_deg"], abs=1.5), seen
    assert SEED_TILT_DEG[0] <= r["body_tilt_mean_deg"] <= SEED_TILT_DEG[1], seen
    assert r["eq41_samples"] >= 30, seen


def test_the_emulators_legs_carry_the_weight_once_however_often_the_bus_ticks():
    """The emulator's physics is brought to the wall clock at every packet: standing for a
    second, ticked 8 times per plant step or once, the legs sag alike and the body tilts
    alike (a load renewed per tick, not per step, once carried the weight several times
    over in the steps a burst of packets fell in)."""
    from armlab.hardware.families.dynamixel1.emulator import emulated_network
    from armlab.hardware.families.dynamixel1.sim_backend import goal_positions

    model = load_robot("quadruped")
    q0 = Walker(plan_gait(GaitSpec())).state().q
    dt = 0.004

    def stand(ticks_per_step: int) -> tuple[np.ndarray, float]:
        physics = emulated_network(model, dt=dt).physics
        for k, plant in enumerate(physics.plants):
            q_leg = q0[3 * k:3 * k + 3]
            plant.set_state(q_leg)
            goals = goal_positions([s.spec for s in plant.servos], plant.directions, q_leg)
            for servo, goal in zip(plant.servos, goals, strict=True):
                servo.regs.goal_position, servo.regs.torque_enable = goal, 1
        for i in range(1, 250 * ticks_per_step + 1):  # 1 s
            physics.advance_to(i * dt / ticks_per_step)
        q = np.concatenate([plant.q for plant in physics.plants])
        return q, implied_tilt_deg(model, q)

    q_once, tilt_once = stand(1)
    q_dense, tilt_dense = stand(8)
    assert np.degrees(np.abs(q_dense - q_once)).max() < 0.01
    assert tilt_dense == pytest.approx(tilt_once, abs=0.01)
    assert np.degrees(np.abs(q_once - q0)).max() > 0.1  # and the legs do carry the weight


@pytest.mark.slow
def test_when_the_servos_let_go_the_body_sits_down_and_the_legs_carry_nothing():
    model = load_robot("quadruped")
    q0 = Walker(plan_gait(GaitSpec())).state().q
    backend = QuadrupedSimBackend(model, q0=q0, dt=2e-3)
    backend.sync(0.02)
    assert backend.body.forces.sum() == pytest.approx(total_mass(model) * G)
    backend.set_torque(False)
    for k in range(2, 100):
        backend.sync(0.02 * k)
    assert backend.body.forces.sum() == 0.0 and not backend.body.contact.any()
    # the legs hang under their own weight (hip pitch down, never flipped over the top)
    q = backend.read().position.reshape(4, 3)
    assert np.all(q[:, 1] > 0.5)
    backend.set_torque(True)  # and standing up again takes the weight back
    for k in range(100, 250):
        backend.write(q0, np.full(12, 2.0))
        backend.sync(0.02 * k)
    assert backend.body.forces.sum() == pytest.approx(total_mass(model) * G)


def test_a_plan_is_made_once_per_spec_and_shared_read_only():
    spec = GaitSpec(command="left")
    plan = plan_gait(spec)
    assert plan_gait(GaitSpec(command="left")) is plan  # a class pressing "left" together
    assert plan_gait(GaitSpec(command="right")) is not plan
    for arr in (plan.angles, plan.body, plan.feet_world, plan.feet_body, plan.com_body,
                plan.margins, plan.cycle.feet, plan.cycle.stance):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 0.0
    with pytest.raises(ValueError, match="reach"):  # a refusal is not kept: it says so again
        plan_gait(GaitSpec(params=replace(GaitSpec().params, D=0.2)))
    with pytest.raises(ValueError, match="reach"):
        plan_gait(GaitSpec(params=replace(GaitSpec().params, D=0.2)))
