"""One client floods slider updates while another watches (issue 12, fair share).

Figures:

- ``flood_watcher_pose_hz``: arm pose frames per second the watching page gets
  while the other page sends in-range "Push force" updates as fast as it can.
- ``flood_loop_realtime_ratio``: loop time / wall time over the flood (1.0: real time).
- ``flood_stderr_bytes``: bytes the server wrote to stderr during the flood.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time

from armlab.app.server import Lab, ServeOptions
from armlab.app.testing.wsclient import HeadlessClient

ARM_PREFIX = "/compliance/arm/"
SLIDER = "Push force (N)"


def run(quick: bool) -> dict[str, float]:
    """The flood figures (see the module docstring)."""
    seconds = 3.0 if quick else 10.0
    saved = os.dup(2)
    with tempfile.TemporaryFile() as err:
        lab = Lab(ServeOptions(http_port=0))
        try:
            url = lab.url.replace("http://", "ws://")
            poses: list[float] = []
            watching = threading.Event()

            def on_message(m: dict, now: float) -> None:
                if watching.is_set() and m.get("type") == "SetOrientationMessage" \
                        and str(m.get("name", "")).startswith(ARM_PREFIX):
                    poses.append(now)

            with HeadlessClient(url, on_message=on_message).connect(), \
                    HeadlessClient(url).connect() as flooder:
                flooder.wait_for(lambda: any(e.label == SLIDER for e in flooder.gui.values()),
                                 timeout=30, what="the slider")
                uuid = flooder.find(SLIDER).uuid
                os.dup2(err.fileno(), 2)
                watching.set()
                t_loop0, t0 = lab.lesson.rig.loop.status.t, time.monotonic()
                k = 0
                while time.monotonic() - t0 < seconds:
                    flooder.send({"type": "GuiUpdateMessage", "uuid": uuid,
                                  "updates": {"value": 1.0 + (k % 50) * 0.1}})
                    k += 1
                wall = time.monotonic() - t0
                t_loop = lab.lesson.rig.loop.status.t - t_loop0
                watching.clear()
                os.dup2(saved, 2)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            lab.close()
        err.seek(0, os.SEEK_END)
        stderr_bytes = err.tell()
    return {
        "flood_watcher_pose_hz": len(poses) / wall,
        "flood_loop_realtime_ratio": t_loop / wall,
        "flood_stderr_bytes": float(stderr_bytes),
    }
