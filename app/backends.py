"""Choosing a backend by name: ``make_backend("sim" | "serial", model, ...)``."""

from __future__ import annotations

import importlib
from typing import Any

from control.backend import Backend
from kinematics.model import SerialChain

KINDS = ("sim", "serial")


def make_backend(kind: str, model: SerialChain, *, port: str | None = None,
                 baud: int | None = None, **kw: Any) -> Backend:
    """Open the backend ``kind`` for ``model``.

    Args:
        kind: "sim" (simulated arm and servos, the default of the lab) or "serial"
            (Dynamixel servos, real or emulated, on a serial port).
        model: the robot's serial chain.
        port, baud: serial port and bit rate (for "serial" only).
        **kw: passed to the backend's constructor (e.g. ``q0``, ``specs``, ``dt`` for "sim").

    Raises:
        ValueError: unknown kind, options that do not fit it, or the serial backend missing.
    """
    if kind == "sim":
        if port is not None or baud is not None:
            raise ValueError("the sim backend takes no port or baud (those are for serial)")
        from hardware.sim_backend import SimBackend

        return SimBackend(model, **kw)
    if kind == "serial":
        try:
            module = importlib.import_module("hardware.dynamixel_backend")
        except ModuleNotFoundError as exc:
            if exc.name != "hardware.dynamixel_backend":
                raise
            raise ValueError("the serial backend is not available") from None
        if port is None:
            raise ValueError("the serial backend needs a port (e.g. /dev/ttyUSB0)")
        if baud is not None:
            kw["baud"] = baud
        return module.DynamixelBackend(model, port, **kw)
    raise ValueError(f"unknown backend {kind!r}; choose one of {', '.join(KINDS)}")
