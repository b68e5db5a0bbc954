"""Protocol 1.0 packets and control tables: the thesis's bytes, checksums, resynchronisation."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.table import AX12A_TABLE, RX24F_TABLE, table_for
from armlab.hardware.servos.servo_spec import load_fraction


def test_thesis_goal_position_packet_and_status_byte_for_byte():
    # thesis §2.3: servo 1 to 207.9° = 0x252 -> FF FF 01 05 03 1E 52 02 84, status FF FF 01 02 00 FC
    assert p1.write(1, 30, p1.word(0x252)) == bytes.fromhex("FFFF0105031E520284")
    assert p1.status(1) == bytes.fromhex("FFFF010200FC")
    st_ = p1.decode_status(bytes.fromhex("FFFF010200FC"))
    assert (st_.servo_id, st_.error, st_.params) == (1, 0, b"")
    # 0x252 = 594 counts is 174° on the 0..300° scale (0.293°/count, 512 = 150°); the
    # thesis's "207.9°" is 594 × 0.35°, a slip in its text, not in its bytes
    assert math.degrees(RX24F_TABLE.to_si("goal_position", 0x252)) + 150 == pytest.approx(
        174.0, abs=0.2)


def test_sdk_ping_and_model_number_read_bytes():
    assert p1.ping(1) == bytes.fromhex("FFFF010201FB")
    assert p1.read(1, 0, 2) == bytes.fromhex("FFFF0104020002F6")


def test_sync_write_of_goal_and_speed_to_three_servos_is_23_bytes():
    pkt = p1.sync_write(30, 4, {1: b"\x00\x02\x10\x00", 2: b"\x00\x02\x10\x00",
                                3: b"\x00\x02\x10\x00"})
    assert len(pkt) == 23
    assert pkt[:8] == bytes.fromhex("FFFFFE13831E0401")
    assert pkt[3] == (4 + 1) * 3 + 4  # LEN = (L+1)·N + 4
    assert p1.decode_instruction(pkt).params[:2] == bytes((30, 4))


def test_factory_reset_needs_explicit_confirmation():
    with pytest.raises(ValueError, match="confirm"):
        p1.factory_reset(1)
    with pytest.raises(ValueError, match="confirm"):
        p1.factory_reset(1, confirm="yes")  # truthy is not enough
    assert p1.factory_reset(1, confirm=True) == bytes.fromhex("FFFF010206F6")


def test_other_instructions():
    assert p1.action() == bytes.fromhex("FFFFFE0205FA")
    reg = p1.decode_instruction(p1.reg_write(3, 30, b"\x00\x02"))
    assert (reg.servo_id, reg.instruction, reg.params) == (3, p1.Instruction.REG_WRITE,
                                                           b"\x1e\x00\x02")


def test_error_bits_are_typed_flags_and_raise_servo_errors():
    pkt = p1.decode_status(p1.status(5, p1.ErrorBits.OVERLOAD | p1.ErrorBits.ANGLE_LIMIT))
    assert p1.ErrorBits.OVERLOAD in pkt.error and p1.ErrorBits.ANGLE_LIMIT in pkt.error
    assert p1.ErrorBits.RANGE not in pkt.error
    with pytest.raises(p1.ServoError, match="servo 5 reports.*angle limits.*overload") as e:
        pkt.check()
    assert e.value.error == 0x22
    assert p1.decode_status(p1.status(5)).check().servo_id == 5


def test_malformed_packets_are_refused():
    good = p1.ping(1)
    with pytest.raises(p1.ProtocolError, match="checksum"):
        p1.decode_status(good[:-1] + bytes((good[-1] ^ 1,)))
    with pytest.raises(p1.ProtocolError, match="length"):
        p1.decode_status(good + b"\x00")
    with pytest.raises(ValueError, match="servo_id"):
        p1.ping(300)


@given(st.integers(0, 253), st.integers(0, 255), st.binary(max_size=40))
def test_checksum_makes_every_packet_sum_to_0xff(servo_id, code, params):
    pkt = p1.encode_packet(servo_id, code, params)
    assert (sum(pkt[2:]) & 0xFF) == 0xFF  # ID + LEN + INST + ΣP + CHK ≡ 0xFF
    assert p1.decode_instruction(pkt) == p1.InstructionPacket(servo_id, code, params)


@given(st.integers(0, 253), st.binary(min_size=1, max_size=20), st.data())
def test_any_single_byte_corruption_is_detected(servo_id, params, data):
    pkt = bytearray(p1.encode_packet(servo_id, p1.Instruction.WRITE, params))
    i = data.draw(st.integers(4, len(pkt) - 1))  # instruction, params or checksum
    pkt[i] ^= data.draw(st.integers(1, 255))
    with pytest.raises(p1.ProtocolError):
        p1.decode_instruction(bytes(pkt))


packets = st.builds(
    lambda i, c, p: p1.encode_packet(i, c, p),
    st.integers(0, 253), st.integers(0, 0x7F), st.binary(max_size=12).map(
        lambda b: bytes(x for x in b if x != 0xFF)),
)


def _feed_in_chunks(parser, stream, cuts):
    out = []
    pos = 0
    for c in sorted(cuts) + [len(stream)]:
        out += parser.feed(stream[pos:c])
        pos = max(pos, c)
    return out


@settings(max_examples=150)
@given(st.lists(st.tuples(st.binary(max_size=15).map(lambda b: b.replace(b"\xff", b"")),
                          packets), min_size=1, max_size=8),
       st.lists(st.integers(0, 400), max_size=10))
def test_parser_finds_every_packet_between_garbage(items, cuts):
    # garbage without FF can never start a header: every packet comes out, nothing else
    stream = b"".join(g + pkt for g, pkt in items)
    parser = p1.PacketParser()
    assert _feed_in_chunks(parser, stream, cuts) == [pkt for _, pkt in items]


@settings(max_examples=150)
@given(st.binary(max_size=80), st.lists(packets, min_size=1, max_size=40),
       st.lists(st.integers(0, 800), max_size=10))
def test_parser_recovers_after_arbitrary_garbage(garbage, pkts, cuts):
    # a false packet that starts in the garbage spans at most 259 bytes: every real
    # packet starting later than that comes out, in order
    tail = []
    while sum(map(len, tail)) < 300:
        tail += pkts
    stream = garbage + b"".join(tail)
    parser = p1.PacketParser()
    out = _feed_in_chunks(parser, stream, cuts)
    offset, expected = len(garbage), []
    for pkt in tail:
        if offset >= len(garbage) + 259:
            expected.append(pkt)
        offset += len(pkt)
    assert expected and out[-len(expected):] == expected
    assert parser.pending < 260


@given(packets, packets, st.data())
def test_parser_drops_a_broken_packet_and_keeps_the_next(first, second, data):
    broken = bytearray(first)
    i = data.draw(st.integers(4, len(broken) - 1))
    broken[i] ^= data.draw(st.integers(1, 255).filter(lambda x: broken[i] ^ x != 0xFF))
    parser = p1.PacketParser()
    assert parser.feed(bytes(broken) + second) == [second]
    assert parser.stats.bad_checksums >= 1


def test_truncated_packet_then_gap_discard_then_packet():
    parser = p1.PacketParser()
    assert parser.feed(p1.ping(1)[:4]) == []
    parser.discard()  # the 100 ms gap rule
    assert parser.feed(p1.ping(2)) == [p1.ping(2)]


# -- control tables ----------------------------------------------------------

def test_control_tables_share_layout_and_differ_in_defaults():
    ax, rx = AX12A_TABLE, RX24F_TABLE
    assert [(i.name, i.address, i.size) for i in ax.items] == [
        (i.name, i.address, i.size) for i in rx.items]
    mem_ax, mem_rx = ax.defaults(), rx.defaults()
    assert ax.value_at(mem_ax, "model_number") == 12 and rx.value_at(mem_rx, "model_number") == 24
    assert ax.value_at(mem_ax, "baud_rate") == 1 and rx.value_at(mem_rx, "baud_rate") == 34
    assert ax.to_si("baud_rate", 1) == 1_000_000
    assert rx.to_si("baud_rate", 34) == pytest.approx(57_142.9, abs=0.1)
    assert ax.value_at(mem_ax, "temperature_limit") == 70
    assert rx.value_at(mem_rx, "temperature_limit") == 80
    assert (ax.value_at(mem_ax, "max_voltage_limit"), rx.value_at(mem_rx, "max_voltage_limit")) \
        == (140, 190)
    for t, mem in ((ax, mem_ax), (rx, mem_rx)):
        assert t.value_at(mem, "return_delay_time") == 250
        assert t.value_at(mem, "ccw_angle_limit") == 1023
        assert t.value_at(mem, "cw_compliance_slope") == 32
        assert t.value_at(mem, "torque_limit") == t.value_at(mem, "max_torque") == 1023
        assert t.item("present_position").area == "RAM"
        assert t.item("baud_rate").area == "EEPROM"


def test_writes_out_of_range_or_read_only_are_refused_before_sending():
    with pytest.raises(ValueError, match="present_position is read-only"):
        RX24F_TABLE.encode("present_position", 100)
    with pytest.raises(ValueError, match="goal_position: 1024 outside 0..1023"):
        RX24F_TABLE.encode("goal_position", 1024)
    with pytest.raises(ValueError, match="status_return_level: 3"):
        AX12A_TABLE.encode("status_return_level", 3)
    with pytest.raises(ValueError, match="unknown control-table item 'goal'"):
        AX12A_TABLE.encode("goal", 1)
    assert RX24F_TABLE.encode("goal_position", 0x252) == (30, b"\x52\x02")


def test_conversions_go_through_servo_spec():
    t = RX24F_TABLE
    assert t.to_si("present_position", 512) == 0.0
    assert math.degrees(t.to_si("present_position", 1023)) == pytest.approx(150.0, abs=0.2)
    assert t.to_si("present_speed", 0x400 | 100) == pytest.approx(-100 * 0.111 * 2 * math.pi / 60)
    assert t.to_si("present_load", 1023) == pytest.approx(2.6)  # stall torque at 12 V
    assert load_fraction(0x400 | 512) == pytest.approx(-0.5, abs=1e-3)
    assert t.to_si("present_voltage", 120) == pytest.approx(12.0)
    assert t.to_si("return_delay_time", 250) == pytest.approx(500e-6)
    assert t.from_si("goal_position", math.radians(24.05)) == 0x252
    assert table_for("ax12a") is AX12A_TABLE and table_for(24) is RX24F_TABLE


def test_error_names_one_per_bit_lowest_first():
    assert p1.error_names(0) == "ok" and p1.error_names(0x80) == "ok"  # bit 7 is not an error
    assert p1.error_names(0x24) == "overheating, overload"
    assert p1.error_names(0x7F) == ("input voltage, angle limit, overheating, range, checksum, "
                                    "overload, instruction")
