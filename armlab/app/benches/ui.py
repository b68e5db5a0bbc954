"""UI bench: what the lab sends to each page, how fast and how late, and the loop's jitter.

The lab runs in this process at its defaults (simulated arm, compliance lesson)
with the thesis line played over and over, so the arm and the charts keep
moving. Fake browsers (:class:`armlab.app.testing.wsclient.HeadlessClient`, the page's own
websocket protocol) run in a *separate* process, as real browsers would, so
their decoding does not load the server's interpreter.

Figures:

- ``ui_bytes_per_client_per_s``: websocket bytes one page receives per second
  while the line runs (target <= 150 kB/s); ``ui_bytes_per_client_per_s_idle``
  with the arm holding still.
- ``ui_pose_hz``: scene frames per second a page receives (each carries the
  arm's pose when it changed, and the probe; target 30); ``ui_arm_moved_hz``:
  frames in which an arm joint actually turned (lower: the arm rests between
  plays); ``ui_plot_hz``: frames carrying new data of the joint-angle chart
  (target >= 10).
- ``ui_latency_p95_ms``: state to page, p95: from the moment the control loop
  recorded the newest sample to the moment a page has the frame built from it
  (a hidden probe node in each frame carries the sample's CLOCK_MONOTONIC time,
  read by the client process on the same clock).
- ``ui_drag_hold_ms_p50`` / ``ui_drag_let_go_ms_p50``: from a page sending a drag's
  "start" ("end") on the hand to the lesson holding the arm with its spring (letting it
  go), median over the drags, the arm at rest: viser's dispatch and the lesson's own
  thread for drags (:mod:`armlab.app.page.in_order`). This page runs in the bench's own
  process: it only sends.
- ``ui_loop_jitter_p99_ms_0_clients`` / ``_10_clients``: the control loop's
  lateness of period starts, p99 over its last 1000 periods, with no page and
  with 10 pages connected (target <= 1 ms, unchanged by clients).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

PROBE = "/bench_probe"
#: a page's own probe (client-scoped): one per frame of its private lesson
OWN_PROBE = "/bench_probe_mine"
#: s the client process waits for every page to draw its own arm (``--my-arm``)
OWN_ARM_TIMEOUT_S = 240.0
ROOT = Path(__file__).resolve().parents[3]  # the checkout: armlab/app/benches/ui.py


# ---------------------------------------------------------------- client process


def client_main(argv: list[str] | None = None) -> int:
    """Entry point of the client process: connect N pages, listen, print JSON stats."""
    from armlab.app.testing.wsclient import HeadlessClient, SharedLoop

    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--clients", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--settle", type=float, default=1.0)
    ap.add_argument("--arm-prefix", default="/compliance/arm/")
    ap.add_argument("--my-arm", action="store_true",
                    help="each page chooses My arm (a classroom lab) and counts its own "
                         "arm's frames")
    args = ap.parse_args(argv)

    lock = threading.Lock()
    measuring = threading.Event()
    latencies: list[float] = []
    frames: dict[int, set[float]] = defaultdict(set)
    pose_frames: dict[int, set[float]] = defaultdict(set)
    plot_frames: dict[int, set[float]] = defaultdict(set)
    own_frames: dict[int, set[float]] = defaultdict(set)  # frames of a page's own lesson
    own_moved: dict[int, set[float]] = defaultdict(set)  # ... in which its own arm turned
    own_seen: set[int] = set()  # pages that have drawn their own arm at least once
    angle_uuid: dict[str, str] = {}

    def listener(i: int):  # noqa: ANN202
        def on_message(m: dict, now: float) -> None:
            if m.get("owner") and m.get("type") == "SetOrientationMessage" and str(
                    m.get("name", "")).startswith(args.arm_prefix):
                own_seen.add(i)
            if not measuring.is_set():
                if m.get("type") == "GuiUplotMessage" and str(
                        (m.get("props") or {}).get("title", "")).startswith("Joint angle"):
                    angle_uuid.setdefault("uuid", m["uuid"])
                return
            kind = m.get("type")
            if kind == "SetPositionMessage" and m.get("name") == OWN_PROBE:
                own_frames[i].add(now)
            elif kind == "SetPositionMessage" and m.get("name") == PROBE:
                with lock:
                    latencies.append(time.monotonic() - float(m["position"][0]))
                frames[i].add(now)
            elif kind == "SetOrientationMessage" and str(m.get("name", "")).startswith(
                    args.arm_prefix):
                (own_moved if m.get("owner") else pose_frames)[i].add(now)
            elif kind == "GuiUpdateMessage" and "data" in m.get("updates", {}) \
                    and m.get("uuid") == angle_uuid.get("uuid"):
                plot_frames[i].add(now)
        return on_message

    pages = SharedLoop()  # one thread for all: as cheap a reader as this process can be
    cpu0, wall0 = os.times(), time.monotonic()
    clients = [HeadlessClient(args.url, on_message=listener(i), loop=pages.loop).connect()
               for i in range(args.clients)]
    if args.my_arm:
        for c in clients:
            c.wait_for(lambda c=c: any(e.label == "View" for e in c.gui.values()), 60.0,  # type: ignore[misc]  # mypy cannot infer a lambda with default arguments
                       "the View switch")
            c.set_value("View", "My arm")
        # every page has its own arm on screen before anything is counted (a busy server
        # builds 30 private lessons one after the other)
        deadline = time.monotonic() + OWN_ARM_TIMEOUT_S
        while len(own_seen) < args.clients:
            if time.monotonic() > deadline:
                raise SystemExit(f"only {len(own_seen)} of {args.clients} pages drew their own "
                                 f"arm within {OWN_ARM_TIMEOUT_S:g} s")
            time.sleep(0.2)
    time.sleep(args.settle)
    b0 = [c.bytes_received for c in clients]
    measuring.set()
    t0 = time.monotonic()
    time.sleep(args.seconds)
    dt = time.monotonic() - t0
    measuring.clear()
    b1 = [c.bytes_received for c in clients]
    # a page whose connection ended before the count did (the server or the network
    # closed it): its rates are 0, and this says why
    dropped = [(i, repr(c.error)) for i, c in enumerate(clients) if c.closed]
    for c in clients:
        c.close()
    pages.close()
    cpu1, wall1 = os.times(), time.monotonic()
    lat = np.array(latencies) * 1e3 if latencies else np.array([np.nan])
    own = [len(own_frames[i]) for i in range(args.clients)]  # each page's own frames
    out = {
        "bytes_per_client_per_s": float(np.mean([(b - a) / dt for a, b in zip(b0, b1,
                                                                               strict=True)])),
        "pose_hz": float(np.mean([len(frames[i]) / dt for i in range(args.clients)])),
        "arm_pose_hz": float(np.mean([len(pose_frames[i]) / dt
                                      for i in range(args.clients)])),
        "plot_hz": float(np.mean([len(plot_frames[i]) / dt for i in range(args.clients)])),
        "own_pose_hz_min": float(min(own) / dt),
        "own_pose_hz_median": float(np.median(own) / dt),
        "own_arm_moved_hz_min": float(min(len(own_moved[i]) / dt
                                          for i in range(args.clients))),
        "bytes_per_client_per_s_max": float(max((b - a) / dt for a, b in zip(b0, b1,
                                                                              strict=True))),
        "latency_p50_ms": float(np.percentile(lat, 50)),
        "latency_p95_ms": float(np.percentile(lat, 95)),
        "samples": len(latencies),
        # this process's CPU per wall second: near 1 (a core), the fake pages, not the
        # server, may be what limits the rates measured
        "client_cpu_share": float((cpu1.user + cpu1.system - cpu0.user - cpu0.system)
                                  / (wall1 - wall0)),
    }
    out["pages_dropped"] = len(dropped)
    if dropped:
        print("pages whose connection ended before the count did:", dropped,
              file=sys.stderr, flush=True)
    if args.my_arm:  # which pages, if any, fell behind (the figure is the lowest)
        print("own frames per page:", sorted(own), file=sys.stderr, flush=True)
    print(json.dumps(out), flush=True)
    return 0


def _clients(url: str, n: int, seconds: float, settle: float = 1.5, *,
             my_arm: bool = False, arm_prefix: str | None = None) -> dict[str, float]:
    res = subprocess.run(
        [sys.executable, "-m", "armlab.app.benches.ui", "--url", url, "--clients", str(n),
         "--seconds", str(seconds), "--settle", str(settle),
         *(["--my-arm"] if my_arm else []),
         *(["--arm-prefix", arm_prefix] if arm_prefix else [])],
        cwd=ROOT, capture_output=True, text=True,
        timeout=seconds + settle + 120 + (OWN_ARM_TIMEOUT_S if my_arm else 0.0))
    if res.returncode != 0:
        raise RuntimeError(f"bench clients failed: {res.stderr.strip()[-500:]}")
    if res.stderr.strip():
        print(res.stderr.strip()[-2000:], file=sys.stderr, flush=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------- server side


class _Instrumented:
    """The lab plus the bench's probe: sample times and a probe node in every frame."""

    def __init__(self, *, classroom: bool = False) -> None:
        from armlab.app.lab.server import Lab, ServeOptions

        self.lab = Lab(ServeOptions(http_port=0, classroom=classroom))
        lesson: Any = self.lab.lesson  # the arm lesson (its rig, publisher and drag)
        self.lesson = lesson
        loop = lesson.rig.loop
        self.loop = loop
        self._stamp = time.monotonic()
        recorder = loop.recorder
        append = recorder.append

        def timed_append(*args: object, **kwargs: object) -> None:  # any signature
            append(*args, **kwargs)
            self._stamp = time.monotonic()

        recorder.append = timed_append  # the loop looks the method up each period
        self.probe = self.lab.server.scene.add_frame(PROBE, show_axes=False, visible=False)
        self._seq = 0

        def hook() -> None:
            self._seq += 1
            self.probe.position = (self._stamp, float(self._seq), 0.0)

        lesson.publisher.add_frame_hook(hook)
        self._stop = threading.Event()
        self._runner: threading.Thread | None = None

    @property
    def ws_url(self) -> str:
        return self.lab.url.replace("http://", "ws://")

    def keep_running_the_line(self) -> None:
        """Play the thesis line again whenever the last play ended."""
        def run() -> None:
            while not self._stop.wait(0.2):
                st = self.loop.status
                if st.trajectory is None and st.active:
                    self.lesson.run_line()
                    time.sleep(0.5)
        self._runner = threading.Thread(target=run, daemon=True)
        self._runner.start()

    def hold(self) -> None:
        self._stop.set()
        if self._runner is not None:
            self._runner.join(2.0)
        self._stop = threading.Event()

    def drag_ms(self, n: int) -> tuple[list[float], list[float]]:
        """ms from a page's drag "start" to the lesson's spring holding the arm, and from
        its "end" to the spring let go, for each of ``n`` drags on the hand where it is."""
        from armlab.app.testing.wsclient import HeadlessClient

        lesson = self.lesson
        grab = lesson.rig.scene.hand.name
        model = lesson.rig.model
        recorded = self.loop.recorder.snapshot(0.1)["q"]
        until = time.monotonic() + 60.0  # (a loop started on a busy machine: its first rows)
        while not len(recorded) and time.monotonic() < until:
            time.sleep(0.02)
            recorded = self.loop.recorder.snapshot(0.1)["q"]
        if not len(recorded):
            raise RuntimeError("bench ui: the lab's loop recorded no row in 60 s")
        hand = model.fk(recorded[-1])[:3, 3]
        where = tuple(float(x) for x in (model.base_pose @ np.append(hand, 1.0))[:3])
        hold: list[float] = []
        let_go: list[float] = []
        with HeadlessClient(self.ws_url).connect() as page:
            for _ in range(n):
                for phase, done, out in (("start", lambda: lesson._drag_anchor is not None,
                                          hold),
                                         ("end", lambda: lesson._drag_anchor is None, let_go)):
                    t0 = time.monotonic()
                    page.drag(grab, phase, start=where, end=where)  # type: ignore[arg-type]  # (3,) m: the target's position
                    deadline = t0 + 30.0
                    while not done():
                        if time.monotonic() > deadline:
                            raise RuntimeError(f"a drag's {phase!r} was not handled in 30 s")
                        time.sleep(0.0002)
                    out.append((time.monotonic() - t0) * 1e3)
        return hold, let_go

    def jitter_p99(self, seconds: float) -> float:
        time.sleep(seconds)
        v = self.loop.status.jitter_p99_ms
        return float("nan") if v is None else float(v)

    def check(self) -> None:
        """Raise if the loop stopped during the bench: its figures would describe an idle
        arm, not the lab at work."""
        st = self.loop.status
        if st.fault is not None or not st.active:
            raise RuntimeError(f"the control loop stopped during the UI bench: {st.fault}")

    def close(self) -> None:
        self.hold()
        self.lab.close()


