"""The SO-101 on its emulated STS3215s over a real pseudo-terminal (``armlab emulate
--robot so101`` as a subprocess), as ``armlab serve --robot so101 --backend serial --port
P`` drives it: the scan finds six servos (five joints and the jaw), the STS backend
configures them (P coefficient and torque limit, logged) and never sends a goal past a
joint's or a servo's limit, the arm lesson holds, follows the hand target and grips; the
compliance loop's step and push give the simulated SO-101's figures; and the faults are
told as on the other families: a lost link, a servo that stops answering, an overload or
overheating bit in the status byte, each one message naming the joint and the servo,
torque off sent where it can be, said truthfully where it cannot.

The emulator steps its plant at 2 ms (``--dt 0.002``): five joints and the jaw at 1 ms
took some 70 % of a core, which this shared two-core machine cannot give it in real time
(its plant clock then slips and the servos lag the wall clock); the simulated SO-101 the
figures are compared with steps at the same 2 ms.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import signal
import subprocess
import sys
import tomllib

import numpy as np
import pytest
from _emulator import ROOT, emulator, pull_the_cable
from _helpers import client_of, confirm_clear, hand_at_rest, wait_for

from armlab.app.arm.backends import loop_over, make_backend
from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons.arm import ArmLesson
from armlab.control.commands import Reset, RunTrajectory
from armlab.control.params import DEFAULT
from armlab.control.trajectory import hold
from armlab.hardware.backends.gripper import so101_gripper
from armlab.hardware.families.feetech import packets as ft
from armlab.hardware.families.feetech.backend import GOAL_AT, StsBackend
from armlab.hardware.families.feetech.sim_backend import StsSimBackend
from armlab.hardware.families.feetech.table import CENTRE, STS3215, STS3215_TABLE
from armlab.hardware.wire.bus import Bus
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

SO101 = load_robot("so101")
EMULATE = ("--robot", "so101", "--dt", "0.002")
STEP_DT = 0.002  #: s, the simulated SO-101's plant step (the emulator's)
MARGIN = 0.3  #: s of reply timeout: generous, the machine is shared
#: N·m on shoulder_lift (a weight hung at the joint): the push both arms get
PUSH_NM = 0.3
#: the pose both arms are brought to and the 15° elbow step from it
POSE = np.radians([0.0, -30.0, 60.0, 20.0, 0.0])
STEP = POSE + np.radians([0.0, 0.0, 15.0, 0.0, 0.0])


def _goals(packets: list[bytes]) -> dict[int, list[int]]:
    """Goal Positions per servo ID in the STS SYNC_WRITEs of 42..47 the emulator received."""
    out: dict[int, list[int]] = {}
    for raw in packets:
        packet = ft.decode_instruction(raw)
        p = packet.params
        if packet.instruction != ft.Instruction.SYNC_WRITE or p[0] != GOAL_AT:
            continue
        size = p[1]
        for k in range(2, len(p), size + 1):
            out.setdefault(p[k], []).append(
                STS3215_TABLE.decode("goal_position", bytes(p[k + 1 : k + 3])))
    return out


def _torque_off_broadcasts(packets: list[bytes]) -> int:
    """The broadcast Torque Enable 0 WRITEs the emulator received (E-STOP)."""
    return sum(raw == ft.write(ft.BROADCAST_ID, 40, b"\x00") for raw in packets)


def _hand(lesson: ArmLesson) -> np.ndarray:
    snap = lesson.loop.recorder.snapshot(0.1)
    return lesson.model.fk(snap["q"][-1])[:3, 3] if len(snap["t"]) else np.full(3, np.nan)


def _q(lesson: ArmLesson) -> np.ndarray:
    snap = lesson.loop.recorder.snapshot(0.1)
    return snap["q"][-1] if len(snap["t"]) else np.full(lesson.model.n, np.nan)


# -- scan, configuration, limits ---------------------------------------------------------


def test_scan_finds_six_sts3215s_and_drafts_a_map_with_the_jaw(tmp_path):
    out = tmp_path / "so101.toml"
    with emulator(*EMULATE) as emu:
        run = subprocess.run(
            [sys.executable, "-m", "armlab.app", "scan", "--port", emu.port, "--ids", "0-7",
             "--baud", "1000000", "--timeout", str(MARGIN), "--robot", "so101",
             "--write-map", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    rows = [line.split() for line in run.stdout.splitlines() if "STS3215" in line]
    assert [int(r[0]) for r in rows] == [1, 2, 3, 4, 5, 6]
    data = tomllib.loads(out.read_text())
    assert (data["servo"], data["protocol"]) == ("STS3215", "sts")
    assert [(j["name"], j["id"]) for j in data["joints"]] == \
        list(zip(SO101.joint_names, range(1, 6), strict=True))
    assert (data["gripper"]["id"], data["gripper"]["joint"]) == (6, "gripper")


def test_configured_logged_and_no_goal_past_a_limit_leaves_the_process(tmp_path, caplog):
    """The configuration sequence is logged step by step and lands in the servos; with a
    technician's Max Position Limit on the elbow's servo, goals past it, past wrist_roll's
    URDF limit and past the jaw's open end are clamped before they are sent."""
    with emulator(*EMULATE, log_dir=tmp_path) as emu:
        top = CENTRE + 400  # about +35° on the elbow's servo
        with Bus(emu.port, protocol="sts", timeout_margin=MARGIN) as bus:
            bus.write(3, "lock", 0)  # an STS takes EEPROM writes only unlocked
            bus.write(3, "max_position_limit", top)
            bus.write(3, "lock", 1)
        with caplog.at_level(logging.INFO, logger="armlab.sts"):
            b = make_backend("serial", SO101, port=emu.port, timeout_margin=MARGIN)
        try:
            assert isinstance(b, StsBackend) and b.n == 5 and b.senses_current
            for step in ("EEPROM unlocked (Lock 0)", "response status level 0",
                         "operating mode 0 (position)", "P coefficient 16",
                         "servo 2 (shoulder_lift): torque limit 100% (1000 of 1000)",
                         "servo 6 (gripper gripper): torque limit 50% (500 of 1000)",
                         "baud 1000000", "EEPROM locked (Lock 1)"):
                assert step in caplog.text, step
                assert any(step in line for line in b.configuration), step
            for i in range(1, 6):
                assert b.bus.read(i, "p_coefficient") == 16
                assert b.bus.read(i, "torque_limit") == 1000
                assert b.bus.read(i, "lock") == 1
            assert b.bus.read(6, "torque_limit") == 500
            assert b.upper[2] <= STS3215.raw_to_position(top) + 1e-9
            b.set_torque(True)
            assert b.set_gripper(5.0) == pytest.approx(b.gripper_range[1])  # past open
            b.write(np.array([0.0, 0.0, 1.5, 0.0, 3.0]), np.full(5, 1.0))
            b.read()  # a round trip: the emulator has logged the SYNC_WRITE
            goals = _goals(emu.packets("rx"))
            assert goals[3] and max(goals[3]) <= top
            assert max(goals[5]) <= STS3215.position_to_raw(SO101.upper[4])
            assert max(goals[6]) <= STS3215.position_to_raw(b.gripper.open_angle)
        finally:
            b.close()


