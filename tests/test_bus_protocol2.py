"""Protocol 2.0 over a real pseudo-terminal: ``armlab emulate`` serving X-series servos
(the OpenManipulator-X's five XM430-W350: the arm's IDs 11..14 and the gripper's 15) and
:class:`armlab.hardware.wire.bus.Bus` opened with ``protocol=2``.

The e-manual's PING answer byte for byte; named reads and writes through the X-series
table; one SYNC_READ and one BULK_READ for every servo; the error numbers a person
can cause (an EEPROM item with the torque on, a goal past its limit, a read-only item);
REBOOT; REG_WRITE held until a broadcast ACTION; FACTORY_RESET behind its confirmation,
at its levels; lost and broken answers retried; a protocol-1.0 bus on it hears nothing
and says which protocol it tried.
"""

from __future__ import annotations

import math

import pytest
from _emulator import emulator
from _helpers import wait_for

from armlab.hardware.families.xseries import packets as p2
from armlab.hardware.families.xseries.table import CENTRE, XM430_W350_TABLE
from armlab.hardware.wire.bus import Bus
from armlab.hardware.wire.errors import NoReply
from armlab.kinematics import load_robot

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

IDS = (11, 12, 13, 14)
OMX = ("--robot", "open_manipulator_x")


def test_ping_answers_as_the_e_manual_shows(tmp_path):
    with emulator(*OMX, log_dir=tmp_path) as emu, Bus(emu.port, protocol=2) as bus:
        status = bus.ping(11)
        assert status.servo_id == 11 and not status.error
        assert int.from_bytes(status.params[:2], "little") == 1020  # XM430-W350
        # the reply on the wire: FF FF FD 00 | ID | LEN 7 | 55 | ERR | model L H | fw | CRC
        reply = emu.packets("tx")[-1]
        assert reply[:9] == bytes.fromhex("ff ff fd 00 0b 07 00 55 00")
        assert reply[9:11] == (1020).to_bytes(2, "little")
        assert p2.crc16(reply[:-2]) == int.from_bytes(reply[-2:], "little")
        assert emu.packets("rx")[-1] == p2.ping(11) == bytes.fromhex(
            "ff ff fd 00 0b 03 00 01") + p2.crc16(bytes.fromhex(
                "ff ff fd 00 0b 03 00 01")).to_bytes(2, "little")


def test_named_access_group_reads_and_the_arm_moves():
    with emulator(*OMX) as emu, Bus(emu.port, protocol=2) as bus:
        for i in IDS:
            assert bus.identify(i, expect="XM430-W350") is XM430_W350_TABLE
        assert bus.read(12, "operating_mode") == 3
        assert bus.read(12, "position_p_gain") == 800  # the XM430-W350's factory gain
        # one SYNC_READ: present current, velocity and position of every servo (10 bytes)
        first = bus.sync_read(126, 10, IDS)
        assert list(first) == list(IDS) and all(len(b) == 10 for b in first.values())
        # (a retry, which a loaded machine may cause, is a packet but not a request)
        assert bus.stats.transactions - bus.stats.retries == 4 + 2 + 1
        goal = CENTRE + round(math.radians(20) / XM430_W350_TABLE.spec.position_unit)
        bus.write(12, "torque_enable", 1)
        bus.write(12, "goal_position", goal)

        def position() -> int:
            data = bus.bulk_read([(12, 132, 4), (11, 132, 4)])
            return int.from_bytes(data[12], "little", signed=True)

        wait_for(lambda: abs(position() - goal) < 40, 30, "joint 2 at its goal")
        assert bus.read_si(12, "present_position") == pytest.approx(math.radians(20), abs=0.05)


