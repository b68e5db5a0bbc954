"""The disturbance and reaction-torque observers on current-sensing servos (issue "Any
Dynamixel arm", build item 4): the plant's known joint torque, ``armlab emulate
--disturb``'s parsing, and ``armlab experiment observers --backend serial``'s figures on
the simulated XM430s (simulated time; the emulated run over a pseudo-terminal is
tests/test_bus_observers.py)."""

from __future__ import annotations

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.app.commands.emulate import parse_disturbance
from armlab.control.experiments.observers import (
    dob_series,
    servo_observers,
    step_figures,
    step_index,
)
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.families.xseries.sim_backend import XSimBackend
from armlab.hardware.families.xseries.table import XL430_W250, XM430_W350
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import IDEAL
from armlab.kinematics import load_robot

OMX = load_robot("open_manipulator_x")
NAMES = OMX.joint_names
SHOULDER = 1
#: N·m: the RTOB with nothing applied reads within three counts of Present Current
#: (2.69 mA × 1.78 N·m/A each) of 0: the simulated plant is moved by the same model
RTOB_ZERO = 3 * XM430_W350.current_unit * XM430_W350.torque_constant


def test_an_applied_joint_torque_acts_from_its_start_and_shows_in_the_truth():
    plant = Plant(OMX, XM430_W350, params=IDEAL, q0=np.zeros(4))
    plant.apply_joint_torque(SHOULDER, 0.3, start=0.01)
    assert np.allclose(plant.truth().external_torque, 0.0)
    free = Plant(OMX, XM430_W350, params=IDEAL, q0=np.zeros(4))
    plant.advance_to(0.02)
    free.advance_to(0.02)
    assert plant.truth().external_torque == pytest.approx([0.0, 0.3, 0.0, 0.0])
    # the limp arm falls the same way both times, the shoulder faster with +0.3 N·m on it
    assert plant.qd[SHOULDER] > free.qd[SHOULDER] + 1e-3
    plant.clear_forces()
    assert np.allclose(plant.truth().external_torque, 0.0)


def test_a_servo_holding_the_joint_takes_the_applied_torque():
    backend = XSimBackend(OMX, spec=XM430_W350, q0=np.zeros(4))
    backend.plant.apply_joint_torque(SHOULDER, 0.3, start=1.0)
    backend.sync(0.9)
    before = backend.read().load[SHOULDER]
    backend.sync(2.0)
    after = np.median([_load_at(backend, 2.0 + 0.01 * k) for k in range(100)])
    assert after - before == pytest.approx(-0.3, rel=0.1)  # the motor works against it


def _load_at(backend, t):
    backend.sync(t)
    return backend.read().load[SHOULDER]


@pytest.mark.parametrize("kw,name", [({"joint": 4}, "joint"), ({"torque": float("nan")},
                                                                 "torque"),
                                     ({"start": -1.0}, "start")])
def test_an_applied_torque_is_checked(kw, name):
    plant = Plant(OMX, XM430_W350)
    args = {"joint": 1, "torque": 0.3, "start": 0.0, **kw}
    with pytest.raises(ValueError, match=name):
        plant.apply_joint_torque(args["joint"], args["torque"], start=args["start"])


@pytest.mark.parametrize("text,want", [("1:0.3@1.5", (1, 0.3, 1.5)),
                                       ("joint2:-0.25@0", (1, -0.25, 0.0)),
                                       (" 3:1e-1@2 ", (3, 0.1, 2.0))])
def test_disturb_takes_a_joint_index_or_name_a_torque_and_a_start(text, want):
    assert parse_disturbance(text, NAMES) == want


@pytest.mark.parametrize("text,why", [("1:0.3", "not JOINT:NM@S"), ("1@0.3:2", "not"),
                                      ("elbow:0.3@1", "joint must be"),
                                      ("4:0.3@1", "joint must be"),
                                      ("1:heavy@1", "torque is not a number"),
                                      ("1:inf@1", "torque must be finite"),
                                      ("1:0.3@-1", "start must be >= 0"),
                                      ("1:0.3@nan", "start must be finite")])
def test_a_bad_disturb_gets_one_clear_message(text, why):
    with pytest.raises(ValueError, match=why) as err:
        parse_disturbance(text, NAMES)
    msg = str(err.value)
    assert msg.startswith(f"--disturb {text!r}: ") and "expected JOINT:NM@S" in msg
    assert "\n" not in msg


