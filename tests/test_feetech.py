"""Feetech STS packets, sign-magnitude values and the STS3215 control table.

Every byte string here was built by hand from the documented frame (``FF FF ID LEN INST
P.. CHK``, LEN = n + 2, CHK = ~(ID + LEN + INST + ΣP) & 0xFF; Feetech's FTServo SDK) and
the instruction codes, not by the code under test; the table's addresses are those of
Feetech's SDK (``sms_sts.py``) and LeRobot's ``motors/feetech/tables.py``.
"""

from __future__ import annotations

import math

import pytest

from armlab.hardware.families.feetech import packets as ft
from armlab.hardware.families.feetech.table import (
    BAUDS,
    STS3215,
    STS3215_TABLE,
    StsControlTable,
    sts_table_for,
)


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def test_ping_of_id_1_and_its_status():
    assert ft.ping(1) == h("ff ff 01 02 01 fb")
    status = ft.decode_status(h("ff ff 01 02 00 fc"))
    assert (status.servo_id, status.error, status.params) == (1, 0, b"")
    assert ft.status(1) == h("ff ff 01 02 00 fc")


def test_write_of_goal_position_2048_to_id_1():
    # 1 + 5 + 3 + 42 + 0 + 8 = 59 = 0x3b; ~0x3b = 0xc4
    assert ft.write(1, 42, h("00 08")) == h("ff ff 01 05 03 2a 00 08 c4")
    address, data = STS3215_TABLE.encode("goal_position", 2048)
    assert ft.write(1, address, data) == h("ff ff 01 05 03 2a 00 08 c4")


def test_read_of_present_position_and_its_status():
    # 1 + 4 + 2 + 56 + 2 = 65 = 0x41; ~0x41 = 0xbe
    assert ft.read(1, 56, 2) == h("ff ff 01 04 02 38 02 be")
    status = ft.decode_status(h("ff ff 01 04 00 00 08 f2"))  # 1 + 4 + 8 = 13; ~13 = 0xf2
    assert STS3215_TABLE.decode("present_position", status.params) == 2048


def test_sync_write_of_goal_position_to_six_servos():
    # LEN = (2 + 1) * 6 + 4 = 22; sum = 0xfe + 0x16 + 0x83 + 0x2a + 0x02 + (1..6) + 6 * 8
    # = 254 + 22 + 131 + 42 + 2 + 21 + 48 = 520; 520 & 0xff = 8; ~8 = 0xf7
    packet = ft.sync_write(42, 2, {i: h("00 08") for i in range(1, 7)})
    assert packet == h("ff ff fe 16 83 2a 02 01 00 08 02 00 08 03 00 08 04 00 08 05 00 08"
                       " 06 00 08 f7")
    assert len(packet) == 26


def test_sync_read_of_six_present_positions():
    # LEN = 6 + 4 = 10; sum = 254 + 10 + 130 + 56 + 2 + 21 = 473; 473 & 0xff = 0xd9; ~ = 0x26
    assert ft.sync_read(56, 2, [1, 2, 3, 4, 5, 6]) == \
        h("ff ff fe 0a 82 38 02 01 02 03 04 05 06 26")


def test_reg_write_action_and_reset():
    assert ft.reg_write(2, 42, h("00 08"))[:5] == h("ff ff 02 05 04")
    assert ft.action() == h("ff ff fe 02 05 fa")  # 254 + 2 + 5 = 261; 261 & 0xff = 5; ~ = 0xfa
    with pytest.raises(ValueError, match="confirm"):
        ft.reset(1)
    assert ft.reset(1, confirm=True) == h("ff ff 01 02 0a f2")  # 1 + 2 + 10 = 13; ~ = 0xf2


def test_status_error_bits_are_feetech_s():
    status = ft.decode_status(ft.status(3, 0x24))
    assert status.error == ft.ErrorBits.OVERHEAT | ft.ErrorBits.OVERLOAD
    assert ft.describe_errors(status.error) == "overheating, overload (0x24)"
    with pytest.raises(ft.ServoError, match="servo 3 reports overheating, overload"):
        status.check()


def test_ids_past_252_are_refused():
    with pytest.raises(ValueError, match="0..252"):
        ft.ping(253)
    with pytest.raises(ValueError, match="0..252"):
        ft.sync_write(42, 2, {253: h("00 08")})


