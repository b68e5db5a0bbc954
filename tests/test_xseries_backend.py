"""XSeriesBackend on emulated X-series servos over a real pty: the OpenManipulator-X's
four XM430-W350 (IDs 11..14, protocol 2.0), as `armlab serve --robot open_manipulator_x
--backend serial --port P` opens them.

The configuration sequence (current-based position control, Goal Current); one
SYNC_READ and one SYNC_WRITE a period; the arm reaches a goal and reports its torque
from the measured current; a goal beyond a servo's Max Position Limit never leaves the
process; E-STOP switches every torque off; a map naming X-series servos opens this
backend through the lab's own factory. Each X-series model the lab knows (XM430-W350,
XL330-M288, and the XL430-W250 without a current sensor) is configured for what it
senses, reaches a goal and reports the torque that holds the arm up. A servo's hardware
alert (``armlab emulate --fault``) stops the served lab with one message naming the servo
and its Hardware Error Status, and Reset REBOOTs it.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
import tomllib

import numpy as np
import pytest
from _emulator import ROOT, emulator, goal_positions
from _helpers import client_of, confirm_clear, wait_for

from armlab.app.arm.backends import make_backend
from armlab.app.lab.server import Lab, ServeOptions
from armlab.hardware.backends.joint_map import default_joint_map
from armlab.hardware.families.xseries import packets as p2
from armlab.hardware.families.xseries.backend import XSeriesBackend
from armlab.hardware.families.xseries.table import (
    CENTRE,
    CURRENT_POSITION_D_GAIN,
    OperatingMode,
    x_table_for,
)
from armlab.hardware.family_parts import open_servo_backend
from armlab.hardware.wire.bus import Bus
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.dynamics import gravity_torques

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

OMX = load_robot("open_manipulator_x")
IDS = (11, 12, 13, 14)
MARGIN = 0.1  # s of reply timeout: generous, the test machine is shared


def _requests(backend: XSeriesBackend) -> int:
    """Requests sent so far (packets less retries: a loaded machine may cause retries)."""
    return backend.bus.stats.transactions - backend.bus.stats.retries


def test_configured_then_it_moves_reports_torque_and_stops(tmp_path):
    with emulator("--robot", "open_manipulator_x", log_dir=tmp_path) as emu:
        b = make_backend("serial", OMX, port=emu.port, timeout_margin=MARGIN)
        try:
            assert isinstance(b, XSeriesBackend) and b.n == 4
            text = "\n".join(b.configuration)
            for step in ("torque off", "return delay 0", "operating mode 5 (current-based",
                         "status return level 1", "goal current 100%", "position D gain 800",
                         "baud 1000000"):
                assert step in text
            for i in IDS:
                assert b.bus.read(i, "operating_mode") == OperatingMode.CURRENT_BASED_POSITION
                assert b.bus.read(i, "return_delay_time") == 0
                assert b.bus.read(i, "goal_current") == 1193
                assert b.bus.read(i, "position_d_gain") == CURRENT_POSITION_D_GAIN
            sent = _requests(b)
            state = b.read()
            assert _requests(b) == sent + 1  # one SYNC_READ for four servos
            b.set_torque(True)
            goal = state.position + np.array([0.0, math.radians(20), 0.0, 0.0])
            sent = _requests(b)
            b.write(goal, np.full(4, 1.0))
            assert _requests(b) == sent + 1  # one SYNC_WRITE

            def there() -> bool:
                return abs(b.read().position[1] - goal[1]) < math.radians(3)

            wait_for(there, 30, "joint 2 at its goal")
            held = b.read()
            assert abs(held.load[1]) > 0.05  # N·m from the measured current, holding it up
            assert all(held.torque_on)
            assert b.estop()
            wait_for(lambda: not any(b.bus.read(i, "torque_enable") for i in IDS), 10,
                     "every torque off")
        finally:
            b.close()


def test_a_goal_beyond_a_servo_s_limit_never_leaves_the_process(tmp_path):
    with emulator("--robot", "open_manipulator_x", log_dir=tmp_path) as emu:
        top = CENTRE + 400  # about +35°
        with Bus(emu.port, protocol=2, timeout_margin=MARGIN) as bus:  # a technician's limit
            bus.write(13, "max_position_limit", top)
        b = XSeriesBackend(OMX, emu.port, timeout_margin=MARGIN)
        try:
            assert b.upper[2] <= math.radians(400 * 360 / 4096) + 1e-9
            b.set_torque(True)
            b.write(np.array([0.0, 0.0, 1.3, 0.0]), np.full(4, 1.0))  # 74°: past it
            b.read()  # a round trip: the emulator has logged the SYNC_WRITE
            sent = goal_positions(emu.packets("rx"), 13)
            assert sent and max(sent) <= top
        finally:
            b.close()


def test_the_lab_on_open_manipulator_x_scan_map_serve_slider_reaches_the_servos(tmp_path):
    """What a teacher with an OpenManipulator-X does: scan, draft the map, serve; a slider
    on the page turns the real (here emulated) joint."""
    map_path = tmp_path / "omx.toml"
    with emulator("--robot", "open_manipulator_x") as emu:
        scan = subprocess.run(
            [sys.executable, "-m", "armlab.app", "scan", "--port", emu.port, "--ids", "10-15",
             "--baud", "1000000", "--write-map", str(map_path), "--robot",
             "open_manipulator_x"], cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert scan.returncode == 0, scan.stderr
        data = tomllib.loads(map_path.read_text())
        assert data["servo"] == "XM430-W350" and data["protocol"] == 2.0
        assert [j["id"] for j in data["joints"]] == list(IDS)
        assert data["gripper"]["id"] == 15  # the servo after the chain's: its gripper
        lab = Lab(ServeOptions(robot="open_manipulator_x", backend="serial", port=emu.port,
                               joint_map=str(map_path), http_port=0))
        try:
            lesson = lab.lesson
            assert isinstance(lesson.backend, XSeriesBackend)
            confirm_clear(lesson)  # a drafted map: torque off until a person confirms
            with client_of(lab.server, token=lab.token) as client:
                client.wait_for(lambda: client.shows("joint2 °"), 60.0,
                                "the joint2 slider")
                client.set_value("joint2 °", 25.0)

                def measured() -> np.ndarray:
                    snap = lesson.loop.recorder.snapshot(0.1)
                    return snap["q"][-1] if len(snap["t"]) else np.full(4, np.nan)

                wait_for(lambda: abs(math.degrees(measured()[1]) - 25.0) < 3.0, 60.0,
                         "the joint2 servo to reach 25°")
                assert lesson.loop.status.fault is None
        finally:
            lab.close()


def _at_rest(b: XSeriesBackend, what: str, *, also=lambda state: True, span: float = 0.3):
    """Poll until every joint stayed still (under 0.05 rad/s) for ``span`` s and ``also``
    holds; the last state read."""
    still: list = []

    def resting() -> bool:
        state = b.read()
        if np.any(np.abs(state.velocity) >= 0.05):
            still.clear()
        still.append((time.monotonic(), state))
        return still[-1][0] - still[0][0] >= span and bool(also(state))

    wait_for(resting, 30, what)
    return still[-1][1]


def _stiffness(servo: str, mode: int) -> float:
    """N·m per rad of position error the servo pushes back with at its factory Position P
    Gain (KPP = P/128 current counts, or PWM counts of 885 for full duty, per count)."""
    table = x_table_for(servo)
    spec = table.spec
    per_rad = table.item("position_p_gain").default / 128 / spec.position_unit
    if mode == OperatingMode.CURRENT_BASED_POSITION:
        return per_rad * spec.current_unit * spec.torque_constant
    return per_rad / 885 * spec.stall_torque


@pytest.mark.parametrize(("servo", "mode", "bound", "limit"), [
    ("XM430-W350", OperatingMode.CURRENT_BASED_POSITION, "goal_current", "current_limit"),
    ("XL330-M288", OperatingMode.CURRENT_BASED_POSITION, "goal_current", "current_limit"),
    ("XL430-W250", OperatingMode.POSITION, "goal_pwm", "pwm_limit"),  # no current sensor
])
def test_each_x_model_is_set_up_for_what_it_senses_and_reports_the_arm_s_weight(
        servo, mode, bound, limit):
    """An OpenManipulator-X built with ``servo`` (its map names that model): the mode and
    torque bound fit the servo, the shoulder reaches a goal, and the torque read (current
    x torque constant, or the XL430's Present Load x stall torque) holds the arm up.

    With the torque off the arm folds onto its shoulder's stop, as a real one does. The
    XL330's 0.52 N·m cannot lift the outstretched arm from there (1.5 N·m for the XL430,
    4.1 for the XM430), so the elbow is folded first, as with any weak arm; then the
    shoulder goes back to -30°, where it and the elbow carry the arm's weight."""
    table = x_table_for(servo)
    jmap = default_joint_map(OMX, servo=servo)
    assert jmap.servo == servo and jmap.ids == IDS
    with emulator("--robot", "open_manipulator_x", "--servo", servo) as emu:
        b = open_servo_backend(OMX, emu.port, joint_map=jmap, timeout_margin=MARGIN)
        try:
            assert isinstance(b, XSeriesBackend) and b.table is table
            assert b.mode == mode and b.senses_current == (servo != "XL430-W250")
            assert f"operating mode {mode} (" in "\n".join(b.configuration)
            for i in IDS:
                assert b.bus.tables[i] is table  # the model number each servo answered
                assert b.bus.read(i, "operating_mode") == mode
                assert b.bus.read(i, bound) == table.item(limit).default  # torque_limit 1.0
            volts = b.bus.read(11, "present_input_voltage")  # the model's own supply
            assert table.item("min_voltage_limit").default < volts < \
                table.item("max_voltage_limit").default
            _at_rest(b, "the arm at rest on its shoulder's stop",
                     also=lambda state: state.position[1] > math.radians(80))
            b.set_torque(True)
            fold = b.read().position.copy()
            fold[2] = math.radians(45)  # the XL330 sags ~15°, well off the elbow's stop
            b.write(fold, np.full(4, 1.0))
            _at_rest(b, "the elbow folded", also=lambda state: state.position[2] > 0.3)
            goal = fold.copy()
            goal[1] = math.radians(-30)
            b.write(goal, np.full(4, 1.0))
            state = _at_rest(b, f"the {servo} shoulder at rest near -30°",
                             also=lambda state: state.position[1] < 0.0)
            g = gravity_torques(OMX, state.position)  # what holds the arm still there
            # position control sags under the weight by |g| / stiffness (XL330: ~13°)
            sag = abs(g[1]) / _stiffness(servo, mode)
            assert abs(state.position[1] - goal[1]) < sag + math.radians(3)
            for k in (1, 2):  # shoulder and elbow carry the arm's weight
                assert abs(state.load[k]) > 0.05 and np.sign(state.load[k]) == np.sign(g[k])
                assert state.load[k] == pytest.approx(g[k], abs=0.06)  # friction 0.03
            assert all(state.torque_on) and not any(state.alarms)
        finally:
            b.close()


