"""A servo family the lab does not ship, added in one folder plus its registry entry, is
scanned, emulated and driven with no file of the lab touched.

The toy family is a clone of the thesis's servos: protocol 1.0's frames under its own
protocol tag ("toy"), its own model (TOY-1, model number 4242, half the RX-24F's speed and
more torque), its own datasheet class, firmware model, backend and emulator. Its folder is
written to a temporary directory; a child Python (so the registration stays out of the
other tests' processes) registers it with ``armlab.hardware.family_parts.register``,
serves its emulator on a real pseudo-terminal, scans the line, opens the arm through
``open_servo_backend`` and drives a joint to a goal.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.realtime  # the emulator over a pseudo-terminal

ROOT = Path(__file__).resolve().parent.parent

#: the toy family's folder: one file a part, as the lab's own families have
TOY = {
    "__init__.py": '''
        """The toy servo (TOY-1): a clone speaking protocol 1.0's frames, its entry."""
        from armlab.hardware.servos.family import ServoFamily
        from toyservo import packets
        from toyservo.firmware import ToyServoModel
        from toyservo.table import TABLES, TOY1_TABLE, table_for

        FAMILY = ServoFamily(
            key="toy", title="Toy servo", protocol="toy", codec=packets, tables=TABLES,
            default_table=TOY1_TABLE, table_for=table_for, model_address=0, ping_data=0,
            status_overhead=packets.OVERHEAD, id_offset=2, group_read=False,
            broadcast_ping=False, spec_type=type(TOY1_TABLE.spec),
            firmware_item="firmware_version",
            limit_items=("cw_angle_limit", "ccw_angle_limit"), servo_model=ToyServoModel)
    ''',
    "packets.py": '''
        """The toy servo's packets: protocol 1.0's frames, as a clone's firmware has them."""
        from armlab.hardware.families.dynamixel1.packets import (  # noqa: F401
            BROADCAST_ID, MAX_ID, OVERHEAD, PacketParser, ProtocolError, action,
            decode_instruction, decode_status, factory_reset, ping, read, reg_write, status,
            sync_read, sync_write, write, write_refusal)
    ''',
    "table.py": '''
        """The TOY-1's datasheet and control table (the RX-24F's layout)."""
        import dataclasses

        from armlab.hardware.families.dynamixel1.table import RX24F_TABLE
        from armlab.hardware.servos.control_table import ControlTable
        from armlab.hardware.servos.servo_spec import RPM, ServoSpec


        @dataclasses.dataclass(frozen=True)
        class ToySpec(ServoSpec):
            """A toy servo's datasheet: its own class, so the plant runs its firmware."""


        TOY1 = ToySpec(name="TOY-1", model_number=4242, stall_torque=4.0,
                       no_load_speed=60 * RPM, gear_ratio=300.0, default_baud_value=1,
                       temperature_limit=75, max_voltage=14.0)
        TOY1_TABLE = ControlTable(TOY1, RX24F_TABLE.items)
        TABLES = {4242: TOY1_TABLE}


        def table_for(model):
            if model in (4242, "TOY-1", "toy1") or model == TOY1:
                return TOY1_TABLE
            raise ValueError(f"unknown servo model {model!r}; known: TOY-1")
    ''',
    "firmware.py": '''
        """The TOY-1's firmware: the RX-24F's model, its motor the TOY-1's datasheet."""
        from armlab.hardware.families.dynamixel1.firmware import ServoModel


        class ToyServoModel(ServoModel):
            """The protocol-1.0 firmware model driving a TOY-1."""
    ''',
    "backend.py": '''
        """The TOY-1 on a serial port: the protocol-1.0 backend under the toy's tag."""
        from armlab.hardware.families.dynamixel1.backend import DynamixelBackend


        class ToyBackend(DynamixelBackend):
            PROTOCOL = "toy"
    ''',
    "emulator.py": '''
        """Emulated TOY-1s: protocol-1.0 servos of the toy's table, moved by the plant."""
        from armlab.hardware.families.dynamixel1.emulator import (
            PlantPhysics, ServoNetwork, make_servos)
        from armlab.hardware.servos.servo_spec import value_from_baud
        from armlab.hardware.sim.plant import Plant
        from toyservo.table import TOY1_TABLE


        class ToyNetwork(ServoNetwork):
            protocol = "toy"


        def network_for_map(model, jmap, *, baud=1_000_000, dt=1e-3):
            plant = Plant(model, TOY1_TABLE.spec, dt=dt)
            slots = [(0, j) for j in range(model.n)]
            positions = [s.present_position() for s in plant.servos]
            servos = make_servos([TOY1_TABLE] * model.n, jmap.ids,
                                 baud_value=value_from_baud(baud), positions=positions)
            physics = PlantPhysics([plant], slots)
            for s in servos:
                physics.apply(s)
                physics.report(s)
            return ToyNetwork(servos, physics)
    ''',
}

#: the child: register the family (its one entry), emulate, scan, drive
DRIVER = '''
import json, math, sys, threading, time
sys.path.insert(0, sys.argv[1])

