"""Controllers, observers, the control loop and headless experiments.

Sees servos only through :class:`control.backend.Backend`; never imports viser or pyserial.
"""
