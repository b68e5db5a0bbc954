"""Choosing a backend by name: ``make_backend("sim" | "serial", model, ...)``; the
compliance loop over one (``loop_over``)."""

from __future__ import annotations

from typing import Any

from armlab.control.backend import Backend
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.kinematics.model import Quadruped, SerialChain

KINDS = ("sim", "serial")


def make_backend(kind: str, model: SerialChain | Quadruped, *, port: str | None = None,
                 baud: int | None = None, **kw: Any) -> Backend:
    """Open the backend ``kind`` for ``model``.

    Args:
        kind: "sim" (simulated arm and servos, the default of the lab) or "serial"
            (Dynamixel servos, real or emulated, on a serial port).
        model: the robot's serial chain, or the quadruped (12 servos; "sim" gives
            ``armlab.hardware.families.dynamixel1.quadruped.QuadrupedSimBackend``, its legs carrying
            the body).
        port, baud: serial port and bit rate (for "serial" only).
        **kw: passed to the backend's constructor (e.g. ``q0``, ``specs``, ``dt`` for "sim").

    Raises:
        ValueError: unknown kind or options that do not fit it.
        armlab.control.backend.BackendError: the serial port or its servos cannot be opened.
    """
    if kind == "sim":
        if port is not None or baud is not None:
            raise ValueError("the sim backend takes no port or baud (those are for serial)")
        if isinstance(model, Quadruped):
            from armlab.hardware.families.dynamixel1.quadruped import QuadrupedSimBackend

            return QuadrupedSimBackend(model, **kw)
        from armlab.hardware.backends.joint_map import default_joint_map, default_servo
        from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
        from armlab.hardware.family_parts import has, load
        from armlab.hardware.servos.registry import family_of_model

        fam = family_of_model(default_servo(model.name))  # the servos the arm ships with
        if has(fam, "sim_backend") and "specs" not in kw:  # their family's simulation
            jmap = default_joint_map(model)
            kw.setdefault("gripper", jmap.gripper)  # its own servo
            return load(fam, "sim_backend")(model, spec=jmap.spec, **kw)
        return SimBackend(model, **kw)
    if kind == "serial":
        if port is None:
            raise ValueError("the serial backend needs a port (e.g. /dev/ttyUSB0)")
        from armlab.hardware.family_parts import open_servo_backend  # pyserial only when asked

        if baud is not None:
            kw["baud"] = baud
        return open_servo_backend(model, port, **kw)  # protocol 1.0 or 2.0, by the map
    raise ValueError(f"unknown backend {kind!r}; choose one of {', '.join(KINDS)}")


def has_firmware_sim(model: SerialChain) -> bool:
    """Whether the servos an arm ships with have their family's own firmware simulation
    (the OpenManipulator-X's XM430-W350, the SO-101's Feetech STS3215), which
    ``make_backend("sim", model)`` runs, one plant per arm; False: the arm is simulated with
    protocol-1.0 RX-24F servos, as the thesis arm (what a classroom's batched plant models)."""
    from armlab.hardware.backends.joint_map import default_servo
    from armlab.hardware.family_parts import has
    from armlab.hardware.servos.registry import family_of_model

    return has(family_of_model(default_servo(model.name)), "sim_backend")


def loop_over(backend: Backend, model: SerialChain, params: Params, **loop_kw: Any
              ) -> ControlLoop:
    """The compliance :class:`~armlab.control.loop.ControlLoop` of ``model`` over ``backend``
    (``loop_kw``: ``realtime``, ``history_s``, ``clock``...), not started; ``backend`` is
    closed when the loop cannot be made (bad parameters), and the error goes on."""
    loop_kw.setdefault("hold_off", getattr(backend, "uncalibrated", None))
    try:
        return ControlLoop(model, backend, params, controller="compliance", **loop_kw)
    except BaseException:
        backend.close()
        raise
