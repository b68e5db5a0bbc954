"""The thesis's hand (§2.4, §3.1.1): gearmotor model, compliant grasp, hand-grip experiment."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.control.experiments.hand_grip import GripOptions, run_grip
from armlab.control.grip import (
    GripController,
    GripModel,
    GripParams,
    grasp_figures,
    simulate_grasp,
)
from armlab.hardware.sim.hand_plant import DCMotor, GraspObject, HandParams, HandSim, make_hand
from armlab.kinematics.hand_statics import OZ_IN, FingerGeometry, motor_torque

#: Documented "never crushes" margin: the peak fingertip force stays within 2 % of
#: the limit for objects up to 5000 N/m (the controller's docstring explains why).
PEAK_MARGIN = 0.02


def grasp(force: float, stiffness: float, *, size: float = 0.06, duration: float = 2.0,
          lpf: float | None = None, open_at: float | None = None):
    plant = make_hand(size=size, stiffness=stiffness, current_lpf_hz=lpf)
    controller = GripController(GripModel.of(plant), GripParams(force_limit=force))
    trace = simulate_grasp(plant, controller, duration=duration, open_at=open_at)
    return plant, controller, trace


def test_motor_constants_from_the_thesis_datasheet():
    m = DCMotor.from_datasheet()
    assert m.resistance == pytest.approx(6.0 / 1.6)  # 3.75 ohm
    assert m.kt == pytest.approx(2 * OZ_IN / 1.6, rel=1e-9)  # 8.83e-3 N·m/A
    # free run 6000 rpm at 120 mA gives the same constant as back-EMF
    assert m.ke == pytest.approx(m.kt, rel=1e-3)
    assert m.stall_torque == pytest.approx(2 * OZ_IN, rel=1e-9)
    assert float(motor_torque(m.kt, 1.6)) == pytest.approx(0.014123, rel=1e-4)


def test_simulated_motor_runs_free_at_6000_rpm_and_120_ma():
    # driving backwards unwinds the tendon: the gearmotor turns unloaded
    hand = HandSim(obj=None)
    for _ in range(300):
        current = hand.step(np.full(3, -6.0), 1e-3)
    rpm = hand.state.motor_speed * 60 / (2 * math.pi)
    np.testing.assert_allclose(rpm, -6000.0, rtol=0.01)
    np.testing.assert_allclose(current, -0.120, rtol=0.01)


def test_simulated_motor_stalls_at_1_6_a_with_2_oz_in():
    # closed fully on nothing: the finger rests on its stop, the motor stalls
    hand = HandSim(obj=None)
    for _ in range(500):
        current = hand.step(np.full(3, 6.0), 1e-3)
    s = hand.state
    np.testing.assert_allclose(s.finger_angle, hand.finger.closed_angle)
    np.testing.assert_allclose(current, 1.6, rtol=0.01)
    np.testing.assert_allclose(s.tension * hand.finger.spool_radius, 2 * OZ_IN, rtol=0.01)


@pytest.mark.parametrize("stiffness", [200.0, 1000.0, 5000.0], ids=["soft", "medium", "hard"])
def test_grip_force_is_the_limit_and_never_crushes(stiffness):
    force = 0.8
    plant, controller, trace = grasp(force, stiffness)
    fig = grasp_figures(trace, force)
    assert controller.modes == ("holding",) * 3
    assert fig["steady_force_N"] == pytest.approx(force, rel=0.10)
    np.testing.assert_allclose(plant.contact_force, force, rtol=0.10)  # every finger
    assert fig["peak_force_N"] <= force * (1 + PEAK_MARGIN)
    # the controller's force estimate (from current only) matches the true force
    np.testing.assert_allclose(controller.estimated_force(), plant.contact_force, rtol=0.02)
    assert fig["time_to_grasp_s"] is not None and fig["time_to_grasp_s"] < 1.5


@pytest.mark.slow
def test_force_limit_sets_the_grip_force():
    weak = grasp_figures(grasp(0.4, 1000.0)[2], 0.4)
    strong = grasp_figures(grasp(1.2, 1000.0)[2], 1.2)
    assert weak["steady_force_N"] == pytest.approx(0.4, rel=0.10)
    assert strong["steady_force_N"] == pytest.approx(1.2, rel=0.10)
    assert strong["final_current_A"] > 1.5 * weak["final_current_A"]


def test_lowering_the_limit_while_holding_lowers_the_force():
    plant, controller, _ = grasp(1.0, 1000.0, duration=1.6)
    assert plant.contact_force == pytest.approx([1.0] * 3, rel=0.05)
    controller.set_force_limit(0.5)
    current = plant.measured_current
    peak = 0.0
    for _ in range(400):
        current = plant.step(controller.update(current), controller.dt)
        peak = max(peak, float(plant.contact_force.max()))
    np.testing.assert_allclose(plant.contact_force, 0.5, rtol=0.10)
    assert peak <= 1.0 * (1 + PEAK_MARGIN)


def test_grasp_with_a_filtered_current_sensor():
    _, _, trace = grasp(0.8, 5000.0, lpf=50.0)
    fig = grasp_figures(trace, 0.8)
    assert fig["steady_force_N"] == pytest.approx(0.8, rel=0.10)
    assert fig["peak_force_N"] <= 0.8 * (1 + PEAK_MARGIN)


def test_open_releases_the_object():
    plant, controller, trace = grasp(0.8, 1000.0, duration=2.0, open_at=1.5)
    before = trace.force[np.searchsorted(trace.t, 1.45)]
    np.testing.assert_allclose(before, 0.8, rtol=0.10)
    after = trace.t > 1.6
    assert np.all(trace.force[after] == 0.0)
    assert controller.modes == ("idle",) * 3
    np.testing.assert_allclose(plant.state.finger_angle, plant.finger.open_angle, atol=0.01)


def test_object_too_small_closes_on_nothing():
    geom = FingerGeometry()
    plant, controller, trace = grasp(0.8, 1000.0, size=0.8 * geom.min_size, duration=2.5)
    assert controller.modes == ("empty",) * 3
    assert trace.force.max() == 0.0
    assert grasp_figures(trace, 0.8)["time_to_grasp_s"] is None


def _args(**kw) -> GripOptions:
    base = dict(force=0.8, stiffness=1000.0, size=6.0, damping=1.0, lpf=None, duration=2.0)
    base.update(kw)
    return GripOptions(**base)


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        (dict(size=-3.0), "size"),
        (dict(size=20.0), "size"),
        (dict(force=float("nan")), "force"),
        (dict(force=-1.0), "force"),
        (dict(force=5.0), "force"),
        (dict(stiffness=0.0), "stiffness"),
        (dict(stiffness=float("inf")), "stiffness"),
        (dict(damping=-1.0), "damping"),
    ],
)
def test_bad_input_names_the_argument(kw, name):
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        run_grip(_args(**kw), hand_plant=make_hand)


def test_bad_plant_and_controller_input():
    with pytest.raises(ValueError, match="size"):
        GraspObject(size=float("nan"))
    with pytest.raises(ValueError, match="force_limit"):
        GripParams(force_limit=-0.5)
    with pytest.raises(ValueError, match="voltage"):
        HandSim().step(np.array([0.0, np.nan, 0.0]), 1e-3)
    with pytest.raises(ValueError, match="current_lpf_hz"):
        HandParams(current_lpf_hz=0.0)


def test_cli_hand_grip_json(capsys):
    assert main(["experiment", "hand-grip", "--force", "0.6", "--stiffness", "5000",
                 "--size", "8", "--duration", "1.5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["steady_force_N"] == pytest.approx(0.6, rel=0.10)
    assert out["peak_force_N"] <= 0.6 * (1 + PEAK_MARGIN)
    assert 0.0 < out["time_to_grasp_s"] < 1.0
    assert out["final_current_A"] > 0.3


def test_cli_bad_input_is_one_line(capsys):
    assert main(["experiment", "hand-grip", "--size", "-3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "armlab experiment: size must be > 0, got -3.0"


def test_a_very_light_grip_is_still_held_and_the_first_touch_stays_small():
    # below F = 0.2 N the first touch (about 0.1 N for a 5000 N/m object) dominates the peak
    plant, controller, trace = grasp(0.05, 5000.0, size=0.08, duration=1.5)
    fig = grasp_figures(trace, 0.05)
    assert fig["steady_force_N"] == pytest.approx(0.05, rel=0.10)
    assert fig["peak_force_N"] <= 0.12


def test_the_hand_loop_takes_typed_commands_that_compose():
    """Two parameter changes posted before a period both apply; a closure is refused."""
    from armlab.control.grip_loop import CloseHand, GripLoop, SetGripParams

    plant = make_hand(size=0.06, stiffness=1000.0)
    controller = GripController(GripModel.of(plant), GripParams(force_limit=1.0))
    loop = GripLoop(plant, controller, realtime=False)
    loop.post(SetGripParams(force_limit=0.6))
    loop.post(SetGripParams(approach_speed=0.02))
    loop.post(CloseHand())
    loop.run_for(0.01)
    assert controller.params.force_limit == 0.6 and controller.params.approach_speed == 0.02
    assert loop.status.modes[0] != "idle"
    with pytest.raises(ValueError, match="not a hand-loop command"):
        loop.post(lambda _p, c: c.open())
