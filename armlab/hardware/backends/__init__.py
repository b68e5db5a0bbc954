"""The parts of the controller's servos behind :class:`armlab.control.backend.Backend`
that every family shares: the part of a serial backend that does not depend on the
family (``servo_bus.py``; each family's own is its folder's ``backend.py`` in
:mod:`armlab.hardware.families`), the joint map (which servo drives which joint),
calibration files and an arm's gripper (its geometry and load; how a family's servo
holds it is its folder's ``gripper.py``)."""