def test_the_bench_s_sts_wire_bound_counts_the_bytes_of_one_backend_cycle(tmp_path):
    """``armlab bench --only bus`` sets ``bus_sts_cycle_median_ms`` beside a wire bound of
    :func:`~armlab.app.benches.bus.sts_cycle_bytes` × 10 bits / baud: the bytes of one
    cycle are what the STS backend sends and the six servos answer (one SYNC_WRITE of the
    goals, one SYNC_READ and its six answers)."""
    from armlab.app.benches.bus import SO101_SERVOS, sts_cycle_bytes

    with emulator(*EMULATE, log_dir=tmp_path) as emu:
        b = StsBackend(SO101, emu.port, timeout_margin=MARGIN)
        try:
            state = b.read()
            b.set_gripper(0.5)
            cycle = emu.cycle_traffic(b, state.position, np.full(5, 1.0))
        finally:
            b.close()
    assert [tag for _, tag, _ in cycle] == ["rx", "rx"] + ["tx"] * SO101_SERVOS
    assert sum(len(raw) for _, _, raw in cycle) == sts_cycle_bytes(SO101_SERVOS) == 190


# -- the lessons -------------------------------------------------------------------------


def test_the_arm_lesson_holds_follows_the_target_and_grips_on_serial():
    with emulator(*EMULATE) as emu:
        with Lab(ServeOptions(robot="so101", backend="serial", port=emu.port,
                              http_port=0)) as lab:
            lesson = lab.lesson
            assert isinstance(lesson, ArmLesson) and isinstance(lesson.backend, StsBackend)
            loop = lesson.loop
            confirm_clear(lesson)  # no calibration: torque off until a person confirms
            wait_for(lambda: loop.status.active and np.all(np.isfinite(_hand(lesson))),
                     60, "the loop holding the arm")
            # it catches the arm falling (its torque was off); how long the catch takes
            # depends on the periods the loop gets, so wait for the arm at rest
            hand_at_rest(lesson)
            here, t1 = _hand(lesson), loop.status.t
            wait_for(lambda: loop.status.t > t1 + 1.0, 60, "a second of holding")
            assert np.linalg.norm(_hand(lesson) - here) < 0.003  # held where it was
            lesson.move_to(POSE)  # what the Joints sliders do
            wait_for(lambda: np.all(np.abs(_q(lesson) - POSE) < math.radians(2.0)), 60,
                     lambda: f"the arm at the sliders' pose (at {np.degrees(_q(lesson))}°)")
            start = _hand(lesson)
            goal = start + np.array([0.0, 0.02, -0.02])
            with client_of(lab.server, token=lab.token) as page:  # a person drags the target
                page.move_gizmo("/arm_target_base/target",
                                [tuple(start + f * (goal - start)) for f in (0.5, 1.0)])
                wait_for(lambda: np.linalg.norm(_hand(lesson) - goal) < 0.003, 90,
                         lambda: f"the hand at the target (at {_hand(lesson) - goal} m)")
            lesson.gripper.grip(0.8)  # the jaw to 46° (rad: the URDF's revolute jaw)
            wait_for(lambda: loop.gripper is not None
                     and abs(loop.gripper.position - 0.8) < 0.05, 60, "the jaw at 0.8 rad")
            assert loop.status.fault is None


