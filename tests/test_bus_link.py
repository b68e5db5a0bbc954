"""The serial bus against the emulator over a real pseudo-terminal: bytes, scan, faults, errors."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import tty
from pathlib import Path

import pytest
import serial
from _emulator import ROOT, emulator
from _helpers import wait_for

from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.table import AX12A_TABLE, RX24F_TABLE
from armlab.hardware.wire.bus import Bus
from armlab.hardware.wire.errors import NoReply, PortError
from armlab.hardware.wire.port import ftdi_latency_check
from armlab.hardware.wire.scan import scan

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal


@pytest.fixture(scope="module")
def emu(tmp_path_factory):
    """One default emulator (receptionist arm, IDs 1, 3, 5, logging) for the tests that
    leave it as they found it; tests that change EEPROM or need options start their own."""
    with emulator(log_dir=tmp_path_factory.mktemp("emu")) as e:
        yield e


def _exchange(port: str, request: bytes, n_reply: int) -> bytes:
    """Raw pyserial: write bytes, read n_reply bytes (bounded wait)."""
    with serial.Serial(port, 1_000_000, timeout=2.0) as ser:
        ser.write(request)
        return ser.read(n_reply)


def test_thesis_packet_and_status_byte_for_byte_over_a_pty(emu):
    seen = len(emu.packets("rx"))
    reply = _exchange(emu.port, bytes.fromhex("FF FF 01 05 03 1E 52 02 84"), 6)
    assert reply == bytes.fromhex("FF FF 01 02 00 FC")
    assert emu.packets("rx")[seen:] == [bytes.fromhex("FFFF0105031E520284")]
    with Bus(emu.port) as bus:
        assert bus.read(1, "goal_position") == 0x252


def test_sdk_ping_then_model_number_read(emu):
    assert _exchange(emu.port, bytes.fromhex("FFFF010201FB"), 6) == bytes.fromhex(
        "FFFF010200FC")
    # model number 24 = 0x0018 (RX-24F): FF FF 01 04 00 18 00 CHK
    reply = _exchange(emu.port, bytes.fromhex("FFFF0104020002F6"), 8)
    assert reply == bytes.fromhex("FFFF0104001800E2")
    assert p1.checksum(reply[2:-1]) == 0xE2


def test_sync_write_is_one_23_byte_packet_and_moves_every_goal(emu):
    with Bus(emu.port) as bus:
        seen = len(emu.packets("rx"))
        goals = {1: 0x200, 3: 0x252, 5: 0x300}
        bus.sync_write(30, 4, {i: p1.word(g) + p1.word(100) for i, g in goals.items()})
        assert [bus.read(i, "goal_position") for i in goals] == list(goals.values())
        assert [bus.read(i, "moving_speed") for i in goals] == [100] * 3
        sync = [p for p in emu.packets("rx")[seen:] if p[4] == p1.Instruction.SYNC_WRITE]
        assert len(sync) == 1 and len(sync[0]) == 23
        assert sync[0][:8] == bytes.fromhex("FFFFFE13831E0401")


def test_scan_finds_exactly_the_emulated_ids_and_models_and_names_a_wrong_model():
    from armlab.hardware.wire.errors import WrongModel

    with emulator("--ids", "4,9,200", "--servo", "AX-12A", "--robot", "receptionist_arm") as emu:
        found = scan(emu.port, (1_000_000,))  # a pty's policy: the emulator is a process
        with Bus(emu.port) as bus:
            assert bus.identify(4) is AX12A_TABLE
            with pytest.raises(WrongModel, match="servo 9 is a AX-12A .*expected a RX-24F"):
                bus.identify(9, expect="RX-24F")
    assert [(f.servo_id, f.model, f.model_number) for f in found] == [
        (4, "AX-12A", 12), (9, "AX-12A", 12), (200, "AX-12A", 12)]
    assert all(f.cw_limit == 0 and f.ccw_limit == 1023 and f.baud == 1_000_000 for f in found)


def test_scan_command_finds_servos_only_at_their_baud_and_silence_is_explained():
    with emulator("--baud", "57600") as emu:
        out = subprocess.run(
            [sys.executable, "-m", "armlab.app", "scan", "--port", emu.port, "--ids", "0-9",
             "--baud", "1000000", "--baud", "57600", "--json"],
            cwd=ROOT, capture_output=True, text=True, timeout=90)
        with Bus(emu.port, 1_000_000, retries=1) as bus:
            with pytest.raises(NoReply) as e:
                bus.ping(1)
            assert bus.stats.retries == 1 and bus.stats.failures == 1
        code, err = emu.stop()
    assert out.returncode == 0, out.stderr
    # the servos heard none of the ten PINGs the scan sent at 1 Mbps, nor the bus's two
    assert code == 0 and int(re.search(r"(\d+) packets at another baud", err)[1]) >= 12, err
    found = json.loads(out.stdout)
    assert [(f["servo_id"], f["model"], round(f["baud"])) for f in found] == [
        (1, "RX-24F", 57600), (3, "RX-24F", 57600), (5, "RX-24F", 57600)]
    assert "1000000 bps" in out.stderr and "57600 bps" in out.stderr  # progress
    msg = str(e.value)
    assert "\n" not in msg
    for cause in ("power", "baud", "ID", "protocol 1.0"):
        assert cause in msg
    assert "came back" not in msg  # silence: not a byte answered


def test_a_servo_whose_replies_all_come_back_broken_is_told_from_silence():
    with emulator("--corrupt", "1", "--seed", "2", "--ids", "1,2,3") as emu, \
            Bus(emu.port, retries=2) as bus:
        with pytest.raises(NoReply) as e:
            bus.ping(2)
        assert bus.stats.corrupt == 3  # each try's reply came, with a broken checksum
    heard = bus.stats.bytes_in
    assert heard == 3 * len(p1.status(2, 0))
    assert f"servo 2 at 1000000 bps on {emu.port} after 3 tries ({heard} bytes came back, " \
           "none of them its reply): check" in str(e.value)


def test_dropped_and_corrupted_replies_are_retried_and_counted():
    args = ("--drop", "0.2", "--corrupt", "0.2", "--seed", "7", "--ids", "1,2,3")
    with emulator(*args) as emu, Bus(emu.port, retries=8) as bus:
        for k in range(40):
            i = 1 + k % 2
            assert bus.read(i, "model_number") == 24
            assert bus.read(i, "id") == i
        st = bus.stats
        assert st.retries > 0 and st.timeouts > 0 and st.corrupt > 0
        assert st.failures == 0 and st.replies == 80
        assert st.transactions == 80 + st.retries


def test_late_replies_do_not_confuse_the_next_transaction():
    args = ("--delay", "0.3", "--delay-time", "0.03", "--seed", "3")
    # a wire's 20 ms margin: the 30 ms delayed replies arrive after the timeout
    with emulator(*args) as emu, Bus(emu.port, retries=8, timeout_margin=0.020) as bus:
        for _ in range(15):  # alternate lengths and IDs: a stale reply never matches
            assert bus.read(1, "model_number") == 24
            assert bus.read(3, "id") == 3
            assert bus.read(5, "cw_angle_limit") == 0
        assert bus.stats.retries > 0 and bus.stats.failures == 0


def test_echoing_adapter_needs_and_gets_echo_cancellation():
    with emulator("--echo") as emu, Bus(emu.port, echo=True) as bus:
        assert bus.read(3, "model_number") == 24
        bus.write(3, "goal_position", 600)  # echo + status
        bus.sync_write(30, 2, {1: p1.word(500)})  # echo only
        assert bus.read(1, "goal_position") == 500
        assert bus.read(3, "goal_position") == 600


def test_a_retry_whose_echoes_both_come_late_still_takes_the_reply_not_an_echo():
    """A slow far end (an emulator the OS paused) answers a retried READ only after the
    retry: both echoes of the request come back first, then the reply. The bus takes the
    two identical echoes as its own packets (one owed per time it was sent), not the
    second as a status, which on protocol 1.0 has the same frame (CI read 512, the
    READ's own address and length, for a model number 24)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    request = p1.read(3, 0, 2)
    try:
        with Bus(path, echo=True, retries=1, timeout_margin=0.05) as bus:
            def far_end() -> None:
                parser = p1.PacketParser()
                seen: list[bytes] = []
                while len(seen) < 2:  # the first try goes unanswered: wait for the retry
                    seen.extend(parser.feed(os.read(master, 64)))
                reply = p1.status(3, 0, (24).to_bytes(2, "little"))
                os.write(master, request + request + reply)

            t = threading.Thread(target=far_end, daemon=True)
            t.start()
            assert bus.read(3, "model_number") == 24
            t.join(timeout=10)
            assert bus.stats.retries == 1
    finally:
        os.close(master)
        os.close(slave)


def test_port_errors_are_one_line_with_the_fix():
    with pytest.raises(PortError, match="not found: is the adapter plugged in"):
        Bus("/dev/ttyUSB-armlab-missing")


def test_a_busy_port_is_named(emu):
    with Bus(emu.port), pytest.raises(PortError, match="busy"):
        Bus(emu.port)


def _port_error_as_nobody(port: str) -> str:
    """The PortError that opening ``port`` raises in a forked child that gave up root for
    the unprivileged user 65534 (root ignores file permissions); "" when none."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: no pytest from here on, only os._exit
        said = b""
        try:
            os.setgroups([])
            os.setgid(65534)
            os.setuid(65534)
            Bus(port)
        except PortError as exc:
            said = str(exc).encode()
        except BaseException as exc:  # noqa: BLE001  (told to the parent, never raised here)
            said = f"not a PortError: {exc!r}".encode()
        finally:
            os.write(write_end, said)
            os._exit(0)
    os.close(write_end)
    with os.fdopen(read_end, "rb") as said:
        message = said.read().decode()
    os.waitpid(pid, 0)
    return message


def test_permission_denied_names_the_dialout_group(tmp_path):
    """A port the user may not open: the one line names the dialout group. Run as root
    (a container's tests), the open is tried by an unprivileged child."""
    if os.geteuid() == 0:  # pytest's folders are root's alone: one the child can pass
        with tempfile.TemporaryDirectory() as home:
            os.chmod(home, 0o711)
            dev = Path(home) / "ttyFAKE"
            dev.write_text("")
            dev.chmod(0)
            said = _port_error_as_nobody(str(dev))
        assert "dialout" in said, said
        return
    dev = tmp_path / "ttyFAKE"
    dev.write_text("")
    dev.chmod(0)
    with pytest.raises(PortError, match="dialout"):
        Bus(str(dev))


def test_rs485_on_a_pty_is_not_applicable_not_an_error(emu):
    with Bus(emu.port, rs485=True) as bus:
        assert any("RS-485 mode not applicable" in n for n in bus.notes)
        assert bus.ping(1).servo_id == 1


def test_ftdi_latency_timer_check_names_the_fix(tmp_path):
    (tmp_path / "ttyUSB7").mkdir()
    (tmp_path / "ttyUSB7" / "latency_timer").write_text("16\n")
    msg = ftdi_latency_check("/dev/ttyUSB7", sysfs=tmp_path)
    assert msg is not None and "16 ms" in msg
    assert f"echo 1 | sudo tee {tmp_path}/ttyUSB7/latency_timer" in msg
    (tmp_path / "ttyUSB7" / "latency_timer").write_text("1\n")
    assert ftdi_latency_check("/dev/ttyUSB7", sysfs=tmp_path) is None
    assert ftdi_latency_check("/dev/pts/0", sysfs=tmp_path) is None


def test_named_access_refuses_bad_writes_before_sending(emu):
    with Bus(emu.port) as bus:
        seen = len(emu.packets("rx"))
        with pytest.raises(ValueError, match="read-only"):
            bus.write(5, "present_position", 10)
        with pytest.raises(ValueError, match="outside 0..1023"):
            bus.write(5, "goal_position", 2000)
        assert emu.packets("rx")[seen:] == []  # nothing left the process
        bus.write_si(5, "goal_position", 0.5)
        assert bus.read_si(5, "goal_position") == pytest.approx(
            0.5, abs=RX24F_TABLE.spec.position_unit)


def test_status_return_level_and_return_delay(emu):
    # one try each (the failure count below is exact); a reply may take 2 s on a loaded
    # machine, so only the packet that is never sent is missed
    with Bus(emu.port, retries=0, timeout_margin=2.0) as bus:
        bus.write(1, "return_delay_time", 250)  # 500 µs before every status packet
        bus.ping(1)
        rx_t = [t for t, tag, p in emu.timed() if tag == "rx" and p == p1.ping(1)][-1]
        tx_t = [t for t, tag, p in emu.timed() if tag == "tx" and t >= rx_t][0]
        assert tx_t - rx_t >= 499e-6  # the log has µs resolution
        bus.write(1, "status_return_level", 1)  # READ only
        t_before = len(emu.packets("tx"))
        bus.write(1, "led", 1)  # no status packet now
        assert bus.read(1, "led") == 1
        assert len(emu.packets("tx")) == t_before + 1  # only the READ was answered
        bus.write(1, "status_return_level", 0)  # PING only
        assert bus.ping(1).servo_id == 1
        with pytest.raises(NoReply):
            bus.read(1, "led")
        assert bus.stats.failures == 1
        bus.write(1, "status_return_level", 2)  # leave it as found
        bus.write(1, "led", 0)


def test_pacing_holds_replies_for_their_wire_time_and_sigterm_stops_cleanly(tmp_path):
    import signal

    with emulator("--pace", "--baud", "57600", log_dir=tmp_path) as emu:
        with Bus(emu.port, 57600) as bus:
            bus.write(1, "return_delay_time", 0)
            bus.read_bytes(1, 36, 6)
        log = emu.timed()
        code, err = emu.stop(signal.SIGTERM)
    rx = [t for t, tag, p in log if tag == "rx" and p == p1.read(1, 36, 6)][-1]
    tx = [t for t, tag, p in log if tag == "tx" and t >= rx][0]
    assert tx - rx >= (8 + 12) * 10 / 57600 * 0.99  # 3.5 ms of wire time
    assert code == 0 and "Traceback" not in err and "emulator stopped" in err


def test_lock_and_eeprom_items_then_factory_reset_then_sigint():
    import signal

    with emulator() as emu, Bus(emu.port) as bus:
        bus.write(5, "cw_angle_limit", 100)  # EEPROM
        assert bus.read(5, "cw_angle_limit") == 100
        bus.write(5, "lock", 1)
        with pytest.raises(p1.ServoError, match="value out of range"):
            bus.write(5, "ccw_angle_limit", 900)  # locked: only 24..35
        assert bus.read(5, "ccw_angle_limit") == 1023
        bus.write(5, "goal_position", 300)  # RAM 30 still writable
        assert bus.read(5, "goal_position") == 300
        with pytest.raises(p1.ServoError, match="out of range"):
            bus.write_bytes(5, 36, p1.word(10))  # present position is read-only
        assert bus.errors[5] & p1.ErrorBits.RANGE
        # FACTORY_RESET: guarded, then ID 1 at the RX-24F's factory 57 600 bps
        with pytest.raises(ValueError, match="confirm"):
            bus.factory_reset(3)
        assert bus.ping(3).servo_id == 3
        bus.factory_reset(3, confirm=True)
        with pytest.raises(NoReply):
            bus.ping(3)
        bus.set_baud(57600)
        assert bus.read(1, "baud_rate") == 34
        assert bus.read(1, "return_delay_time") == 250
        bus.close()
        code, err = emu.stop(signal.SIGINT)
        assert code == 0 and "Traceback" not in err and "emulator stopped" in err


def test_reg_write_waits_for_action(emu):
    with Bus(emu.port) as bus:
        bus.transact(p1.reg_write(3, 25, b"\x01"), reply=True)
        assert bus.read(3, "led") == 0 and bus.read(3, "registered") == 1
        bus.action()  # broadcast, no reply: the next transaction reads what it did
        wait_for(lambda: bus.read(3, "led") == 1, 30, "the registered LED write to act")
        assert bus.read(3, "registered") == 0
        status = bus.transact(p1.action(3), reply=True)  # nothing registered
        assert status is not None and status.error & p1.ErrorBits.INSTRUCTION


def test_emulator_keeps_its_name_across_a_restart_through_link(tmp_path):
    """``--link PATH``: a symlink to the pty, replaced by the next emulator (a by-id name
    survives a re-plug the same way), removed at exit; a file is never overwritten."""
    link = tmp_path / "by-id" / "usb-armlab-emulator"
    link.parent.mkdir()
    ports = []
    for _ in range(2):  # the second emulator is "the same device, plugged in again"
        with emulator("--link", str(link)) as emu:
            assert os.readlink(link) == emu.port
            ports.append(emu.port)
            with Bus(str(link)) as bus:
                assert bus.identify(1) is RX24F_TABLE  # the servos answer by the name
            code, _ = emu.stop()
            assert code == 0
        assert not os.path.lexists(link)  # gone with its emulator
    stale = tmp_path / "stale"
    os.symlink("/dev/null", stale)  # an earlier emulator killed -9 left its link
    with emulator("--link", str(stale)) as emu:
        assert os.readlink(stale) == emu.port
    plain = tmp_path / "a-file"
    plain.write_text("keep me")
    out = subprocess.run([sys.executable, "-m", "armlab.app", "emulate", "--link", str(plain)],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and plain.read_text() == "keep me"
    assert "exists and is not a symlink" in out.stderr and len(out.stderr.splitlines()) == 1


def test_scan_finds_servos_whose_every_answer_comes_late():
    """Every reply 0.15 s late (a machine holding the emulator back): each ping's answer
    arrives while the scan already pings the next ID; the scan asks those servos again."""
    with emulator("--ids", "4,9,11", "--servo", "AX-12A", "--robot", "redundant_planar",
                  "--delay", "1.0", "--delay-time", "0.15") as emu:
        found = scan(emu.port, (1_000_000,), ids=range(0, 12))
    assert [f.servo_id for f in found] == [4, 9, 11]
