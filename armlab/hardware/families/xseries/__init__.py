"""Dynamixel X-series on protocol 2.0 (XL330, XL430, XM430, ...), its entry.

Its packets (``packets.py``), control tables (``table.py``), firmware model
(``firmware.py``), backends (``backend.py`` on a port, ``sim_backend.py`` simulated) and
emulator (``emulator.py``) are in this folder.
"""

from __future__ import annotations

from armlab.hardware.families.xseries import gripper, packets
from armlab.hardware.families.xseries.firmware import XServoModel
from armlab.hardware.families.xseries.table import X_TABLES, XM430_W350_TABLE, x_table_for
from armlab.hardware.servos.family import ServoFamily

FAMILY = ServoFamily(
    key="xseries", title="Dynamixel X-series (protocol 2.0)", protocol=2, codec=packets,
    tables=X_TABLES, default_table=XM430_W350_TABLE, table_for=x_table_for, model_address=0,
    ping_data=3, status_overhead=packets.status_length(0), id_offset=4, group_read=True,
    broadcast_ping=True, spec_type=type(XM430_W350_TABLE.spec),
    firmware_item="firmware_version", limit_items=("min_position_limit", "max_position_limit"),
    servo_model=XServoModel,
    drives_gripper=gripper.drives_gripper, grip_note=gripper.grip_note,
    aliases=("2", "2.0", "protocol2", "dynamixel2"),
    reboot_packet=packets.reboot, bulk_read_packet=packets.bulk_read,
    # its Hardware Error Status bits
    fault_flags={flag.name.lower(): int(flag) for flag in packets.HardwareError if flag.name},
)
