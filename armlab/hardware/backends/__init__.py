"""The controller's servos behind :class:`armlab.control.backend.Backend`, the parts every
family shares: the simulated arm (one, or a batch's), the part of a serial backend that
does not depend on the family (``servo_bus.py``; each family's own is its folder's
``backend.py`` in :mod:`armlab.hardware.families`), the joint map (which servo drives
which joint), calibration files and an arm's gripper servo."""
