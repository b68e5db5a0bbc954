"""DynamixelBackend on the emulator over a real pty: thesis configuration, limits, faults."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from _emulator import emulator

from armlab.control.backend import Backend, BackendError
from armlab.hardware.backends.joint_map import JointMap, JointServo, load_joint_map
from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.backend import DynamixelBackend
from armlab.hardware.servos.servo_spec import RX24F
from armlab.hardware.wire.bus import Bus
from armlab.hardware.wire.errors import NoReply, WrongModel
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

MARGIN = 0.1  # s of reply timeout: generous, the test machine is shared

ARM = load_robot("receptionist_arm")


def _goal_words(packets: list[bytes], servo_id: int) -> list[int]:
    """Goal positions sent to ``servo_id`` in SYNC_WRITE or WRITE packets at address 30."""
    out = []
    for p in packets:
        if p[4] == p1.Instruction.SYNC_WRITE and p[5] == 30:
            L = p[6]
            body = p[7:-1]
            for k in range(0, len(body), L + 1):
                if body[k] == servo_id:
                    out.append(body[k + 1] | body[k + 2] << 8)
        elif p[4] == p1.Instruction.WRITE and p[2] in (servo_id, p1.BROADCAST_ID) and p[5] == 30:
            out.append(p[6] | p[7] << 8)
    return out


def test_thesis_configuration_then_read_and_one_sync_write_per_cycle(tmp_path):
    with emulator(log_dir=tmp_path) as emu:
        b = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        try:
            assert isinstance(b, Backend) and b.n == 3
            text = "\n".join(b.configuration)
            for step in ("return delay 0", "status return level 1", "compliance margin 0",
                         "compliance slope 64", "torque limit 100%", "baud 1000000"):
                assert step in text
            for i in (1, 3, 5):
                assert b.bus.read(i, "return_delay_time") == 0
                assert b.bus.read(i, "status_return_level") == 1
                assert [b.bus.read(i, n) for n in ("cw_compliance_margin", "ccw_compliance_margin",
                                                   "cw_compliance_slope", "ccw_compliance_slope")
                        ] == [0, 0, 64, 64]
                assert b.bus.read(i, "torque_limit") == 1023
            b.set_torque(True)
            goal = np.array([0.4, 0.3, 0.6])
            b.read()  # a round trip: every earlier packet has reached the emulator's log
            seen = len(emu.packets("rx"))
            retries = b.stats.retries
            for _ in range(40):
                b.sync(0.0)  # hardware: no-op
                b.write(goal, np.full(3, 3.0))
                state = b.read()
                time.sleep(0.016)
            cycle = emu.packets("rx")[seen:]
            reads = [p for p in cycle if p[4] == p1.Instruction.READ]
            syncs = [p for p in cycle if p[4] == p1.Instruction.SYNC_WRITE]
            # one READ per servo and cycle (and one more for each retry: a stalled machine),
            # one SYNC_WRITE per cycle (no reply, never retried)
            assert len(reads) == 3 * 40 + b.stats.retries - retries and len(syncs) == 40
            assert {p for p in reads} == {p1.read(i, 36, 6) for i in (1, 3, 5)}
            assert all(len(p) == 23 for p in syncs)
            state = b.read()
            assert state.torque_on == (True, True, True) and state.errors == (0, 0, 0)
            # the servos got there (compliance slope 64 lets gravity pull a few counts)
            assert np.all(np.abs(state.position - goal) < math.radians(8))
            assert b.stats.failures == 0
        finally:
            b.close()


def test_the_angle_limits_are_one_read_per_servo(tmp_path):
    """CW and CCW limits (addresses 6 and 8) come in one 4-byte READ per servo: a late
    2-byte answer cannot pass for either (issue 14's X-series finding, on protocol 1.0)."""
    with emulator(log_dir=tmp_path) as emu:
        b = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        try:
            b.read()  # a round trip: every earlier packet has reached the emulator's log
            reads = {p for p in emu.packets("rx") if p[4] == p1.Instruction.READ}
            for i in (1, 3, 5):
                assert p1.read(i, 6, 4) in reads
                assert p1.read(i, 6, 2) not in reads and p1.read(i, 8, 2) not in reads
            assert np.all(b.lower >= ARM.lower) and np.all(b.upper <= ARM.upper)
        finally:
            b.close()


def test_goal_outside_the_servo_angle_limits_is_clamped_and_never_sent(tmp_path):
    with emulator(log_dir=tmp_path) as emu:
        with Bus(emu.port, timeout_margin=MARGIN) as bus:  # a technician set limits
            bus.write(1, "cw_angle_limit", 312)
            bus.write(1, "ccw_angle_limit", 712)
            with pytest.raises(p1.ServoError) as e:  # the servo says so if asked directly
                bus.write(1, "goal_position", 900)
            assert e.value.error & p1.ErrorBits.ANGLE_LIMIT
        b = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        try:
            assert b.read().errors[0] & p1.ErrorBits.ANGLE_LIMIT  # surfaced in JointState
            assert b.upper[0] == pytest.approx(RX24F.raw_to_position(712))
            assert b.lower[0] == pytest.approx(RX24F.raw_to_position(312))
            b.read()
            seen = len(emu.packets("rx"))
            b.write(np.array([2.5, 0.0, 0.0]), np.ones(3))
            b.write(np.array([-2.5, 0.0, 0.0]), np.ones(3))
            with pytest.raises(ValueError, match="non-finite"):
                b.write(np.array([np.nan, 0.0, 0.0]), np.ones(3))
            assert b.read().errors[0] == 0  # a valid goal clears the angle-limit bit
            sent = [p for p in emu.packets("rx")[seen:] if p[4] != p1.Instruction.READ]
            assert _goal_words(sent, 1) == [712, 312]
            assert len(sent) == 2  # the NaN goal sent nothing
        finally:
            b.close()


def test_overload_bit_is_surfaced_and_its_servo_reports_torque_off():
    with emulator() as emu:
        b = DynamixelBackend(ARM, emu.port, torque_limit=0.03, timeout_margin=MARGIN)
        try:
            b.set_torque(True)
            b.write(np.array([0.0, 1.2, 0.0]), np.full(3, 2.0))  # lift the arm on 3 % torque
            deadline = time.monotonic() + 15.0
            state = b.read()
            while not state.errors[1] & p1.ErrorBits.OVERLOAD and time.monotonic() < deadline:
                time.sleep(0.1)
                state = b.read()
            assert state.errors[1] & p1.ErrorBits.OVERLOAD
            assert state.torque_on == (True, False, True)
            assert b.bus.read(3, "torque_limit") == 0  # alarm shutdown
            assert b.bus.read(3, "torque_enable") == 0
        finally:
            b.close()


def test_emulator_killed_mid_run_gives_one_backend_error_and_attempts_torque_off():
    with emulator() as emu:
        b = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        try:
            b.set_torque(True)
            b.read()
            emu.proc.kill()
            emu.proc.wait(timeout=10)
            with pytest.raises(BackendError) as e:
                for _ in range(3):
                    b.write(np.zeros(3), np.ones(3))
                    b.read()
            msg = str(e.value)
            assert "\n" not in msg and ("lost the serial link" in msg or "no reply" in msg)
            assert b.estops >= 1  # broadcast torque off was attempted
            b.estop()  # and never raises, even with the link gone
        finally:
            b.close()


def test_joint_map_file_ids_signs_and_offsets(tmp_path):
    cfg = tmp_path / "arm.toml"
    cfg.write_text(
        'servo = "RX-24F"\n'
        '[[joints]]\nname = "theta1"\nid = 7\nsign = -1\noffset_deg = 10\n'
        '[[joints]]\nname = "theta0"\nid = 8\nlower_deg = -30\nupper_deg = 45\n'
        '[[joints]]\nname = "theta2"\nid = 9\n')
    jmap = load_joint_map(cfg, ARM)
    assert jmap.ids == (7, 8, 9) and jmap.joints[0].sign == -1
    with emulator("--ids", "7,8,9") as emu:
        b = DynamixelBackend(ARM, emu.port, joint_map=jmap, timeout_margin=MARGIN)
        try:
            q = b.read().position  # servos at their centre (raw 512)
            assert q == pytest.approx([math.radians(10), 0.0, 0.0])
            assert b.upper[1] == pytest.approx(math.radians(45))
            words, _ = b.goal_words(np.array([math.radians(10) - 0.5, 1.0, 0.0]), np.ones(3))
            assert words[0] == RX24F.position_to_raw(0.5)  # sign −1 about the 10° offset
            assert words[1] == RX24F.position_to_raw(math.radians(45))  # clamped
        finally:
            b.close()
    bad = tmp_path / "bad.json"
    bad.write_text('{"joints": [{"name": "elbow", "id": 1}]}')
    with pytest.raises(ValueError, match="bad.json: unknown joint 'elbow'"):
        load_joint_map(bad, ARM)
    bad.write_text('{"joints": [{"name": "theta1", "id": 1}]}')
    with pytest.raises(ValueError, match="no servo for joint.*theta0"):
        load_joint_map(bad, ARM)


def test_wrong_model_and_missing_servo_are_named():
    with emulator("--servo", "AX-12A") as emu:
        with pytest.raises(BackendError, match="servo 1 is a AX-12A.*expected a RX-24F") as e:
            DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        assert isinstance(e.value.__cause__, WrongModel)  # the bus's error, translated
        jmap = JointMap("AX-12A", (JointServo("theta1", 1), JointServo("theta0", 3),
                                   JointServo("theta2", 7)))
        with pytest.raises(BackendError, match="joint theta2: no reply from servo 7") as e:
            DynamixelBackend(ARM, emu.port, joint_map=jmap, timeout_margin=MARGIN)
        assert isinstance(e.value.__cause__, NoReply)
        with Bus(emu.port):  # the failed backends released the port
            pass


def test_a_torque_off_that_cannot_be_sent_is_never_reported_as_sent():
    """The link dies under a running lab: the fault's torque-off and a later E-STOP cannot
    reach the servos, so the status says so (a red line: switch the servo power off) and
    never "torque off"; the log says the same."""
    import signal

    from _helpers import wait_for

    from armlab.app.lab.server import Lab, ServeOptions
    from armlab.app.testing.wsclient import HeadlessClient
    from armlab.control.commands import EStop

    with emulator() as emu:
        with Lab(ServeOptions(backend="serial", port=emu.port, http_port=0)) as lab, \
                HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
            loop = lab.lesson.rig.loop

            def status_line() -> str:  # what the page shows at the top of the panel
                return " ".join(str(e.props.get("content", "")) for e in page.gui.values()
                                if "●" in str(e.props.get("content", "")))

            wait_for(lambda: loop.status.active and loop.status.torque_on, 60, "torque on")
            wait_for(lambda: "torque on" in status_line(), 60, "the status on the page")
            emu.stop(signal.SIGKILL)  # the adapter pulled out
            wait_for(lambda: loop.status.fault is not None, 60, "the lost link's fault")
            wait_for(lambda: loop.status.torque_off_unsent, 60, "the unsent torque-off")
            loop.post(EStop())
            wait_for(lambda: loop.status.estopped, 60, "the E-STOP")
            st = loop.status
            assert st.torque_off_unsent and st.torque_on  # not claimed off
            assert "could not be sent" in st.message
            wait_for(lambda: "Torque off could not be sent: switch the servo power off"
                     in status_line(), 60, lambda: f"the red status line ({status_line()!r})")
            assert "torque unknown" in status_line()
            assert "· torque off ·" not in status_line()
    assert lab.lesson is None  # closed cleanly, nothing raised


def test_estop_reports_whether_the_packet_went_out():
    with emulator() as emu:
        b = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        try:
            b.set_torque(True)
            assert b.estop() is True
            b.bus.close()  # the port is gone
            assert b.estop() is False
        finally:
            b.close()


def test_servos_left_at_status_return_level_1_are_opened_again_without_waiting():
    """A backend configures the servos to answer PING and READ only (the thesis's status
    return level 1, kept in EEPROM); opened again on the same servos (a restart of the
    lab), it reads that level first and waits for no reply to a write that none will
    answer: it configures them with no timeout and no retry."""
    with emulator() as emu:
        first = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN)
        first.close()
        again = DynamixelBackend(ARM, emu.port, timeout_margin=MARGIN, retries=1)
        try:
            assert again.bus.status_return_level == {1: 1, 3: 1, 5: 1}
            assert "servo 1 (theta1): status return level 1 (already set)" in again.configuration
            assert (again.stats.timeouts, again.stats.retries) == (0, 0)
            again.set_torque(True)
            assert all(again.read().torque_on)
        finally:
            again.close()
