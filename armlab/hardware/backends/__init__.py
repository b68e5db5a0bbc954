"""The controller's servos behind :class:`armlab.control.backend.Backend`: simulated ones
(one arm, X-series, a batch's arm) and real ones on a serial port (protocol 1.0, X-series),
the joint map (which servo drives which joint) and an arm's gripper servo."""