def test_refused_writes_name_the_error_and_change_nothing():
    with emulator(*OMX) as emu, Bus(emu.port, protocol=2) as bus:
        bus.write(13, "torque_enable", 1)
        with pytest.raises(p2.ServoError, match="access"):  # EEPROM with the torque on
            bus.write(13, "return_delay_time", 0)
        assert bus.read(13, "return_delay_time") == 250
        with pytest.raises(p2.ServoError, match="limits"):  # past Current Limit (1193)
            bus.write_bytes(13, 102, (1500).to_bytes(2, "little"))
        bus.write(13, "torque_enable", 0)
        bus.write(13, "max_position_limit", 3000)
        bus.write(13, "torque_enable", 1)
        with pytest.raises(p2.ServoError, match="limits"):  # past Max Position Limit
            bus.write(13, "goal_position", 3500)
        bus.write(13, "goal_position", 2900)
        assert bus.read(13, "goal_position") == 2900
        with pytest.raises(p2.ServoError, match="access"):  # read-only
            bus.write_bytes(13, 132, (0).to_bytes(4, "little"))
        with pytest.raises(ValueError, match="read-only"):  # and never sent by name
            bus.write(13, "present_position", 0)


def test_reboot_turns_the_torque_off():
    with emulator(*OMX) as emu, Bus(emu.port, protocol=2) as bus:
        bus.write(14, "torque_enable", 1)
        bus.reboot(14)
        wait_for(lambda: bus.read(14, "torque_enable") == 0, 10, "torque off after REBOOT")


def test_lost_and_broken_answers_to_a_sync_read_are_asked_again():
    with emulator(*OMX, "--drop", "0.1", "--corrupt", "0.1", "--seed", "5") as emu, \
            Bus(emu.port, protocol=2, retries=8) as bus:
        for _ in range(20):
            data = bus.sync_read(132, 4, IDS)
            assert list(data) == list(IDS)
        assert bus.stats.retries > 0 and bus.stats.failures == 0


def test_a_protocol_1_bus_hears_nothing_and_names_the_protocol():
    with emulator(*OMX) as emu:
        with Bus(emu.port, retries=1) as bus:
            with pytest.raises(NoReply, match="protocol 1.0"):
                bus.ping(11)
            # protocol-2.0 instructions are refused before anything is sent
            sent = bus.stats.transactions
            for call in (lambda: bus.sync_read(132, 4, [11]), lambda: bus.reboot(11),
                         lambda: bus.bulk_read([(11, 132, 4)])):
                with pytest.raises(ValueError, match="protocol 2.0"):
                    call()
            assert bus.stats.transactions == sent
        with Bus(emu.port, protocol=2) as bus:
            bus.ping(11)  # the servos still answer in their own protocol


def test_scan_finds_the_x_series_servos_and_their_protocol():
    from armlab.hardware.backends.joint_map import draft_joint_map
    from armlab.hardware.wire.scan import scan

    with emulator(*OMX) as emu:
        # the IDs the assertion names (11..15) and two silent neighbours each side
        found = scan(emu.port, (57_600, 1_000_000), ids=range(9, 18))
    assert [(f.servo_id, f.model, f.protocol, f.baud) for f in found] == \
        [(i, "XM430-W350", 2, 1_000_000.0) for i in (*IDS, 15)]  # the gripper's too
    assert all(f.model_number == 1020 and f.cw_limit == 0 and f.ccw_limit == 4095
               for f in found)
    assert found[0].ccw_limit_deg == pytest.approx(180.0, abs=0.1)
    text = draft_joint_map(found, load_robot("open_manipulator_x"))
    assert 'servo = "XM430-W350"' in text and "protocol = 2.0" in text
    assert 'name = "joint1"\nid = 11' in text
    assert '[gripper]\nid = 15\njoint = "gripper_left_joint"' in text


def test_scan_of_a_protocol_1_bus_names_protocol_1():
    from armlab.hardware.wire.scan import scan

    with emulator("--ids", "1,3,5") as emu:
        found = scan(emu.port, (1_000_000,), ids=range(0, 8))
    assert [(f.servo_id, f.protocol) for f in found] == [(1, 1), (3, 1), (5, 1)]


