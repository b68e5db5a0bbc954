"""The servo families the lab drives, one folder each, and how to find one.

A family (:class:`~armlab.hardware.servos.family.ServoFamily`) is everything the lab
knows about one kind of servo, all in its own folder ``families/<family>/``:

- ``packets.py``: its packet codec (typed by :class:`~armlab.hardware.servos.family.Codec`);
- ``table.py``: its control tables by model number;
- ``firmware.py``: its firmware model for the simulation;
- ``backend.py``: the backend on a serial port;
- ``sim_backend.py``: the simulated arm with its servos (protocol 1.0's ``SimBackend``,
  the lab's default arm; the X-series and Feetech ones extend it with a gripper);
- ``gripper.py``: how its servo holds an arm's gripper (the families that drive one);
- ``emulator.py``: its emulated servos behind a pseudo-terminal;
- ``__init__.py``: its entry, ``FAMILY``, naming its codec, tables and firmware model.

Protocol 1.0's folder also holds the thesis's servos simulated many at once: a class's
private arms (``batched_plant.py``, ``batched_backend.py``) and seed 003's quadruped on
AX-12A servos (``quadruped.py``, N at once ``batched_quadruped.py``).

Importing this package registers the three in :mod:`armlab.hardware.servos.registry`
(``armlab.hardware`` imports it first of all), where the bus, the scan, the joint map,
the plant and the emulator find a family (by protocol, name or model) without naming
one: nothing outside the family folders imports them. The entry does not import the
backends and the emulator: :mod:`armlab.hardware.family_parts` does, when first asked
for.
"""

from __future__ import annotations

from armlab.hardware.families.dynamixel1 import FAMILY as DYNAMIXEL1
from armlab.hardware.families.feetech import FAMILY as STS
from armlab.hardware.families.xseries import FAMILY as XSERIES
from armlab.hardware.servos.registry import FAMILIES, register

for _entry in (DYNAMIXEL1, XSERIES, STS):
    if _entry not in FAMILIES:
        register(_entry)
