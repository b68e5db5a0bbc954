"""``armlab bench --peers``: armlab beside MuJoCo and Pinocchio on the same URDF."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from armlab.app.commands.cli import main
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import rnea

ROOT = Path(__file__).resolve().parents[1]


def test_without_the_extra_peers_says_how_to_install_it_in_one_line():
    """The peers are optional: where they cannot be imported, one line and exit 2."""
    hide = ("import sys; sys.modules['mujoco'] = None; sys.modules['pinocchio'] = None; "
            "from armlab.app.commands.cli import main; "
            "sys.exit(main(['bench', '--peers', '--quick']))")
    run = subprocess.run([sys.executable, "-c", hide], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install -e '.[bench]'" in lines[0], run.stderr
    assert "mujoco" in lines[0] and "pin" in lines[0]


def test_an_unknown_bench_group_is_named(capsys):
    assert main(["bench", "--only", "nope"]) == 2
    err = capsys.readouterr().err
    assert "no bench 'nope'" in err and "kinematics" in err


@pytest.mark.slow
def test_the_peers_agree_with_armlab_on_the_same_urdf_and_report_every_figure():
    pytest.importorskip("pinocchio")
    mujoco = pytest.importorskip("mujoco")
    import pinocchio as pin

    from armlab.app.benches.peers import mujoco_model, pinocchio_ik, run

    arm = load_robot("receptionist_arm")
    q, qd, qdd = np.array([0.3, -0.5, 1.1]), np.array([0.4, -0.2, 0.6]), np.array([1.0, 2, 3])
    mm = mujoco_model(str(arm.urdf_path))
    md = mujoco.MjData(mm)
    md.qpos[:], md.qvel[:], md.qacc[:] = q, qd, qdd
    mujoco.mj_inverse(mm, md)
    # the same physics (MuJoCo's bound mass on the massless joint link is 1e-9 kg)
    np.testing.assert_allclose(md.qfrc_inverse, rnea(arm, q, qd, qdd), atol=1e-6)
    pm = pin.buildModelFromUrdf(str(arm.urdf_path))
    pd = pm.createData()
    np.testing.assert_allclose(pin.rnea(pm, pd, q, qd, qdd), rnea(arm, q, qd, qdd), atol=1e-9)
    target = arm.fk(q)[:3, 3]
    q_ik, reached = pinocchio_ik(pm, pd, pm.getFrameId("hand"),
                                 (arm.base_pose @ np.append(target, 1.0))[:3], arm.neutral())
    assert reached and np.linalg.norm(arm.fk(q_ik)[:3, 3] - target) < 1e-4

    figures = run(quick=True)
    for key in ("peer_rnea_us", "armlab_rnea_us", "peer_ik_us", "armlab_rmrc_us",
                "peer_plant_steps_per_s", "armlab_plant_steps_per_s", "ratio_rnea",
                "ratio_ik", "ratio_plant", "peer_ik_set_us", "armlab_rmrc_set_us",
                "ratio_ik_set", "peer_plant_wall_steps_per_s", "armlab_plant_wall_steps_per_s",
                "ratio_plant_wall"):
        assert math.isfinite(figures[key]) and figures[key] > 0, key
    assert figures["peer_ik_solved"] == 1.0


@pytest.mark.slow
def test_the_bus2_cycles_alternate_on_one_paced_emulator_and_report_their_figures():
    """armlab's bus and the SDK take turns on one port; neither beats the paced wire."""
    pytest.importorskip("dynamixel_sdk")
    from armlab.app.benches.bus import OMX_SERVOS, protocol2_cycle_bytes
    from armlab.app.benches.peers import bus2_cycles
    from armlab.hardware.servos.servo_spec import wire_time

    out = bus2_cycles(True)
    assert set(out) == {"armlab_bus2_cycle_ms", "peer_bus2_cycle_ms", "ratio_bus2"}
    bound_ms = wire_time(protocol2_cycle_bytes(OMX_SERVOS), 1e6) * 1e3
    for name in ("armlab_bus2_cycle_ms", "peer_bus2_cycle_ms"):
        assert math.isfinite(out[name]) and out[name] > 0.95 * bound_ms, out
    assert math.isfinite(out["ratio_bus2"]) and out["ratio_bus2"] > 0, out


@pytest.mark.slow
def test_the_feetech_cycles_alternate_with_feetech_s_own_sdk_and_report_their_figures():
    """armlab's bus and Feetech's SDK (scservo_sdk) take turns on one paced emulator of the
    SO-101's six STS3215; neither beats the paced wire, and the wire bound is the bytes of
    one STS backend cycle (190 bytes, 1.90 ms at 1 Mbps)."""
    pytest.importorskip("scservo_sdk")
    from armlab.app.benches.peers import bus_sts_cycles

    out = bus_sts_cycles(True)
    assert set(out) == {"armlab_bus_sts_cycle_ms", "peer_bus_sts_cycle_ms", "ratio_bus_sts",
                        "bus_sts_wire_bound_ms", "ratio_bus_sts_wire"}
    assert out["bus_sts_wire_bound_ms"] == pytest.approx(1.90)
    for name in ("armlab_bus_sts_cycle_ms", "peer_bus_sts_cycle_ms"):
        assert math.isfinite(out[name]) and out[name] > 0.95 * out["bus_sts_wire_bound_ms"], out
    assert math.isfinite(out["ratio_bus_sts"]) and out["ratio_bus_sts"] > 0, out
    assert out["ratio_bus_sts_wire"] == pytest.approx(
        out["armlab_bus_sts_cycle_ms"] / out["bus_sts_wire_bound_ms"], rel=1e-9)
