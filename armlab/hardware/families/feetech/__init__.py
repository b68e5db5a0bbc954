"""Feetech STS/SMS (the SO-101's STS3215), its entry.

Its packets (``packets.py``: protocol 1.0's frame with Feetech's own instructions),
control tables (``table.py``), firmware model (``firmware.py``), backends
(``backend.py`` on a port, ``sim_backend.py`` simulated) and emulator (``emulator.py``)
are in this folder.
"""

from __future__ import annotations

from armlab.hardware.families.feetech import gripper, packets
from armlab.hardware.families.feetech.firmware import SILENT, StsServoModel
from armlab.hardware.families.feetech.table import STS3215_TABLE, STS_TABLES, sts_table_for
from armlab.hardware.servos.family import ServoFamily

FAMILY = ServoFamily(
    key="sts", title="Feetech STS", protocol="sts", codec=packets, tables=STS_TABLES,
    default_table=STS3215_TABLE, table_for=sts_table_for, model_address=3, ping_data=0,
    status_overhead=packets.OVERHEAD, id_offset=2, group_read=True, broadcast_ping=False,
    spec_type=type(STS3215_TABLE.spec), firmware_item="firmware_major",
    limit_items=("min_position_limit", "max_position_limit"),
    servo_model=StsServoModel,
    drives_gripper=gripper.drives_gripper, grip_note=gripper.grip_note,
    replies_all_level=1,
    aliases=("feetech", "scs", "sms_sts"),
    # its status error bits, and one that is none: the servo stops answering
    fault_flags={**{flag.name.lower(): int(flag) for flag in packets.ErrorBits if flag.name},
                 "silent": SILENT},
)