def test_reg_write_holds_a_goal_until_a_broadcast_action_moves_both_servos():
    """REG_WRITE: the servo checks the goal and keeps it aside (Registered Instruction 1,
    Goal Position unchanged, the horn where it was); one broadcast ACTION starts both."""
    turn = (11, 13)  # the base turns freely, the elbow against gravity
    with emulator(*OMX) as emu, Bus(emu.port, protocol=2) as bus:
        seen: list[dict[int, int]] = []

        def at_rest() -> bool:  # the torque-off elbow swings down for a second at start
            seen.append({i: bus.read(i, "present_position") for i in turn})
            return (len(seen) >= 3 and seen[-3] == seen[-2] == seen[-1]
                    and all(bus.read(i, "moving") == 0 for i in turn))

        wait_for(at_rest, 30, "the torque-off arm at rest", every=0.1)
        held = {}
        for i in turn:  # hold where the horn is now
            held[i] = bus.read(i, "present_position")
            bus.write(i, "goal_position", held[i])
            bus.write(i, "torque_enable", 1)
        goal = {i: held[i] + 300 for i in turn}  # 26°
        for i in turn:
            bus.reg_write(i, "goal_position", goal[i])
        for i in turn:
            assert bus.read(i, "registered_instruction") == 1
            assert bus.read(i, "goal_position") == held[i]
            assert abs(bus.read(i, "present_position") - held[i]) < 40  # not on its way
        with pytest.raises(p2.ServoError, match="limits"):  # checked when registered
            bus.reg_write(11, "goal_current", 1500)  # past Current Limit (1193)
        assert bus.read(11, "registered_instruction") == 1  # the goal still waits
        bus.action()  # broadcast: no reply
        for i in turn:
            wait_for(lambda i=i: abs(bus.read(i, "present_position") - goal[i]) < 40, 30,
                     f"servo {i} at its registered goal after ACTION")
            assert bus.read(i, "registered_instruction") == 0
            assert bus.read(i, "goal_position") == goal[i]
        # an ACTION with nothing registered: the e-manual's Instruction error
        status = bus.transact(p2.action(11), reply=True)
        assert status.error.number == p2.ErrorNumber.INSTRUCTION


#: what the factory-reset test changes from the XM430-W350's factory values (EEPROM and RAM)
CHANGED = {"return_delay_time": 0, "operating_mode": 5, "max_position_limit": 3000,
           "shutdown": 0x24, "position_p_gain": 500}


def test_factory_reset_needs_its_confirmation_and_keeps_id_and_baud_at_level_2():
    with emulator(*OMX) as emu, Bus(emu.port, protocol=2) as bus:
        for name, value in CHANGED.items():
            bus.write(12, name, value)
        sent = bus.stats.transactions
        with pytest.raises(ValueError, match="confirm=True"):
            bus.factory_reset(12, level=p2.ResetLevel.KEEP_ID_AND_BAUD)
        assert bus.stats.transactions == sent  # refused before anything was sent
        assert {n: bus.read(12, n) for n in CHANGED} == CHANGED
        bus.factory_reset(12, level=p2.ResetLevel.KEEP_ID_AND_BAUD, confirm=True)
        assert bus.ping(12).servo_id == 12  # still ID 12 at 1 Mbps
        assert (bus.read(12, "id"), bus.read(12, "baud_rate")) == (12, 3)
        assert {n: bus.read(12, n) for n in CHANGED} == \
            {n: XM430_W350_TABLE.item(n).default for n in CHANGED}
        assert bus.read(13, "operating_mode") == 3 and bus.read(11, "id") == 11  # the others
        # level 0xFF forgets the ID and the baud too: servo 13 becomes ID 1 at 57 600
        bus.factory_reset(13, confirm=True)
        with pytest.raises(NoReply):
            bus.ping(13, tries=2)
        bus.set_baud(57_600)
        assert int.from_bytes(bus.ping(1).params[:2], "little") == 1020
