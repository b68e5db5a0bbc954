"""The SO-101's STS3215s emulated behind a real pseudo-terminal (``armlab emulate --robot
so101`` as a subprocess): the scan finds them, a Feetech bus moves them, and LeRobot's
calibration file becomes the lab's joint map.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest
from _emulator import ROOT, emulator
from _helpers import wait_for

from armlab.hardware.backends.joint_map import load_joint_map
from armlab.hardware.backends.lerobot_calibration import joint_map_from_lerobot
from armlab.hardware.families.feetech import packets as ft
from armlab.hardware.families.feetech.table import CENTRE, STS3215_TABLE
from armlab.hardware.wire.bus import Bus
from armlab.hardware.wire.scan import scan
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator over a pseudo-terminal

SO101 = ("--robot", "so101")
ARM_IDS = [1, 2, 3, 4, 5]  # LeRobot's shoulder_pan .. wrist_roll
#: s of reply timeout: generous, the five-joint plant is the slowest the emulator runs
#: and the test machine is shared
MARGIN = 0.3


def test_scan_finds_the_so101_s_sts3215s_and_their_protocol():
    with emulator(*SO101) as emu:
        found = scan(emu.port, (1_000_000,), ids=range(0, 8), margin=MARGIN)
        assert "Feetech STS" in emu.stderr()
    assert [(f.servo_id, f.model, f.model_number, f.protocol) for f in found] == \
        [(i, "STS3215", 777, "sts") for i in [*ARM_IDS, 6]]  # and the jaw's servo
    assert all(f.baud_value == 0 and f.cw_limit == 0 and f.ccw_limit == 4095 for f in found)


def test_a_feetech_only_scan_pings_ids_0_to_252():
    with emulator(*SO101) as emu:
        found = scan(emu.port, (1_000_000,), ids=[4, 251, 252, 253], margin=MARGIN,
                     protocols=("sts",))
    assert [(f.servo_id, f.protocol) for f in found] == [(4, "sts")]


def test_a_feetech_bus_moves_the_emulated_arm_with_one_sync_write():
    with emulator(*SO101) as emu, Bus(emu.port, protocol="sts", timeout_margin=MARGIN) as bus:
        assert [bus.identify(i).name for i in ARM_IDS] == ["STS3215"] * 5
        start = bus.sync_read(56, 2, ARM_IDS)
        here = {i: STS3215_TABLE.decode("present_position", start[i]) for i in ARM_IDS}
        bus.sync_write(40, 1, {i: b"\x01" for i in ARM_IDS})  # torque on, all at once
        goal = dict(here)
        goal[4] = here[4] + 300  # wrist_flex by 26°
        bus.sync_write(42, 2, {i: STS3215_TABLE.encode("goal_position", goal[i])[1]
                               for i in ARM_IDS})

        def positions() -> dict[int, int]:
            data = bus.sync_read(56, 2, ARM_IDS)
            return {i: STS3215_TABLE.decode("present_position", data[i]) for i in ARM_IDS}

        wait_for(lambda: abs(positions()[4] - goal[4]) < 40, 30, "wrist_flex at its goal")
        assert bus.read(4, "torque_enable") == 1
        assert bus.read_si(4, "present_voltage") == pytest.approx(5.0)  # the kit's supply
        # the status packets are Feetech's: an error byte of 0 while all is well
        assert bus.errors[4] == ft.ErrorBits(0)
        bus.write(4, "torque_limit", 0)  # no torque: no load
        wait_for(lambda: bus.read(4, "present_load") == 0, 10, "no load without torque")


def _calibration(tmp_path, **ranges):
    """A LeRobot-style calibration file: the middle of each range at raw CENTRE + 100
    (shoulder_lift mounted the other way round), the gripper included."""
    names = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll",
             "gripper"]
    data = {}
    for k, name in enumerate(names):
        lo, hi = ranges.get(name, (CENTRE + 100 - 500, CENTRE + 100 + 500))
        data[name] = {"id": k + 1, "drive_mode": int(name == "shoulder_lift"),
                      "homing_offset": -37 * k, "range_min": lo, "range_max": hi}
    path = tmp_path / "so101_follower.json"
    path.write_text(json.dumps(data))
    return path


def test_a_lerobot_calibration_gives_the_expected_map(tmp_path):
    model = load_robot("so101")
    jmap = joint_map_from_lerobot(_calibration(tmp_path), model)
    unit = 2 * math.pi / 4096
    assert jmap.servo == "STS3215" and jmap.ids == tuple(ARM_IDS)
    lift = jmap.joints[1]
    assert (lift.sign, lift.offset) == (-1, pytest.approx(100 * unit))
    pan = jmap.joints[0]
    assert (pan.sign, pan.offset) == (1, pytest.approx(-100 * unit))
    assert (pan.lower, pan.upper) == (pytest.approx(-500 * unit), pytest.approx(500 * unit))
    # the middle of the range is the joint's zero, whichever way the servo turns
    assert jmap.to_joint([100 * unit] * 5) == pytest.approx([0.0] * 5)
    # the gripper's motor: its range laid onto the URDF's jaw, range_min closed
    g = jmap.gripper
    assert (g.servo_id, g.joint) == (6, "gripper")
    assert (g.closed_angle, g.open_angle) == (pytest.approx(-400 * unit),
                                              pytest.approx(600 * unit))
    assert (g.lower, g.upper) == (pytest.approx(math.radians(-10)),
                                  pytest.approx(math.radians(100)))


def test_a_range_past_the_urdf_s_limits_is_refused_naming_the_joint(tmp_path):
    model = load_robot("so101")
    bad = _calibration(tmp_path, elbow_flex=(100, 4000))  # ±170°, the URDF allows ±96.8°
    with pytest.raises(ValueError, match="joint 'elbow_flex' \\(servo ID 3\\): its range"):
        joint_map_from_lerobot(bad, model)


def test_scan_writes_the_map_from_the_calibration_and_the_servos_that_answer(tmp_path):
    out = tmp_path / "so101.toml"
    with emulator(*SO101) as emu:
        run = subprocess.run(
            [sys.executable, "-m", "armlab.app", "scan", "--port", emu.port, "--ids", "0-7",
             "--baud", "1000000", "--timeout", str(MARGIN), "--robot", "so101",
             "--calibration", str(_calibration(tmp_path)), "--write-map", str(out)],
            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "STS3215" in run.stdout and "Feetech STS" in run.stdout
    model = load_robot("so101")
    jmap = load_joint_map(out, model)
    want = joint_map_from_lerobot(tmp_path / "so101_follower.json", model)
    assert jmap.protocol == "sts"
    assert [(j.name, j.servo_id, j.sign) for j in jmap.joints] == \
        [(j.name, j.servo_id, j.sign) for j in want.joints]
    for got, exp in zip(jmap.joints, want.joints, strict=True):  # degrees to 4 decimals
        assert (got.offset, got.lower, got.upper) == \
            pytest.approx((exp.offset, exp.lower, exp.upper), abs=1e-5)
    g, exp = jmap.gripper, want.gripper
    assert (g.servo_id, g.joint) == (exp.servo_id, exp.joint)
    assert (g.closed_angle, g.open_angle) == pytest.approx((exp.closed_angle, exp.open_angle),
                                                           abs=1e-5)