def _packets_to(emu, servo_id: int, instruction: int) -> list[p2.InstructionPacket]:
    """The instruction packets of one kind the emulator received for ``servo_id``."""
    packets = (p2.decode_instruction(raw) for raw in emu.packets("rx"))
    return [k for k in packets if k.servo_id == servo_id and k.instruction == instruction]


def test_a_hardware_alert_stops_the_lab_naming_the_servo_and_reset_reboots_it(
        tmp_path, capfd):
    """``emulate --fault joint2:overload@1``: after 1 s of torque on, servo 12 raises
    Overload in its Hardware Error Status and, the bit being in its Shutdown register,
    switches its own torque off; every reply carries the alert bit. The backend READs
    address 70 of that servo once; the loop stops with the torque off and one message
    naming the servo, the flag and the value, which the page shows. Reset REBOOTs the
    servo and the arm is held again."""
    with emulator("--robot", "open_manipulator_x", "--fault", "joint2:overload@1",
                  log_dir=tmp_path) as emu:
        with Lab(ServeOptions(robot="open_manipulator_x", backend="serial", port=emu.port,
                              http_port=0)) as lab:
            lesson = lab.lesson
            loop, bus = lesson.loop, lesson.backend.bus
            with client_of(lab.server, token=lab.token) as page:
                wait_for(lambda: loop.status.fault is not None, 60, "the loop to stop")
                st = loop.status
                said = "servo 12: Overload (Hardware Error Status 0x20), cleared by a REBOOT"
                assert st.fault.startswith(f"joint joint2: {said}"), st.fault
                assert not (st.active or st.torque_on or st.torque_off_unsent or st.link_down)
                page.wait_for(lambda: any(said in str(e.props.get("content", ""))
                                          for e in page.gui.values()), 30,
                              "the page to show the alert")
                reads = [k for k in _packets_to(emu, 12, p2.Instruction.READ)
                         if k.params[:2] == (70).to_bytes(2, "little")]
                assert len(reads) == 1  # asked once
                assert bus.read(12, "hardware_error_status") == p2.HardwareError.OVERLOAD
                assert bus.errors[12].alert
                assert not any(bus.read(i, "torque_enable") for i in IDS)
                assert not _packets_to(emu, 12, p2.Instruction.REBOOT)
                page.click("Reset (after E-STOP or a fault)")
                wait_for(lambda: loop.status.active and loop.status.torque_on, 60,
                         "the arm held again after Reset")
                assert len(_packets_to(emu, 12, p2.Instruction.REBOOT)) == 1
                assert bus.read(12, "hardware_error_status") == 0
                assert not bus.errors[12].alert and loop.status.fault is None
                assert not page.notifications  # told by the status line, not a pop-up
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-2000:]