def run(quick: bool) -> dict[str, float]:
    """The UI figures (see the module docstring)."""
    measure = 4.0 if quick else 12.0
    window = 6.0 if quick else 17.0  # the loop keeps 1000 periods = 16 s of lateness
    lab = _Instrumented()
    try:
        jitter0 = lab.jitter_p99(window)
        idle = _clients(lab.ws_url, 1, measure)
        hold, let_go = lab.drag_ms(10 if quick else 40)
        lab.keep_running_the_line()
        one = _clients(lab.ws_url, 1, measure)
        ten: dict[str, float] = {}
        ten_thread = threading.Thread(target=lambda: ten.update(
            _clients(lab.ws_url, 10, window + 2.0, settle=1.0)))
        ten_thread.start()
        jitter10 = lab.jitter_p99(window + 1.5)
        ten_thread.join()
        lab.check()
    finally:
        lab.close()
    return {
        "ui_bytes_per_client_per_s": one["bytes_per_client_per_s"],
        "ui_bytes_per_client_per_s_idle": idle["bytes_per_client_per_s"],
        "ui_bytes_per_client_per_s_10_clients": ten["bytes_per_client_per_s"],
        "ui_latency_p95_ms": one["latency_p95_ms"],
        "ui_latency_p50_ms": one["latency_p50_ms"],
        "ui_latency_p95_ms_10_clients": ten["latency_p95_ms"],
        "ui_drag_hold_ms_p50": float(np.median(hold)),
        "ui_drag_let_go_ms_p50": float(np.median(let_go)),
        "ui_pose_hz": one["pose_hz"],
        "ui_arm_moved_hz": one["arm_pose_hz"],
        "ui_plot_hz": one["plot_hz"],
        "ui_pose_hz_10_clients": ten["pose_hz"],
        "ui_plot_hz_10_clients": ten["plot_hz"],
        "ui_loop_jitter_p99_ms_0_clients": jitter0,
        "ui_loop_jitter_p99_ms_10_clients": jitter10,
    }


if __name__ == "__main__":
    sys.exit(client_main())
