"""Servos: the wire and its protocols, the servos' tables, the simulation, the backends the
controller drives, and the emulator.

Importing this package registers every servo family (:mod:`armlab.hardware.families`) in
:mod:`armlab.hardware.servos.registry`, so a part below the families finds one there
before anything asks, whichever module was imported first.
"""

from armlab.hardware import families as families  # registers the families
