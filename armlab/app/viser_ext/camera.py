"""A page's camera, sent and recorded without viser's public setters' extra work.

relies on: ``CameraHandle._state`` (``position``, ``look_at``, ``update_timestamp``) and
viser._messages' ``SetCameraPositionMessage`` / ``SetCameraLookAtMessage``; seen in viser 1.1.1
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import viser

from armlab.app.viser_ext.clients import connected, queue
from armlab.app.viser_ext.messages import SetCameraLookAtMessage, SetCameraPositionMessage
from armlab.app.viser_ext.probe import assigned_in


def missing() -> list[str]:
    """What of the above this viser lacks."""
    out = [] if assigned_in(viser.CameraHandle, "_state") else ["CameraHandle._state"]
    from viser import _viser

    state = getattr(_viser, "_CameraHandleState", None)
    fields = getattr(state, "__dataclass_fields__", {})
    out += [f"_CameraHandleState.{f}" for f in ("position", "look_at", "update_timestamp")
            if f not in fields]
    return out


def send_view(client: viser.ClientHandle, position: Sequence[float] | np.ndarray,
              look_at: Sequence[float] | np.ndarray) -> None:
    """Queue the page's camera position and look-at point (3,) m, whatever viser last
    heard of them (the newer of two waiting camera messages replaces the older)."""
    queue(client, SetCameraPositionMessage(tuple(float(v) for v in position)))
    queue(client, SetCameraLookAtMessage(tuple(float(v) for v in look_at)))


def shift_view(client: viser.ClientHandle, offset: Sequence[float]) -> bool:
    """Move ``client``'s camera and the point it looks at by ``offset`` (3,) m, world, in
    viser's record of the page's camera, and send the two points (the orientation is
    kept, so viser's work of finding it again is skipped). False if the page has gone,
    has not reported its camera yet, or the result is not finite."""
    state = client.camera._state
    if not connected(client) or state.update_timestamp == 0.0:
        return False
    dx, dy, dz = (float(v) for v in offset)
    position = state.position + (dx, dy, dz)
    look_at = state.look_at + (dx, dy, dz)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(look_at))):
        return False
    state.position, state.look_at = position, look_at
    state.update_timestamp = time.time()
    send_view(client, position.tolist(), look_at.tolist())
    return True
