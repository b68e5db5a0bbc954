"""Protocol 2.0 packets against the ROBOTIS e-manual's own byte examples ("Protocol 2.0"
page: PING, READ, WRITE, REG_WRITE, ACTION, REBOOT, FACTORY_RESET, SYNC_READ,
SYNC_WRITE), a bit-by-bit CRC, byte stuffing and the parser's resynchronisation."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from armlab.hardware.families.xseries import packets as p2


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# e-manual, Protocol 2.0, one example per instruction (instruction, then status)
EXAMPLES = [
    (p2.ping(1), "ff ff fd 00 01 03 00 01 19 4e"),
    (p2.read(1, 132, 4), "ff ff fd 00 01 07 00 02 84 00 04 00 1d 15"),  # Present Position
    (p2.write(1, 116, (512).to_bytes(4, "little")),  # Goal Position 512
     "ff ff fd 00 01 09 00 03 74 00 00 02 00 00 ca 89"),
    (p2.reg_write(1, 104, (200).to_bytes(4, "little")),  # Goal Velocity 200
     "ff ff fd 00 01 09 00 04 68 00 c8 00 00 00 ae 8e"),
    (p2.action(1), "ff ff fd 00 01 03 00 05 02 ce"),
    (p2.reboot(1), "ff ff fd 00 01 03 00 08 2f 4e"),
    (p2.factory_reset(1, p2.ResetLevel.KEEP_ID, confirm=True),
     "ff ff fd 00 01 04 00 06 01 a1 e6"),
    (p2.sync_read(132, 4, [1, 2]), "ff ff fd 00 fe 09 00 82 84 00 04 00 01 02 ce fa"),
    (p2.sync_write(116, 4, {1: (150).to_bytes(4, "little"), 2: (170).to_bytes(4, "little")}),
     "ff ff fd 00 fe 11 00 83 74 00 04 00 01 96 00 00 00 02 aa 00 00 00 82 87"),
    (p2.status(1, 0, bytes((0x06, 0x04, 0x26))),  # PING's answer: model 1030, firmware 38
     "ff ff fd 00 01 07 00 55 00 06 04 26 65 5d"),
    (p2.status(1, 0, (166).to_bytes(4, "little")),  # READ's answer: position 166
     "ff ff fd 00 01 08 00 55 00 a6 00 00 00 8c c0"),
    (p2.status(2, 0, (2079).to_bytes(4, "little")),  # SYNC_READ: servo 2's answer
     "ff ff fd 00 02 08 00 55 00 1f 08 00 00 ba be"),
    (p2.status(1), "ff ff fd 00 01 04 00 55 00 a1 0c"),  # WRITE's answer
]


@pytest.mark.parametrize(("packet", "manual"), EXAMPLES, ids=[e[1][18:26] for e in EXAMPLES])
def test_packets_are_the_e_manuals_bytes(packet, manual):
    assert packet.hex(" ") == manual


def test_ping_answer_decodes_to_model_and_firmware():
    s = p2.decode_status(h("ff ff fd 00 01 07 00 55 00 06 04 26 65 5d"))
    assert s.servo_id == 1 and not s.error
    assert int.from_bytes(s.params[:2], "little") == 1030 and s.params[2] == 0x26


def _crc_bitwise(data: bytes) -> int:
    """CRC-16/BUYPASS one bit at a time (poly 0x8005, init 0, MSB first, no final xor)."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


@given(st.binary(max_size=300))
def test_table_crc_equals_the_bitwise_definition(data):
    assert p2.crc16(data) == _crc_bitwise(data)


@given(st.binary(max_size=60), st.binary(max_size=60))
def test_crc_continues_from_an_initial_value_across_odd_and_even_splits(a, b):
    assert p2.crc16(b, p2.crc16(a)) == _crc_bitwise(a + b)


def test_crc_check_value_of_crc16_buypass():
    assert p2.crc16(b"123456789") == 0xFEE8  # the catalogue's check value


def test_stuffing_inserts_fd_after_each_header_pattern_and_counts_in_len():
    pkt = p2.write(1, 0x0100, b"\xff\xff\xfd\x01")  # data that looks like a header
    assert b"\xff\xff\xfd\xfd\x01" in pkt
    assert pkt[5] | pkt[6] << 8 == len(pkt) - 7  # LEN counts the stuffed bytes
    back = p2.decode_instruction(pkt)
    assert back.params == b"\x00\x01\xff\xff\xfd\x01"