def test_the_emulator_refuses_a_bad_disturb_before_it_serves(capsys):
    assert main(["emulate", "--robot", "open_manipulator_x", "--disturb", "9:0.3@1"]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # no "port: " line: nothing was served
    assert err.count("\n") == 1 and err.startswith("armlab emulate: --disturb '9:0.3@1': ")


def _omx_factory(torque, start, *, spec=XM430_W350, q0=(0.2, 0.2, 0.2, 0.2), seen=None):
    def factory(model):
        b = XSimBackend(model, spec=spec, q0=np.array(q0))
        b.plant.apply_joint_torque(SHOULDER, torque, start=start)
        if seen is not None:
            seen.append(b)
        return b
    return factory


@pytest.mark.parametrize("torque", [0.3, -0.3, 0.1])
@pytest.mark.slow
def test_the_dob_and_the_rtob_on_simulated_xm430s_estimate_the_applied_torque(torque):
    opened = []
    fig = servo_observers(OMX, _omx_factory(torque, 5.0, seen=opened), joint=SHOULDER,
                          duration=8.0, applied=torque, pose=np.zeros(4))
    assert fig["relative_error"] < 0.10, fig
    assert fig["estimated_nm"] == pytest.approx(torque, rel=0.1)
    assert fig["joint"] == "joint2" and fig["samples"] == 800
    # the hold works against gravity: τ̂_dis before is the shoulder's gravity torque (< 0)
    assert fig["dob_before_nm"] < -0.3
    # the RTOB takes the model's gravity at the measured pose out: ~0, then the torque itself
    assert abs(fig["rtob_before_nm"]) < RTOB_ZERO, fig
    assert fig["rtob_after_nm"] == pytest.approx(torque, rel=0.1)
    assert fig["rtob_error_pct"] < 10.0
    assert len(fig["series"]["applied_hat"]) == len(fig["series"]["tau_known"]) == 160
    # torque off and closed at the end
    (b,) = opened
    assert not any(s.regs.torque_enable for s in b.plant.servos) and b._closed


def test_the_step_is_found_or_taken_from_at():
    t = np.arange(0.0, 6.0, 0.01)
    x = np.where(t >= 3.0, -1.0, 0.5) + 0.01 * np.sin(40 * t)
    assert t[step_index(x)] == pytest.approx(3.0, abs=0.011)
    fig = step_figures(t, x)
    assert fig["estimated_nm"] == pytest.approx(1.5, abs=0.02)
    assert step_figures(t, x, at=3.0)["estimated_nm"] == pytest.approx(1.5, abs=0.02)
    with pytest.raises(ValueError, match="longer --duration"):
        step_figures(t, x, at=5.5)


def test_the_dob_at_rest_is_the_measured_torque_and_lags_by_its_cut_off():
    t = np.arange(0.0, 1.0, 0.001)
    tau = np.where(t >= 0.5, 0.2, 0.0)
    est = dob_series(t, np.zeros_like(t), tau, j_n=0.01, g_dis=20.0)
    k = np.searchsorted(t, 0.5 + 1 / 20.0)  # one time constant after the step: 63 %
    assert est[k] == pytest.approx(0.2 * (1 - np.exp(-1)), rel=0.03)
    assert est[-1] == pytest.approx(0.2, rel=1e-3)


@pytest.mark.parametrize("factory", [
    lambda model: SimBackend(model),  # RX-24F: Present Load, no current
    lambda model: XSimBackend(model, spec=XL430_W250),  # no current sensor
])
def test_servos_without_current_sensing_get_one_clear_error(factory):
    opened = []

    def recording(model):
        opened.append(factory(model))
        return opened[-1]

    with pytest.raises(ValueError, match="report no motor current"):
        servo_observers(OMX, recording, joint=SHOULDER, duration=3.0)
    assert opened[0]._closed


@pytest.mark.parametrize("kw,why", [({"duration": 2.0}, "--duration must be at least 3"),
                                    ({"joint": 4}, "joint must be an index"),
                                    ({"applied": 0.0}, "--applied must not be 0"),
                                    ({"g_reac": 0.0}, "g_reac must be > 0")])
def test_bad_servo_run_arguments_are_refused_before_the_servos_are_opened(kw, why):
    def factory(model):
        raise AssertionError("opened")

    with pytest.raises(ValueError, match=why):
        servo_observers(OMX, factory, **{"joint": SHOULDER, **kw})


@pytest.mark.parametrize("argv,why", [
    (["--joint", "1"], "--joint is for the servos"),
    (["--backend", "serial", "--port", "/dev/null", "--joint", "1", "--step", "1"],
     "--step is for the simulation"),
    (["--backend", "serial", "--port", "/dev/null"], "--joint: name the joint"),
    (["--backend", "serial", "--port", "/dev/null", "--joint", "1", "--pose", "0,0"],
     "--pose"),
    # the RTOB's cut-off is for the servos too: checked before the port is opened
    (["--backend", "serial", "--port", "/dev/null", "--joint", "1", "--g-reac", "0"],
     "g_reac must be > 0"),
])
def test_options_of_the_other_backend_are_refused(argv, why, capsys):
    assert main(["experiment", "observers", *argv]) == 2
    err = capsys.readouterr().err
    assert why in err and err.count("\n") == 1