import toyservo
from armlab.hardware import family_parts
from armlab.hardware.servos.registry import family, family_of_spec

family_parts.register(toyservo.FAMILY, family_parts.Parts(
    real_backend=lambda: __import__("toyservo.backend").backend.ToyBackend,
    emulator=lambda: __import__("toyservo.emulator").emulator.network_for_map))

from armlab.hardware.backends.joint_map import default_joint_map
from armlab.hardware.emulator.pty import PtyEmulator
from armlab.hardware.wire.scan import scan
from armlab.kinematics.catalog import load_robot

out = {"family": family("toy").title, "of_spec": family_of_spec(toyservo.table.TOY1).key}
model = load_robot("receptionist_arm")
jmap = default_joint_map(model, servo="TOY-1")
network = family_parts.load(family("toy"), "emulator")(model, jmap, baud=1_000_000)
out["plant_firmware"] = type(network.physics.plants[0].servos[0]).__name__
emu = PtyEmulator(network)
stop = threading.Event()
serving = threading.Thread(target=emu.serve, args=(stop.is_set,), daemon=True)
serving.start()
try:
    found = scan(emu.path, (1_000_000,), ids=range(0, 8), protocols=("toy",), margin=0.05)
    out["scan"] = sorted((f.servo_id, f.model, str(f.protocol)) for f in found)
    backend = family_parts.open_servo_backend(model, emu.path, joint_map=jmap,
                                              timeout_margin=0.1)
    try:
        out["backend"] = type(backend).__name__
        start = backend.read().position.copy()
        backend.set_torque(True)
        goal = start.copy()
        goal[0] += math.radians(20.0)
        deadline = time.monotonic() + 60.0
        q = start
        while time.monotonic() < deadline:
            backend.write(goal, [1.0] * model.n)
            q = backend.read().position
            if abs(q[0] - goal[0]) < math.radians(2.0):
                break
            time.sleep(0.02)
        out["moved_deg"] = math.degrees(q[0] - start[0])
        backend.set_torque(False)
    finally:
        backend.close()
finally:
    stop.set()
    serving.join(10.0)
    emu.close()
print(json.dumps(out))
'''


def test_a_toy_family_in_one_folder_is_scanned_emulated_and_driven(tmp_path):
    folder = tmp_path / "toyservo"
    folder.mkdir()
    for name, text in TOY.items():
        (folder / name).write_text(textwrap.dedent(text).lstrip())
    before = subprocess.run(["git", "status", "--porcelain"], cwd=ROOT, capture_output=True,
                            text=True).stdout
    done = subprocess.run([sys.executable, "-c", DRIVER, str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["family"] == "Toy servo"
    # the plant runs the toy's own firmware, found by its datasheet class (a kind of the
    # RX-24F's: its own class comes first)
    assert out["of_spec"] == "toy"
    assert out["plant_firmware"] == "ToyServoModel"
    # the scan names the toy's model at the receptionist arm's IDs
    assert out["scan"] == [[1, "TOY-1", "toy"], [3, "TOY-1", "toy"], [5, "TOY-1", "toy"]]
    assert out["backend"] == "ToyBackend"
    assert out["moved_deg"] == pytest.approx(20.0, abs=2.0)
    # nothing of the lab was written
    after = subprocess.run(["git", "status", "--porcelain"], cwd=ROOT, capture_output=True,
                           text=True).stdout
    assert after == before