#: parameter bytes as a packet's data may hold them: any bytes, and runs made of the
#: header's pieces (FF FF FD, FF FF FD FD, FF, FD), which plain random bytes almost never
#: give, so that byte stuffing is exercised where it acts
PIECES = st.sampled_from([b"\xff\xff\xfd", b"\xff\xff\xfd\xfd", b"\xff", b"\xfd",
                          b"\x00", b"\xff\xff"])
PARAMS = st.one_of(
    st.binary(max_size=200),
    st.lists(st.one_of(PIECES, st.binary(max_size=3)), max_size=40).map(b"".join))


@given(st.integers(0, p2.MAX_ID), PARAMS)
def test_any_params_round_trip_through_encode_parse_decode(servo_id, params):
    parser = p2.PacketParser()
    wire = p2.status(servo_id, 0, params)
    stuffed = p2.stuff(params)
    assert p2.unstuff(stuffed) == params
    # after stuffing, a header pattern is always followed by the stuffing byte
    assert stuffed.count(b"\xff\xff\xfd") == stuffed.count(b"\xff\xff\xfd\xfd")
    (got,) = parser.feed(wire)
    s = p2.decode_status(got)
    assert (s.servo_id, s.params) == (servo_id, params)


@given(st.binary(max_size=64), st.binary(max_size=64))
def test_parser_resynchronises_after_garbage_and_a_broken_packet(junk, junk2):
    good1 = p2.status(3, 0, b"\x01\x02")
    broken = bytearray(p2.status(4, 0, b"\x05\x06"))
    broken[-1] ^= 0xFF  # bad CRC
    good2 = p2.status(5, 0, b"\xff\xff\xfd\x07")
    parser = p2.PacketParser()
    stream = junk + good1 + bytes(broken) + junk2 + good2
    got = []
    for i in range(0, len(stream), 7):  # arriving in pieces
        got += parser.feed(stream[i : i + 7])
    ids = [p2.decode_status(g).servo_id for g in got]
    assert ids[-1] == 5 and 3 in ids and 4 not in ids
    assert p2.decode_status(got[-1]).params == b"\xff\xff\xfd\x07"


def test_a_garbage_length_does_not_hold_the_stream():
    parser = p2.PacketParser()
    fake = p2.HEADER + bytes((1, 0xFF, 0xFF))  # LEN 65535: nothing waits for it
    assert parser.feed(fake + p2.status(1)) == [p2.status(1)]


def test_error_byte_number_and_alert():
    s = p2.decode_status(p2.status(1, 0x80 | p2.ErrorNumber.DATA_LIMIT))
    assert s.error.number == p2.ErrorNumber.DATA_LIMIT and s.error.alert
    assert "limits" in s.error.describe() and "hardware alert" in s.error.describe()
    with pytest.raises(p2.ServoError, match="servo 1 reports value outside"):
        s.check()
    assert not p2.decode_status(p2.status(1)).error


def test_hardware_error_status_names_each_bit():
    # the e-manual's Shutdown / Hardware Error Status table: bit 0 Input Voltage, 2
    # Overheating, 3 Motor Encoder, 4 Electrical Shock, 5 Overload (1, 6, 7 unused)
    for bit, name in ((0, "Input Voltage"), (2, "Overheating"), (3, "Motor Encoder"),
                      (4, "Electrical Shock"), (5, "Overload")):
        assert p2.describe_hardware_error(1 << bit) == \
            f"{name} (Hardware Error Status {1 << bit:#04x})"
    assert p2.describe_hardware_error(0x24) == \
        "Overheating, Overload (Hardware Error Status 0x24)"
    assert p2.describe_hardware_error(0) == p2.describe_hardware_error(0xC2) == "ok"


def test_malformed_packets_and_arguments_are_refused():
    with pytest.raises(p2.ProtocolError, match="bad CRC"):
        p2.decode_status(h("ff ff fd 00 01 04 00 55 00 a1 0d"))
    with pytest.raises(p2.ProtocolError, match="not a status"):
        p2.decode_status(p2.ping(1))
    with pytest.raises(ValueError, match="confirm"):
        p2.factory_reset(1)
    with pytest.raises(ValueError, match="outside"):
        p2.sync_read(132, 4, [253])
    with pytest.raises(ValueError, match="expected 4"):
        p2.sync_write(116, 4, {1: b"\x00"})
    with pytest.raises(ValueError, match="two bytes"):
        p2.read(1, 70000, 1)


def test_bulk_read_lists_id_address_length_for_each_servo():
    pkt = p2.decode_instruction(p2.bulk_read([(1, 144, 2), (2, 132, 4)]))
    assert pkt.servo_id == p2.BROADCAST_ID and pkt.instruction == p2.Instruction.BULK_READ
    assert pkt.params == bytes((1, 144, 0, 2, 0, 2, 132, 0, 4, 0))
