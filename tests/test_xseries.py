"""X-series control tables and datasheets (ROBOTIS e-manual pages of the XL430-W250-T,
XM430-W350-T and XL330-M288-T; ../shared notes list the same addresses)."""

from __future__ import annotations

import math

import pytest

from armlab.hardware.families.xseries import packets as p2
from armlab.hardware.families.xseries.table import (
    X_TABLES,
    XL330_M288_TABLE,
    XL430_W250_TABLE,
    XM430_W350_TABLE,
    OperatingMode,
    x_table_for,
)

#: e-manual control table: (name, address, bytes), the same on the three models
SHARED = [("model_number", 0, 2), ("firmware_version", 6, 1), ("id", 7, 1), ("baud_rate", 8, 1),
          ("return_delay_time", 9, 1), ("drive_mode", 10, 1), ("operating_mode", 11, 1),
          ("velocity_limit", 44, 4), ("max_position_limit", 48, 4),
          ("min_position_limit", 52, 4), ("torque_enable", 64, 1), ("led", 65, 1),
          ("status_return_level", 68, 1), ("hardware_error_status", 70, 1),
          ("velocity_i_gain", 76, 2), ("velocity_p_gain", 78, 2), ("position_d_gain", 80, 2),
          ("position_i_gain", 82, 2), ("position_p_gain", 84, 2), ("goal_pwm", 100, 2),
          ("goal_velocity", 104, 4), ("profile_acceleration", 108, 4),
          ("profile_velocity", 112, 4), ("goal_position", 116, 4), ("moving", 122, 1),
          ("present_pwm", 124, 2), ("present_velocity", 128, 4), ("present_position", 132, 4),
          ("present_input_voltage", 144, 2), ("present_temperature", 146, 1)]


@pytest.mark.parametrize("table", list(X_TABLES.values()), ids=lambda t: t.name)
def test_addresses_and_sizes_are_the_e_manuals(table):
    for name, address, size in SHARED:
        item = table.item(name)
        assert (item.address, item.size) == (address, size), name


def test_model_numbers_and_lookup():
    assert {t.name: n for n, t in X_TABLES.items()} == {
        "XL430-W250": 1060, "XM430-W350": 1020, "XL330-M288": 1200}
    assert x_table_for("xm430") is XM430_W350_TABLE and x_table_for(1200) is XL330_M288_TABLE
    with pytest.raises(ValueError, match="known: XL430-W250"):
        x_table_for("XC330")


def test_address_126_is_current_where_sensed_and_load_on_the_xl430():
    assert XM430_W350_TABLE.item("present_current").address == 126
    assert XL330_M288_TABLE.item("present_current").address == 126
    assert XL430_W250_TABLE.item("present_load").address == 126
    with pytest.raises(ValueError, match="unknown control-table item 'goal_current'"):
        XL430_W250_TABLE.item("goal_current")  # no current modes without a sensor
    # 2.69 mA per count on the XM430, 1 mA on the XL330; 0.1 % of max torque on the XL430
    assert XM430_W350_TABLE.to_si("present_current", 100) == pytest.approx(0.269)
    assert XL330_M288_TABLE.to_si("present_current", -100) == pytest.approx(-0.100)
    assert XL430_W250_TABLE.to_si("present_load", 1000) == pytest.approx(1.5)  # 100 % = stall


def test_signed_items_round_trip_through_the_wire_bytes():
    t = XM430_W350_TABLE
    address, data = t.encode("goal_velocity", -200)
    assert (address, data) == (104, (-200).to_bytes(4, "little", signed=True))
    assert t.decode("goal_velocity", data) == -200
    assert t.decode("present_current", (-5).to_bytes(2, "little", signed=True)) == -5


def test_units_position_velocity_baud():
    t = XM430_W350_TABLE
    assert t.to_si("present_position", 2048) == 0.0  # the horn's centre
    assert math.degrees(t.to_si("present_position", 2049)) == pytest.approx(0.0879, abs=1e-4)
    assert t.from_si("goal_position", math.pi / 2) == 3072
    assert t.to_si("present_velocity", 1) * 60 / (2 * math.pi) == pytest.approx(0.229)
    assert t.to_si("baud_rate", 3) == 1_000_000 and t.from_si("baud_rate", 57_600) == 1


def test_writes_are_checked_before_anything_is_sent():
    t = XM430_W350_TABLE
    with pytest.raises(ValueError, match="goal_position: 4096 outside 0..4095"):
        t.encode("goal_position", 4096)
    with pytest.raises(ValueError, match="read-only"):
        t.encode("present_position", 0)
    with pytest.raises(ValueError, match="not available on the XL430-W250"):
        XL430_W250_TABLE.check_operating_mode(OperatingMode.CURRENT_BASED_POSITION)
    assert t.check_operating_mode(OperatingMode.CURRENT_BASED_POSITION) == 5


def test_torque_from_current_uses_the_stall_point_constant():
    spec = XM430_W350_TABLE.spec
    assert spec.torque_constant == pytest.approx(4.1 / 2.3)
    raw = spec.current_to_raw(1.0)  # 1 A
    assert spec.raw_to_torque(raw) == pytest.approx(4.1 / 2.3, rel=3e-3)


def test_power_on_image_reads_back_and_packs_a_sync_read_answer():
    t = XL330_M288_TABLE
    mem = t.defaults(servo_id=11, present_position=3000)
    assert t.value_at(mem, "model_number") == 1200 and t.value_at(mem, "id") == 11
    assert t.value_at(mem, "operating_mode") == OperatingMode.POSITION
    assert t.value_at(mem, "goal_position") == t.value_at(mem, "present_position") == 3000
    # a SYNC_READ of present current, velocity and position (126..135) answers from here
    data = bytes(mem[126:136])
    pkt = p2.decode_status(p2.status(11, 0, data))
    assert t.decode("present_position", pkt.params[6:10]) == 3000
