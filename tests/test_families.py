"""The servo-family registry: every place that chooses by servo family asks it.

Protocol tags, model numbers and names resolve to one family; the bus, the joint map and
the plant take their codec, tables and firmware model from it.
"""

from __future__ import annotations

import os
import threading
import tty

import pytest

from armlab.hardware.backends.joint_map import default_joint_map, servo_table
from armlab.hardware.families import DYNAMIXEL1, STS, XSERIES
from armlab.hardware.families.feetech import packets as ft
from armlab.hardware.families.feetech.table import STS3215, STS3215_TABLE
from armlab.hardware.families.xseries.table import XM430_W350
from armlab.hardware.servos.registry import FAMILIES, family, family_of_model, family_of_spec
from armlab.hardware.wire.bus import Bus
from armlab.kinematics.catalog import load_robot


@pytest.mark.parametrize(("tag", "want"), [
    (1, DYNAMIXEL1), (1.0, DYNAMIXEL1), ("1.0", DYNAMIXEL1), (2, XSERIES), (2.0, XSERIES),
    ("sts", STS), ("feetech", STS), ("xseries", XSERIES),
])
def test_protocol_tags_name_one_family(tag, want):
    assert family(tag) is want


def test_an_unknown_tag_lists_the_known_families():
    with pytest.raises(ValueError, match="'sts' \\(Feetech STS\\)"):
        family(3)


@pytest.mark.parametrize(("model", "want"), [
    (12, DYNAMIXEL1), ("RX-24F", DYNAMIXEL1), (1020, XSERIES), ("xm430", XSERIES),
    (777, STS), ("STS3215", STS),
])
def test_models_belong_to_their_family(model, want):
    assert family_of_model(model) is want
    assert servo_table(model) is want.table_for(model)


def test_an_unknown_model_lists_every_family_s_models():
    with pytest.raises(ValueError, match="AX-12A.*XM430-W350.*STS3215"):
        servo_table("MX-64")


def test_each_family_s_tables_hold_their_model_number_where_it_says():
    for fam in FAMILIES:
        for number, table in fam.tables.items():
            item = table.item("model_number")
            assert (item.address, item.size) == (fam.model_address, 2)
            assert table.spec.model_number == number
            assert family_of_spec(table.spec) is fam


def test_the_plant_runs_each_family_s_firmware_model():
    from armlab.hardware.sim.plant import Plant

    arm = load_robot("receptionist_arm")
    plant = Plant(arm, XM430_W350)
    assert type(plant.servos[0]) is XSERIES.servo_model


def test_a_joint_map_of_sts3215s_speaks_sts():
    arm = load_robot("receptionist_arm")
    jmap = default_joint_map(arm, servo="STS3215")
    assert jmap.family is STS and jmap.protocol == "sts"
    assert jmap.spec is STS3215


def test_a_bus_speaks_sts_through_a_real_pty():
    """A PING and a READ on a bus opened with protocol "sts": the bytes written are the
    Feetech packets, and the status read back is decoded with Feetech's error bits."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    try:
        with Bus(path, protocol="sts", retries=0, timeout_margin=0.5) as bus:
            assert bus.family is STS and bus.table is STS3215_TABLE
            # a servo answering by hand-built packets, each after its request arrived
            def servo() -> None:
                parser = ft.PacketParser()
                answers = iter([ft.status(1, 0x20),
                                ft.status(1, 0, (777).to_bytes(2, "little"))])
                seen = []
                while len(seen) < 2:
                    for raw in parser.feed(os.read(master, 64)):
                        seen.append(raw)
                        os.write(master, next(answers))
                requests.extend(seen)

            requests: list[bytes] = []
            t = threading.Thread(target=servo, daemon=True)
            t.start()
            status = bus.ping(1)
            assert status.error == ft.ErrorBits.OVERLOAD
            assert bus.errors[1] == ft.ErrorBits.OVERLOAD
            assert bus.identify(1) is STS3215_TABLE
            t.join(timeout=10)
            assert requests == [ft.ping(1), ft.read(1, 3, 2)]
    finally:
        os.close(master)
        os.close(slave)


def test_every_family_names_its_serial_and_simulated_backends():
    from armlab.hardware import family_parts
    from armlab.hardware.backends.servo_bus import ServoBusBackend
    from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
    from armlab.hardware.servos.registry import FAMILIES

    for f in FAMILIES:
        assert issubclass(family_parts.load(f, "real_backend"), ServoBusBackend)
        assert family_parts.load(f, "real_backend").PROTOCOL == f.protocol
        if family_parts.has(f, "sim_backend"):
            assert issubclass(family_parts.load(f, "sim_backend"), SimBackend)
        assert family_parts.has(f, "emulator") and callable(family_parts.load(f, "emulator"))
    assert not family_parts.has(FAMILIES[0], "sim_backend")  # 1.0: the plain SimBackend
    with pytest.raises(ValueError, match="has no sim backend"):
        family_parts.load(FAMILIES[0], "sim_backend")


def test_every_familys_packet_module_is_its_codec():
    """Each family's codec offers what the bus, the scan and the emulator call, its
    parser counts what it dropped, and a family without SYNC_READ says so."""
    from armlab.hardware.families.dynamixel1 import packets as p1
    from armlab.hardware.servos.family import Codec
    from armlab.hardware.servos.registry import FAMILIES

    for f in FAMILIES:
        codec: Codec = f.codec  # (mypy checks each module against Codec where they are made)
        parser = codec.PacketParser()
        assert list(parser.feed(codec.ping(1))) == [codec.ping(1)]
        assert parser.broken == 0 and parser.pending == 0
        assert codec.decode_instruction(codec.ping(3)).servo_id == 3
        assert codec.decode_status(codec.status(4)).servo_id == 4
        if not f.group_read:
            with pytest.raises(p1.ProtocolError, match="no SYNC_READ"):
                codec.sync_read(0, 2, [1, 2])


def test_one_ping_per_id_serves_both_families_that_share_the_frame():
    from armlab.hardware.wire.scan import default_protocols, scan_time_bound

    assert default_protocols() == (1, 2, "sts")
    bound = scan_time_bound("/dev/ttyUSB0", (1_000_000,), range(10), 0.01,
                            protocols=(1, "sts"))
    assert bound == scan_time_bound("/dev/ttyUSB0", (1_000_000,), range(10), 0.01,
                                    protocols=(1,))


def test_a_drafted_map_of_scanned_sts3215s_loads_back_as_sts(tmp_path):
    from armlab.hardware.backends.joint_map import draft_joint_map, load_joint_map
    from armlab.hardware.wire.scan import Found

    model = load_robot("so101")
    found = [Found(i, 777, "STS3215", 3, 1e6, 0, 0, 4095, -180.0, 179.9, 0, "sts")
             for i in range(1, 6)]
    path = tmp_path / "so101.toml"
    path.write_text(draft_joint_map(found, model))
    assert 'protocol = "sts"' in path.read_text()
    jmap = load_joint_map(path, model)
    assert (jmap.servo, jmap.protocol, jmap.ids) == ("STS3215", "sts", (1, 2, 3, 4, 5))
