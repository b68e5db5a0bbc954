"""The arm a lab page drives: the backend a name opens (``backends.py``: the simulation,
the servos on a port) and a student's own law in its controller (``student_law.py``)."""