@pytest.mark.parametrize(("value", "bit", "word"), [
    (0, 15, 0x0000), (1, 15, 0x0001), (-1, 15, 0x8001), (32767, 15, 0x7FFF),
    (-32767, 15, 0xFFFF), (-2047, 11, 0x0FFF), (2047, 11, 0x07FF), (-1, 11, 0x0801),
    (-1000, 10, 0x07E8), (1000, 10, 0x03E8),
])
def test_sign_magnitude_round_trips(value, bit, word):
    assert ft.encode_sign_magnitude(value, bit) == word
    assert ft.decode_sign_magnitude(word, bit) == value


def test_sign_magnitude_edges():
    assert ft.decode_sign_magnitude(0x8000, 15) == 0  # "minus zero"
    assert ft.decode_sign_magnitude(0x0800, 11) == 0
    for value, bit in ((32768, 15), (-32768, 15), (2048, 11), (-2048, 11), (1024, 10)):
        with pytest.raises(ValueError, match="does not fit"):
            ft.encode_sign_magnitude(value, bit)


def test_sts3215_addresses_match_feetech_and_lerobot():
    want = {"model_number": (3, 2), "id": (5, 1), "baud_rate": (6, 1),
            "return_delay_time": (7, 1), "status_return_level": (8, 1),
            "min_position_limit": (9, 2), "max_position_limit": (11, 2),
            "temperature_limit": (13, 1), "max_voltage_limit": (14, 1),
            "min_voltage_limit": (15, 1), "max_torque": (16, 2),
            "p_coefficient": (21, 1), "d_coefficient": (22, 1), "i_coefficient": (23, 1),
            "protection_current": (28, 2), "homing_offset": (31, 2),
            "operating_mode": (33, 1), "overload_torque": (36, 1), "torque_enable": (40, 1),
            "acceleration": (41, 1), "goal_position": (42, 2), "goal_time": (44, 2),
            "goal_speed": (46, 2), "torque_limit": (48, 2), "lock": (55, 1),
            "present_position": (56, 2), "present_speed": (58, 2), "present_load": (60, 2),
            "present_voltage": (62, 1), "present_temperature": (63, 1), "moving": (66, 1),
            "present_current": (69, 2)}
    got = {name: (STS3215_TABLE.item(name).address, STS3215_TABLE.item(name).size)
           for name in want}
    assert got == want
    assert STS3215.model_number == 777
    assert sts_table_for("sts3215") is STS3215_TABLE and sts_table_for(777) is STS3215_TABLE
    assert BAUDS[0] == 1_000_000 and STS3215_TABLE.from_si("baud_rate", 1e6) == 0


def test_signed_items_encode_sign_magnitude_on_the_wire():
    t: StsControlTable = STS3215_TABLE
    assert t.encode("goal_speed", -100) == (46, h("64 80"))
    assert t.encode("homing_offset", -5) == (31, h("05 08"))
    assert t.decode("present_load", h("fa 04")) == -250  # bit 10: 0x04fa
    assert t.decode("present_speed", h("10 80")) == -16
    with pytest.raises(ValueError, match="read-only"):
        t.encode("present_position", 0)
    with pytest.raises(ValueError, match="outside"):
        t.encode("homing_offset", 2048)


def test_units_4096_counts_a_turn():
    t = STS3215_TABLE
    assert t.to_si("goal_position", 2048 + 1024) == pytest.approx(math.pi / 2)
    assert t.from_si("goal_position", -math.pi / 2) == 1024
    assert t.to_si("present_speed", 4096) == pytest.approx(2 * math.pi)  # counts a second
    assert t.to_si("present_voltage", 50) == pytest.approx(5.0)
    assert t.to_si("present_current", 100) == pytest.approx(0.65)
    assert t.to_si("torque_limit", 1000) == pytest.approx(STS3215.stall_torque)


def test_power_on_image_holds_the_model_number_and_the_position():
    mem = STS3215_TABLE.defaults(servo_id=4, present_position=1500)
    assert mem[3:5] == (777).to_bytes(2, "little")
    assert STS3215_TABLE.value_at(mem, "id") == 4
    assert STS3215_TABLE.value_at(mem, "goal_position") == 1500
    assert STS3215_TABLE.value_at(mem, "torque_limit") == 1000
    assert STS3215_TABLE.value_at(mem, "lock") == 1
