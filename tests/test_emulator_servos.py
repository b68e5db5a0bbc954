"""The emulated servos: control-table semantics, instructions, the plant behind them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _emulator import emulator

from armlab.hardware.families.dynamixel1 import packets as p1
from armlab.hardware.families.dynamixel1.backend import DynamixelBackend
from armlab.hardware.families.dynamixel1.emulator import emulated_network
from armlab.hardware.wire.scan import scan
from armlab.kinematics.catalog import load_robot

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal

ARM = load_robot("receptionist_arm")


def _send(net, packet: bytes, baud: float = 1_000_000) -> list[p1.StatusPacket]:
    return [p1.decode_status(r) for _, r in net.handle(p1.decode_instruction(packet), baud=baud)]


def test_default_ids_models_and_power_on_table():
    net = emulated_network(ARM)
    assert [s.servo_id for s in net.servos] == [1, 3, 5]  # thesis left arm
    s = net.servos[0]
    assert s.table.name == "RX-24F" and s.get("model_number") == 24
    assert s.get("baud_rate") == 1 and s.get("return_delay_time") == 250
    assert s.get("goal_position") == s.get("present_position")  # copied at power-on
    assert s.get("torque_limit") == s.get("max_torque") == 1023
    quad = emulated_network(load_robot("quadruped"))
    assert [s.servo_id for s in quad.servos] == list(range(1, 13))
    assert {s.table.name for s in quad.servos} == {"AX-12A"}
    assert len(quad.physics.plants) == 4  # one plant per leg chain


def test_status_return_level_and_broadcast():
    net = emulated_network(ARM)
    assert len(_send(net, p1.write(1, 25, b"\x01"))) == 1  # level 2: every instruction
    assert _send(net, p1.write(p1.BROADCAST_ID, 25, b"\x00")) == []  # broadcast: never
    assert [s.get("led") for s in net.servos] == [0, 0, 0]
    _send(net, p1.write(1, 16, b"\x01"))
    assert _send(net, p1.write(1, 25, b"\x01")) == []
    assert len(_send(net, p1.read(1, 25, 1))) == 1
    _send(net, p1.write(1, 16, b"\x00"))
    assert _send(net, p1.read(1, 25, 1)) == [] and len(_send(net, p1.ping(1))) == 1


def test_error_bits_for_range_instruction_checksum_and_angle_limit():
    net = emulated_network(ARM)
    (st,) = _send(net, p1.write(3, 30, p1.word(1100)))  # goal beyond 1023
    assert st.error == p1.ErrorBits.RANGE and net.servos[1].get("goal_position") == 512
    (st,) = _send(net, p1.write(3, 36, p1.word(100)))  # present position is read-only
    assert st.error == p1.ErrorBits.RANGE
    (st,) = _send(net, p1.read(3, 45, 10))  # past the table's end
    assert st.error == p1.ErrorBits.RANGE and st.params == b""
    (st,) = _send(net, p1.encode_packet(3, 0x92, b"\x00"))  # BULK_READ: not on these models
    assert st.error == p1.ErrorBits.INSTRUCTION
    (st,) = _send(net, p1.action(3))  # ACTION without REG_WRITE
    assert st.error == p1.ErrorBits.INSTRUCTION
    broken = bytearray(p1.write(3, 25, b"\x01"))
    broken[-1] ^= 0x55
    (s3, reply), = net.checksum_error(bytes(broken))
    assert s3.servo_id == 3 and p1.decode_status(reply).error == p1.ErrorBits.CHECKSUM
    _send(net, p1.write(3, 6, p1.word(400) + p1.word(600)))  # angle limits 400..600
    (st,) = _send(net, p1.write(3, 30, p1.word(700)))
    assert st.error == p1.ErrorBits.ANGLE_LIMIT  # stored, stops at the limit, flagged
    (st,) = _send(net, p1.write(3, 30, p1.word(550)))
    assert st.error == 0


def test_silent_at_the_wrong_baud():
    net = emulated_network(ARM, baud=57_600)
    assert _send(net, p1.ping(1), baud=1_000_000) == []
    assert _send(net, p1.ping(1), baud=57_600)[0].servo_id == 1
    assert _send(net, p1.ping(1), baud=57_142)[0].servo_id == 1  # 2 000 000 / 35


def test_sync_write_drives_the_plant_and_present_values_follow():
    net = emulated_network(ARM)
    _send(net, p1.sync_write(24, 1, {1: b"\x01", 3: b"\x01", 5: b"\x01"}))
    goal = 512 + 150  # +44° on every joint
    _send(net, p1.sync_write(30, 4, {i: p1.word(goal) + p1.word(200) for i in (1, 3, 5)}))
    net.tick(0.1)
    moving = [s.get("moving") for s in net.servos]
    speed = [s.get("present_speed") & 0x3FF for s in net.servos]
    net.tick(3.0)
    (st,) = _send(net, p1.read(1, 36, 6))
    pos = st.params[0] | st.params[1] << 8
    assert moving == [1, 1, 1] and min(speed) > 0
    assert abs(pos - goal) <= 10  # there within 3° (gravity on compliance slope 32)
    true = net.physics.plants[0].q[0]  # the reading is the plant's true angle, quantised
    assert true == pytest.approx((pos - 512) * math.radians(300) / 1023, abs=math.radians(0.3))


def test_quadruped_scan_and_backend_over_a_pty():
    # the plant at 4 ms: twelve servos' physics at 1 ms takes most of a core of a slow
    # machine, and beside the other real-time tests their replies missed a 50 ms margin
    with emulator("--robot", "quadruped", "--dt", "0.004") as emu:
        found = scan(emu.port, (1_000_000,), ids=range(0, 20), margin=0.2)
        assert [(f.servo_id, f.model) for f in found] == [(i, "AX-12A") for i in range(1, 13)]
        quad = load_robot("quadruped")
        b = DynamixelBackend(quad, emu.port, timeout_margin=0.1)
        try:
            state = b.read()
            assert state.position.shape == (12,) and np.all(np.isfinite(state.position))
            assert b.map.servo == "AX-12A"
        finally:
            b.close()


def test_the_bench_s_quadruped_wire_bound_counts_the_bytes_of_one_backend_cycle(tmp_path):
    """``armlab bench --only bus`` sets ``bus_quadruped_cycle_median_ms`` beside a wire bound
    of :func:`~armlab.app.benches.bus.protocol1_cycle_bytes` × 10 bits / baud: the bytes of
    one cycle are what the protocol-1.0 backend sends and the twelve servos answer (a READ
    and its status per servo, one SYNC_WRITE of the goals); for the thesis arm's three
    servos, 3 × (8 + 12) + 23 bytes."""
    from armlab.app.benches.bus import QUADRUPED_SERVOS, protocol1_cycle_bytes

    with emulator("--robot", "quadruped", "--dt", "0.004", log_dir=tmp_path) as emu:
        b = DynamixelBackend(load_robot("quadruped"), emu.port, timeout_margin=0.1)
        try:
            state = b.read()
            cycle = emu.cycle_traffic(b, state.position, np.full(12, 1.0))
        finally:
            b.close()
    assert [tag for _, tag, _ in cycle] == ["rx"] + ["rx", "tx"] * QUADRUPED_SERVOS
    assert sum(len(raw) for _, _, raw in cycle) == protocol1_cycle_bytes(QUADRUPED_SERVOS) \
        == 308
    assert protocol1_cycle_bytes(3) == 3 * (8 + 12) + 23
