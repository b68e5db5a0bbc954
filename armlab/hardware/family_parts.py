"""Each servo family's backends and emulator (:mod:`armlab.hardware.families` holds the
rest of a family: codec, tables, firmware model).

A family's entry (its folder's ``FAMILY``) is registered when ``armlab.hardware`` is
imported, and names only its codec, tables and firmware model; its backends and emulator
stand on the bus and the emulated network, so they are named here, at the top of the
hardware layer, where nothing below imports this module. A backend or an emulator is
imported when first asked for (pyserial only when a serial arm is opened).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from armlab.control.backend import BackendError
from armlab.hardware.servos import registry
from armlab.hardware.servos.family import ServoFamily
from armlab.kinematics.model import Quadruped, SerialChain

if TYPE_CHECKING:
    from armlab.hardware.backends.joint_map import JointMap
    from armlab.hardware.backends.servo_bus import ServoBusBackend


@dataclass(frozen=True)
class Parts:
    """A family's heavy parts, each imported by a function when first asked for (None:
    the family has none yet).

    Attributes:
        real_backend: the backend on a serial port (a ``ServoBusBackend`` class).
        sim_backend: the simulated backend with this family's servos (None: the plain
            ``SimBackend``).
        emulator: the emulated network's factory ``(model, joint_map, *, baud, dt) ->
            network``.
    """

    real_backend: Callable[[], type[ServoBusBackend]] | None = None
    sim_backend: Callable[[], type] | None = None
    emulator: Callable[[], Callable[..., Any]] | None = None


def _dxl_backend() -> type[ServoBusBackend]:
    from armlab.hardware.families.dynamixel1.backend import DynamixelBackend
    return DynamixelBackend


def _dxl_emulator() -> Callable[..., Any]:
    from armlab.hardware.families.dynamixel1.emulator import network_for_map
    return network_for_map


def _x_backend() -> type[ServoBusBackend]:
    from armlab.hardware.families.xseries.backend import XSeriesBackend
    return XSeriesBackend


def _x_sim() -> type:
    from armlab.hardware.families.xseries.sim_backend import XSimBackend
    return XSimBackend


def _x_emulator() -> Callable[..., Any]:
    from armlab.hardware.families.xseries.emulator import x_network_for_map
    return x_network_for_map


def _sts_backend() -> type[ServoBusBackend]:
    from armlab.hardware.families.feetech.backend import StsBackend
    return StsBackend


def _sts_sim() -> type:
    from armlab.hardware.families.feetech.sim_backend import StsSimBackend
    return StsSimBackend


def _sts_emulator() -> Callable[..., Any]:
    from armlab.hardware.families.feetech.emulator import sts_network_for_map
    return sts_network_for_map


#: each family's parts, by its key
PARTS: dict[str, Parts] = {
    "dynamixel1": Parts(real_backend=_dxl_backend, emulator=_dxl_emulator),
    "xseries": Parts(real_backend=_x_backend, sim_backend=_x_sim, emulator=_x_emulator),
    "sts": Parts(real_backend=_sts_backend, sim_backend=_sts_sim, emulator=_sts_emulator),
}


def register(family: ServoFamily, parts: Parts) -> None:
    """Add a servo family the lab does not ship: the family to the registry
    (:func:`armlab.hardware.servos.registry.register`) and its parts here. Its folder holds the
    rest (``families/<family>/`` for the lab's own: codec, tables, firmware model,
    backends, emulator); nothing else changes.

    Raises:
        ValueError: the family's key, protocol, an alias or a model is another family's.
    """
    if family.key in PARTS:
        raise ValueError(f"a family {family.key!r} is registered already")
    registry.register(family)
    PARTS[family.key] = parts


def has(family: ServoFamily, part: str) -> bool:
    """Whether ``family`` has ``part`` ("real_backend", "sim_backend" or "emulator")."""
    return getattr(PARTS[family.key], part) is not None


def load(family: ServoFamily, part: str) -> Any:
    """``family``'s ``part``, imported now; ValueError naming the family when it has none."""
    loader = getattr(PARTS[family.key], part)
    if loader is None:
        raise ValueError(f"the {family.title} family has no {part.replace('_', ' ')}")
    return loader()


def open_servo_backend(model: SerialChain | Quadruped, port: str, *,
                       joint_map: JointMap | str | Path | None = None,
                       **kw: Any) -> ServoBusBackend:
    """The backend for ``model``'s servos on ``port``: the real backend of the servo family
    the joint map names (``DynamixelBackend`` on protocol 1.0, ``XSeriesBackend`` on the
    X-series, ``StsBackend`` on Feetech STS)."""
    from armlab.hardware.backends.joint_map import default_joint_map, load_joint_map
    from armlab.hardware.families.dynamixel1.backend import DynamixelBackend

    if isinstance(joint_map, str | Path):
        joint_map = load_joint_map(joint_map, model)
    jmap = joint_map or default_joint_map(model)
    try:
        backend = load(jmap.family, "real_backend")
    except ValueError as exc:
        raise BackendError(f"the {jmap.servo} cannot be driven on a serial port yet: {exc}"
                           ) from None
    if isinstance(model, Quadruped) and backend is not DynamixelBackend:
        raise BackendError(f"the {jmap.family.title} backend drives a serial arm, not the "
                           "quadruped")
    return backend(model, port, joint_map=jmap, **kw)