def test_a_target_dragged_on_the_page_from_where_the_arm_was_caught_moves_it():
    """The serial SO-101 starts limp and is caught folded on its shoulder_lift limit; a
    person's first drag of the target through the page (2 cm aside and down, partly
    beyond the folded arm's reach) moves the hand towards it, with no fault (it was taken
    for unstable gains, torque off: tests/test_control_loop.py names why)."""
    with emulator(*EMULATE) as emu:
        with Lab(ServeOptions(robot="so101", backend="serial", port=emu.port,
                              http_port=0)) as lab:
            lesson, loop = lab.lesson, lab.lesson.loop
            confirm_clear(lesson)
            wait_for(lambda: loop.status.active and np.all(np.isfinite(_hand(lesson))),
                     60, "the loop holding the arm")
            t0 = loop.status.t
            wait_for(lambda: loop.status.t > t0 + 3.0, 60, "the arm caught where it fell")
            start = _hand(lesson)
            goal = start + np.array([0.0, 0.02, -0.02])
            with client_of(lab.server, token=lab.token) as page:
                page.move_gizmo("/arm_target_base/target",
                                [tuple(start + f * (goal - start)) for f in (0.5, 1.0)])
                wait_for(lambda: loop.status.fault is not None
                         or np.linalg.norm(_hand(lesson) - start) > 0.012, 90,
                         lambda: f"the hand towards the target (at {_hand(lesson) - goal} m)")
                assert loop.status.fault is None, loop.status.fault
                assert np.linalg.norm(_hand(lesson) - goal) < np.linalg.norm(start - goal)


