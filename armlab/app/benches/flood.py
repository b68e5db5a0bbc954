"""One client floods slider updates while another watches (issue 12, fair share).

Figures:

- ``flood_watcher_pose_hz``: arm pose frames per second the watching page gets
  while the other page sends in-range "Push force" updates as fast as it can.
- ``flood_loop_realtime_ratio``: loop time / wall time over the flood (1.0: real time).
- ``flood_stderr_bytes``: bytes the server wrote to stderr during the flood.
- ``calm_watcher_pose_hz``, ``calm_loop_realtime_ratio``: the same two with nobody
  sending, in blocks taking turns with the flood's (the reference its figures are judged
  against).
"""

from __future__ import annotations

import os
import tempfile
import threading
import time

from armlab.app.lab.server import Lab, ServeOptions
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
                loop = lab.lesson.rig.loop  # type: ignore[union-attr]  # the lab's arm lesson, open
                # calm and flooded blocks in turn, so a busy machine's load falls on both
                rounds = 3 if quick else 5
                wall = {"calm": 0.0, "flood": 0.0}
                advanced = dict(wall)
                count = dict(wall)
                k = 0
                watching.set()
                for _ in range(rounds):
                    for part in ("calm", "flood"):
                        if part == "flood":
                            os.dup2(err.fileno(), 2)
                        n0, t_loop0, t0 = len(poses), loop.status.t, time.monotonic()
                        while time.monotonic() - t0 < seconds / rounds:
                            if part == "calm":
                                time.sleep(0.05)
                                continue
                            flooder.send({"type": "GuiUpdateMessage", "uuid": uuid,
                                          "updates": {"value": 1.0 + (k % 50) * 0.1}})
                            k += 1
                        wall[part] += time.monotonic() - t0
                        advanced[part] += loop.status.t - t_loop0
                        count[part] += len(poses) - n0
                        os.dup2(saved, 2)
                watching.clear()
                os.dup2(saved, 2)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            lab.close()
        err.seek(0, os.SEEK_END)
        stderr_bytes = err.tell()
    return {
        "flood_watcher_pose_hz": count["flood"] / wall["flood"],
        "flood_loop_realtime_ratio": advanced["flood"] / wall["flood"],
        "flood_stderr_bytes": float(stderr_bytes),
        "calm_watcher_pose_hz": count["calm"] / wall["calm"],
        "calm_loop_realtime_ratio": advanced["calm"] / wall["calm"],
    }
