"""Dynamixel protocol 1.0 (AX-12A, RX-24F: the thesis's servos), its entry.

Its packets (``packets.py``, thesis §3.5), control tables (``table.py``, thesis Table
2.1), firmware model (``firmware.py``), backend (``backend.py``) and emulator
(``emulator.py``) are in this folder.
"""

from __future__ import annotations

from armlab.hardware.families.dynamixel1 import packets
from armlab.hardware.families.dynamixel1.firmware import ServoModel
from armlab.hardware.families.dynamixel1.table import RX24F_TABLE, TABLES, table_for
from armlab.hardware.servos.family import ServoFamily

FAMILY = ServoFamily(
    key="dynamixel1", title="Dynamixel protocol 1.0", protocol=1, codec=packets,
    tables=TABLES, default_table=RX24F_TABLE, table_for=table_for, model_address=0,
    ping_data=0, status_overhead=packets.OVERHEAD, id_offset=2, group_read=False,
    broadcast_ping=False, spec_type=type(RX24F_TABLE.spec),
    firmware_item="firmware_version", limit_items=("cw_angle_limit", "ccw_angle_limit"),
    servo_model=ServoModel,
    aliases=("1", "1.0", "protocol1"),
)