def _figures(backend, *, realtime: bool) -> dict[str, float]:
    """Run the compliance loop over ``backend``: bring the arm to :data:`POSE`, then step
    the elbow 15°; the figures of the hold (under the push both arms carry) and the step."""
    loop = loop_over(backend, SO101, DEFAULT, realtime=realtime, history_s=30.0)
    loop.start()
    try:
        if loop.status.held_off:  # servos with no calibration: a person confirms
            loop.post(Reset())
        wait_for(lambda: loop.status.active, 60, "the loop holding")

        def settle(q: np.ndarray) -> dict[str, np.ndarray]:
            # the approach lasts as long as the way from where the arm is: the emulated
            # arm may have fallen onto its shoulder's limit before the loop caught it
            t0 = loop.status.t

            def there() -> bool:
                st = loop.status
                return st.fault is not None or (st.t > t0 + 0.5 and st.trajectory is None
                                                and not st.catching)

            loop.post(RunTrajectory(hold(q, 0.2), approach=True))
            wait_for(there, 120, "the approach and the hold run")
            t1 = loop.status.t
            wait_for(lambda: loop.status.t > t1 + 3.0, 120, "3 s of holding")
            assert loop.status.fault is None, loop.status.fault
            snap = loop.recorder.snapshot(0.3)
            return {k: np.nanmean(snap[k], axis=0) for k in ("q", "q_cmd", "tau_ext", "q_env")}

        held = settle(POSE)
        stepped = settle(STEP)
    finally:
        loop.shutdown(torque_off=True)
        backend.close()
    return {"tau_ext": float(held["tau_ext"][1]),
            "deflection_deg": math.degrees(held["q_env"][1]),
            "step_error_deg": math.degrees(stepped["q_cmd"][2] - stepped["q"][2]),
            "step_reached_deg": math.degrees(stepped["q"][2])}


def test_the_step_and_the_push_give_the_simulated_so101_s_figures():
    """The compliance loop (the lab's gains) over the emulated servos and over the
    simulated SO-101, each with :data:`PUSH_NM` on shoulder_lift (the emulator's
    ``--disturb``, the plant's joint torque): the external torque the loop estimates and
    the compliant deflection it gives way by, and where a 15° elbow step ends.

    Tolerances: the same firmware model and plant run behind both, but the two arms reach
    the pose from different sides (the emulated one fell with its torque off before the
    lab opened), so each stops somewhere in its gears' dry-friction band (±0.03 N·m a
    joint): the estimated torque may differ by twice that, 0.06 N·m, and the deflection
    (that torque over K_env) by 1°; the step ends within 0.5° (the friction band through
    the servo's P loop). Transients are not compared: the serial loop reads servos that
    answer a transaction late, on a machine whose load moves the emulator's clock."""
    backend = make_backend("sim", SO101, dt=STEP_DT)
    assert isinstance(backend, StsSimBackend)
    backend.plant.apply_joint_torque(1, PUSH_NM)
    sim = _figures(backend, realtime=True)
    assert abs(abs(sim["tau_ext"]) - PUSH_NM) < 0.06, sim  # the loop sees the push
    with emulator(*EMULATE, "--disturb", f"shoulder_lift:{PUSH_NM}@0") as emu:
        serial = _figures(make_backend("serial", SO101, port=emu.port,
                                       timeout_margin=MARGIN), realtime=True)
    assert serial["tau_ext"] == pytest.approx(sim["tau_ext"], abs=0.06), (serial, sim)
    assert serial["deflection_deg"] == pytest.approx(sim["deflection_deg"], abs=1.0), \
        (serial, sim)
    assert serial["step_error_deg"] == pytest.approx(sim["step_error_deg"], abs=0.5), \
        (serial, sim)
    assert serial["step_reached_deg"] == pytest.approx(sim["step_reached_deg"], abs=0.5)


# -- faults ------------------------------------------------------------------------------


def test_link_killed_mid_run_the_arm_lesson_says_torque_off_could_not_be_sent(capfd):
    from armlab.app.testing.wsclient import HeadlessClient

    with emulator(*EMULATE) as emu:
        with Lab(ServeOptions(robot="so101", backend="serial", port=emu.port,
                              http_port=0)) as lab:
            lesson = lab.lesson
            loop = lesson.loop
            confirm_clear(lesson)
            with HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
                page.wait_for(lambda: loop.status.active, timeout=60, what="the loop holding")
                pull_the_cable(emu, loop, lesson.status, page)
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-2000:]


def test_a_replugged_link_reconnects_configures_again_and_keeps_the_torque_off(tmp_path):
    """The emulator behind a stable name (``--link``, as /dev/serial/by-id) is killed: a
    read fails with one line; once it is back, :meth:`reconnect` finds the six servos,
    configures them again and leaves every torque off."""
    from armlab.control.backend import BackendError

    link = tmp_path / "usb-so101"
    with emulator(*EMULATE, "--link", str(link)) as emu:
        b = StsBackend(SO101, str(link), timeout_margin=MARGIN)
        b.set_torque(True)
        b.read()
        emu.stop(signal.SIGKILL)
        with pytest.raises(BackendError) as err:
            for _ in range(3):
                b.read()
        assert "\n" not in str(err.value)
    try:
        with emulator(*EMULATE, "--link", str(link)):
            lines = b.reconnect()
            assert any("P coefficient 16" in line for line in lines)
            state = b.read()
            assert not any(state.torque_on) and state.gripper is not None
            assert not any(b.bus.read(i, "torque_enable") for i in range(1, 7))
    finally:
        b.close()


