"""Controllers, observers, the control loop and headless experiments.

Sees servos only through :class:`armlab.control.backend.Backend`; never imports viser or pyserial.
"""
