"""What a run file says besides its record: which law ran, on which backend, and every
gain change with its loop time (the file's ``extra``, docs/runs.md)."""

from __future__ import annotations

import hashlib
import math
import threading
from collections import deque
from collections.abc import Mapping
from pathlib import Path
from typing import Any

#: The most characters of a student's law file a run file holds (a law is a page or two).
MAX_LAW_SOURCE_CHARS = 64_000
#: Gain changes remembered (the newest), and parameters shown per change.
MAX_GAIN_CHANGES = 1000


def law_json(law: object | None, params: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Which law ran: ``{"by": "lab", "law": <params' law>}``, or the student's file
    (``armlab serve --exercise``, an :class:`armlab.app.arm.student_law.StudentLaw`):
    ``{"by": "student", "file": name, "sha256": hex, "source": its text, "exercise": ...}``
    as the file is now (read here: the law the loop runs is the file's last save)."""
    if law is None:
        out: dict[str, Any] = {"by": "lab"}
        if params is not None and "law" in params:
            out["law"] = params["law"]
        return out
    path = Path(str(getattr(law, "path", "")))
    out = {"by": "student", "file": path.name}
    exercise = getattr(law, "exercise", None)
    name = getattr(exercise, "name", None)
    if isinstance(name, str):
        out["exercise"] = name
    try:
        data = path.read_bytes()
    except OSError as exc:
        out["error"] = f"the file could not be read ({exc.strerror or exc})"
        return out
    out["sha256"] = hashlib.sha256(data).hexdigest()
    text = data.decode("utf-8", errors="replace")
    out["source"] = text[:MAX_LAW_SOURCE_CHARS]
    if len(text) > MAX_LAW_SOURCE_CHARS:
        out["source_cut_at_chars"] = MAX_LAW_SOURCE_CHARS
    return out


def backend_json(kind: str, *, port: str | None = None,
                 backend: object | None = None) -> dict[str, Any]:
    """Which backend the run ran on: ``{"kind": "simulated", "servos": [...]}`` or
    ``{"kind": "serial", "port": ..., "servos": model, "servo_ids": [...]}``, with the
    servos' models as far as the backend tells them."""
    if kind == "sim":
        models = sorted({str(getattr(s, "name", s)) for s in getattr(backend, "specs", ())})
        return {"kind": "simulated", **({"servos": ", ".join(models)} if models else {})}
    out: dict[str, Any] = {"kind": kind}
    if port:
        out["port"] = port
    joint_map = getattr(backend, "map", None)
    if joint_map is not None:
        servo = getattr(joint_map, "servo", None)
        if servo is not None:
            out["servos"] = str(servo)
        ids = [getattr(j, "servo_id", None) for j in getattr(joint_map, "joints", ())]
        out["servo_ids"] = [i for i in ids if isinstance(i, int)]
    bus = getattr(backend, "bus", None)
    baud = getattr(bus, "baud", None)
    if isinstance(baud, int | float) and math.isfinite(baud):
        out["baud"] = baud
    return out


class GainLog:
    """The gains' changes, each with the loop time it was seen at (the newest
    :data:`MAX_GAIN_CHANGES`)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()  # seen from the publisher and from a run's start
        self._last: dict[str, Any] | None = None
        self._changes: deque[dict[str, Any]] = deque(maxlen=MAX_GAIN_CHANGES)

    def see(self, params: Mapping[str, Any], *, t: float) -> None:
        """The parameters in force at loop time ``t`` s: a change from the last seen is
        kept as ``{"t": s, name: new value, ...}`` (only what changed)."""
        now = dict(params)
        with self._lock:
            last, self._last = self._last, now
            if last is None:
                return
            changed = {k: v for k, v in now.items() if last.get(k) != v}
            if changed:
                self._changes.append({"t": float(t), **changed})

    def between(self, t0: float, t1: float = math.inf) -> list[dict[str, Any]]:
        """The changes seen from ``t0`` to ``t1`` s, oldest first."""
        with self._lock:
            return [c for c in self._changes if t0 <= c["t"] <= t1]