def test_a_servo_that_stops_answering_is_named_with_its_joint_and_torque_off_is_sent(
        tmp_path, capfd):
    """``emulate --fault elbow_flex:silent@1``: servo 3 answers nothing after 1 s of torque
    on; the loop stops with one message naming the joint and the servo, and the broadcast
    torque off goes out (the link itself is fine), so the lab says torque off."""
    with emulator(*EMULATE, "--fault", "elbow_flex:silent@1", log_dir=tmp_path) as emu:
        with Lab(ServeOptions(robot="so101", backend="serial", port=emu.port,
                              http_port=0)) as lab:
            loop = lab.lesson.loop
            confirm_clear(lab.lesson)
            with client_of(lab.server, token=lab.token):
                wait_for(lambda: loop.status.fault is not None, 90, "the loop to stop")
                st = loop.status
                assert "joint elbow_flex: no reply" in st.fault and "servo 3" in st.fault, \
                    st.fault
                assert "\n" not in st.fault and len(st.fault) < 400
                assert not st.active and not st.torque_on and not st.torque_off_unsent
                wait_for(lambda: _torque_off_broadcasts(emu.packets("rx")) >= 1, 30,
                         "the broadcast torque off")
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-2000:]


def test_emulate_fault_takes_the_sts_status_bits_and_silent():
    from armlab.app.commands.emulate import parse_fault
    from armlab.hardware.families.feetech.firmware import SILENT

    names = SO101.joint_names
    assert parse_fault("elbow_flex:overheat@2", names, protocol="sts") == \
        (2, ft.ErrorBits.OVERHEAT, 2.0)
    assert parse_fault("0:silent@0", names, protocol="sts") == (0, SILENT, 0.0)
    with pytest.raises(ValueError, match="no flag 'electrical_shock'.*overcurrent"):
        parse_fault("1:electrical_shock@1", names, protocol="sts")


@pytest.mark.parametrize(("flag", "said"), [("overload", "overload (0x20)"),
                                            ("overheat", "overheating (0x04)")])
def test_a_status_error_bit_stops_the_lab_naming_joint_and_servo_and_reset_recovers(
        flag, said, tmp_path, capfd):
    """``emulate --fault shoulder_lift:FLAG@1``: after 1 s of torque on, servo 2's status
    byte carries the bit; the loop stops with torque off (sent: the broadcast is in the
    emulator's log) and one message naming the joint, the servo and the flag, which the
    page shows. Reset switches the torque on again, which clears it, and the arm is held."""
    with emulator(*EMULATE, "--fault", f"shoulder_lift:{flag}@1", log_dir=tmp_path) as emu:
        with Lab(ServeOptions(robot="so101", backend="serial", port=emu.port,
                              http_port=0)) as lab:
            lesson = lab.lesson
            loop = lesson.loop
            confirm_clear(lesson)
            with client_of(lab.server, token=lab.token) as page:
                wait_for(lambda: loop.status.fault is not None, 90, "the loop to stop")
                st = loop.status
                assert st.fault.startswith(f"joint shoulder_lift: servo 2: {said}"), st.fault
                assert "\n" not in st.fault
                assert not (st.active or st.torque_on or st.torque_off_unsent or st.link_down)
                wait_for(lambda: _torque_off_broadcasts(emu.packets("rx")) >= 1, 30,
                         "the broadcast torque off")
                page.wait_for(lambda: any(said in str(e.props.get("content", ""))
                                          for e in page.gui.values()), 30,
                              "the page to show the fault")
                page.click("Reset (after E-STOP or a fault)")
                wait_for(lambda: loop.status.active and loop.status.torque_on
                         and loop.status.fault is None, 60, "the arm held again after Reset")
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-2000:]


# -- the lab's own calibration -----------------------------------------------------------

#: degrees a person holds each joint at: its middle, one end, the other end
PLACES = {"shoulder_pan": (10.0, -80.0, 95.0), "shoulder_lift": (-5.0, 90.0, -95.0),
          "elbow_flex": (20.0, -70.0, 110.0), "wrist_flex": (0.0, -90.0, 90.0),
          "wrist_roll": (-30.0, -150.0, 120.0)}
JAW = {"closed": -5.0, "fully open": 90.0}  #: degrees of the jaw


def _calibrate(tmp_path, places: dict[str, tuple[float, float, float]]
               ) -> tuple[subprocess.CompletedProcess, str, list[str]]:
    """``armlab scan --calibrate`` against the emulator, a hand (``emulate --control``)
    holding each joint where each instruction asks; (the finished scan, its stdout's
    instructions, and the emulator's stderr)."""
    hand = tmp_path / "hand"
    out = tmp_path / "so101.toml"
    said = []
    with emulator(*EMULATE, "--control", str(hand)) as emu:
        wait_for(hand.exists, 30, "the emulator's control pipe")
        cmd = [sys.executable, "-m", "armlab.app", "scan", "--port", emu.port, "--ids", "0-7",
               "--baud", "1000000", "--timeout", str(MARGIN), "--robot", "so101",
               "--calibrate", "--write-map", str(out)]
        with subprocess.Popen(cmd, cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) as proc, \
                open(hand, "w") as pipe:
            for line in proc.stdout:  # one instruction a line; Enter once it is done
                said.append(line.strip())
                words = line.split()
                if line.startswith("Move "):
                    k = ["middle" in line, "one end" in line, "other end" in line].index(True)
                    pipe.write(f"hold {words[1]} {places[words[1]][k]}\n")
                elif line.startswith("Put the gripper"):
                    jaw = JAW["closed"] if "closed" in line else JAW["fully open"]
                    pipe.write(f"hold gripper {jaw}\n")
                else:
                    continue
                pipe.flush()
                proc.stdin.write("\n")
                proc.stdin.flush()
            proc.stdin.close()
            err = proc.stderr.read()
            code = proc.wait(timeout=60)
        assert "--control" not in emu.stderr(), emu.stderr()  # every line taken
    return subprocess.CompletedProcess(cmd, code, "", err), str(out), said


def test_the_guided_calibration_writes_the_map_from_where_the_joints_were_held(tmp_path):
    """``armlab scan --robot so101 --calibrate --write-map``: torque off, each joint
    guided to the middle of its range and its two ends, the jaw closed and open; the map
    takes each joint's zero at its middle and its range from its ends, and serves."""
    from armlab.hardware.backends.joint_map import load_joint_map

    run, out, said = _calibrate(tmp_path, PLACES)
    assert run.returncode == 0, run.stderr
    assert len([s for s in said if s.startswith("Move ")]) == 15  # three places, five joints
    assert "torque off on every servo" in run.stderr
    jmap = load_joint_map(out, SO101)
    assert jmap.ids == (1, 2, 3, 4, 5) and jmap.protocol == "sts"
    tol = math.radians(0.2)  # a count is 0.088°
    for j, servo in zip(SO101.joints, jmap.joints, strict=True):
        mid, *ends = (math.radians(x) for x in PLACES[j.name])
        assert servo.sign == 1 and servo.offset == pytest.approx(-mid, abs=tol), j.name
        assert servo.lower == pytest.approx(max(min(ends) - mid, j.lower), abs=tol), j.name
        assert servo.upper == pytest.approx(min(max(ends) - mid, j.upper), abs=tol), j.name
    g = jmap.gripper
    assert g is not None and g.servo_id == 6
    assert g == dataclasses.replace(so101_gripper(SO101.urdf_path), servo_id=6,
                                    closed_angle=g.closed_angle, open_angle=g.open_angle)
    assert (g.closed_angle, g.open_angle) == (pytest.approx(math.radians(-5.0), abs=tol),
                                              pytest.approx(math.radians(90.0), abs=tol))


def test_a_guided_range_past_the_urdf_s_limits_is_refused_naming_the_joint(tmp_path):
    places = dict(PLACES, elbow_flex=(0.0, -120.0, 120.0))  # the URDF allows ±96.8°
    run, out, _ = _calibrate(tmp_path, places)
    assert run.returncode != 0
    assert "joint 'elbow_flex' (servo ID 3): its range" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr
    assert not os.path.exists(out)
