"""Helpers shared by the tests that serve the lab or a lesson (fixtures: conftest.py).

- :func:`wait_for`: poll a condition the server side reaches in its own time.
- :func:`served_lesson`: a lesson built on a real viser server on a free port.
- :func:`client_of`: a headless client
  (:class:`armlab.app.testing.wsclient.HeadlessClient`, what the
  page sends on the wire) connected to a server, once the server counts it as a client.
- :func:`project`: points in a camera's view, as the framing tests judge them.
- The Chromium the browser tests drive, its flags, the console messages that
  headless software rendering prints without a fault, and :func:`chart_x_ranges`.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import viser

from armlab.app.lessons import LessonContext
from armlab.app.testing.wsclient import HeadlessClient

CHROMIUM = Path(os.environ.get("ARMLAB_CHROMIUM", "/usr/bin/chromium"))
#: WebGL in SwiftShader (software: no GPU here); the page's tiles rasterised by the CPU, not
#: also through SwiftShader, as Debian's launcher asks (/etc/chromium.d/default-flags).
CHROMIUM_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--disable-gpu-rasterization",
                 "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
#: ms a page waits for an element to be actionable (visible, enabled and standing still
#: for two animation frames) before a click fails. Playwright's 30 s ran out once on a
#: loaded machine, where a software-rendered 3D page draws a frame in seconds.
ACTION_TIMEOUT_MS = 120_000
#: Console messages that are expected in headless software rendering, not faults.
EXPECTED_CONSOLE = ("software webgl", "three.clock", "gpu stall",
                    "automatic fallback to software")


#: viser's page logs this when a GUI update arrives for an element already removed: a
#: lesson's last frame and its removal reach the page in one rendered frame (it applies
#: updates after the removals of a frame, and software WebGL on a loaded machine takes
#: seconds a frame). The server sends them in order; nothing is shown wrongly.
STALE_UPDATE = "tried to update non-existent component"


def after_switch(errors: list[str]) -> list[str]:
    """Console errors after a lesson switch, without :data:`STALE_UPDATE` (see there)."""
    return [e for e in errors if STALE_UPDATE not in e.lower()]


def expected_console(text: str) -> bool:
    """True for a browser console message listed in :data:`EXPECTED_CONSOLE`."""
    return any(e in text.lower() for e in EXPECTED_CONSOLE)


def chart_x_ranges(page: Any) -> list[tuple[float | None, float | None, float, float]]:
    """(x min shown, x max shown, first x, last x of the data) of every chart on the page.

    From viser's uPlot test registry (``window.__viserTestpoints.uplots``); a shown bound
    is None while the chart has no x range.
    """
    return [tuple(r) for r in page.evaluate(
        """() => Object.values((window.__viserTestpoints || {}).uplots || {})
            .filter(({chart}) => chart.root.isConnected)
            .map(({chart}) => [chart.scales.x.min, chart.scales.x.max,
                               chart.data[0][0], chart.data[0][chart.data[0].length - 1]])""")]


#: ms a browser screenshot may take: software WebGL on a loaded 2-core machine draws a
#: frame in seconds, and a screenshot waits for one (Playwright's default is 30 s)
SCREENSHOT_TIMEOUT_MS = 120_000


def view_png(page: Any, box: dict[str, float]) -> bytes:
    """PNG of the page area ``box`` (x, y, width, height in CSS px), as the page shows it.

    Clips the page rather than screenshotting the canvas element, which first waits for
    the element to be "stable" across animation frames (slow under load)."""
    return page.screenshot(clip=box, timeout=SCREENSHOT_TIMEOUT_MS, animations="disabled")


def wait_for(predicate: Callable[[], object], timeout: float = 30.0,
             what: str | Callable[[], str] = "condition", *, every: float = 0.02) -> None:
    """Poll ``predicate`` every ``every`` s until true; AssertionError after ``timeout`` s
    naming ``what`` (a callable is asked then, to say what was seen)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            said = what() if callable(what) else what
            raise AssertionError(f"timed out after {timeout} s waiting for {said}")
        time.sleep(every)


@contextmanager
def served_lesson(build: Callable[[viser.ViserServer, LessonContext], Any],
                  ctx: LessonContext) -> Iterator[Any]:
    """``build(server, ctx)`` on a viser server on a free port; closed, then stopped."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        handle = build(server, ctx)
        try:
            yield handle
        finally:
            handle.close()
    finally:
        server.stop()


@contextmanager
def client_of(server: viser.ViserServer, *, timeout: float = 30.0,
              token: str | None = None) -> Iterator[HeadlessClient]:
    """A headless client of ``server`` (presenting ``token`` for a gated lab,
    armlab.app.classroom.gate),
    returned once the server has registered it."""
    before = set(server.get_clients())
    query = f"/?token={token}" if token else ""
    with HeadlessClient(f"ws://127.0.0.1:{server.get_port()}{query}").connect(timeout) as client:
        client.wait_for(lambda: bool(set(server.get_clients()) - before), timeout,
                        "the server to register the client")
        yield client


def settled(server: viser.ViserServer | viser.ClientHandle, page: HeadlessClient,
            timeout: float = 60.0) -> None:
    """Return once ``page`` holds every message ``server`` had queued before this call.

    viser keeps order within a stream: a marker added now arrives after all of them (then
    it is removed again). A server's own messages (the shared controls) are one stream, a
    page's own (its camera, its own controls) another: pass the page's ClientHandle for
    those."""
    marker = f"settled {time.monotonic_ns()}"
    handle = server.gui.add_markdown(marker)
    try:
        page.wait_for(lambda: any(e.props.get("_markdown") == marker
                                  for e in list(page.gui.values())),
                      timeout, "the page to receive the controls made before it")
    finally:
        handle.remove()


def project(points: np.ndarray, position, look_at, up, fov: float, aspect: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, depth) of ``points`` (k, 3) in a pinhole view from ``position`` towards
    ``look_at`` (``up`` upwards, vertical field of view ``fov`` rad, width/height
    ``aspect``): x, y in units of the view's half-width and half-height (±1 at its
    edges), depth along the view direction."""
    position, look_at, up = (np.asarray(v, dtype=float) for v in (position, look_at, up))
    forward = (look_at - position) / np.linalg.norm(look_at - position)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    upward = np.cross(right, forward)
    rel = np.asarray(points, dtype=float) - position
    depth = rel @ forward
    t = math.tan(0.5 * fov)
    return rel @ right / (depth * t * aspect), rel @ upward / (depth * t), depth


def wait_look_settled(lab: Any, known: set[int]) -> None:
    """Wait until the page of ``lab`` that connected after ``known`` (client ids) has its
    look for good: armlab.app.page.look (a page drawing WebGL in software turns plain once it has
    named its renderer, which changes every pixel between two pictures) and armlab.app.page.theme
    (a page whose browser chose Projector gets its sizes once it has said so)."""
    wait_for(lambda: any(lab.looks.settled(cid) and lab.page_style.settled(cid)
                         for cid in lab.server.get_clients() if cid not in known),
             180.0, "the page's look to settle")


def new_page_client(lab: Any, known: set[int]) -> Any:
    """The one page (``viser.ClientHandle``) of ``lab`` that connected after ``known``
    (client ids), or None while there is not exactly one."""
    new = [c for cid, c in lab.server.get_clients().items() if cid not in known]
    return new[0] if len(new) == 1 else None


def my_arm_in(lab: Any, page: HeadlessClient, cid: int, lesson: str) -> Any:
    """Switch ``lab``'s class to ``lesson``, wait for ``page`` (client ``cid``) to follow
    it, put that page on "My arm" and return its own copy of the lesson (a new object of
    the shared lesson's type)."""
    lab.switch(lesson)
    page.wait_for(lambda: page.find("View").value == "Follow the teacher", 60.0,
                  "the page following the new lesson")
    page.set_value("View", "My arm")
    wait_for(lambda: lab.room.private_lesson(cid) is not None, 60.0,
             f"the page's own {lesson} lesson")
    mine = lab.room.private_lesson(cid)
    assert mine is not lab.lesson and type(mine) is type(lab.lesson)
    return mine


def hand_at_rest(lesson: Any, timeout: float = 120.0) -> np.ndarray:
    """The hand (3,) m of an arm lesson (``lesson.loop``, ``lesson.model``) once it moved
    less than 0.5 mm over 0.5 s of loop time (a gain just changed, or the arm just
    started or was caught limp, moves it)."""
    def hand() -> np.ndarray:
        snap = lesson.loop.recorder.snapshot(0.1)
        return (lesson.model.fk(snap["q"][-1])[:3, 3] if len(snap["t"])
                else np.full(3, np.nan))

    last = [hand(), lesson.loop.status.t]

    def resting() -> bool:
        if lesson.loop.status.t - last[1] < 0.5:
            return False
        now = hand()
        done = bool(np.linalg.norm(now - last[0]) < 5e-4)
        last[:] = [now, lesson.loop.status.t]
        return done

    wait_for(resting, timeout, "the hand at rest")
    return last[0]



def confirm_clear(lesson: Any, timeout: float = 60.0) -> None:
    """What a technician does on an uncalibrated arm (no calibration, or a drafted map),
    which the lab opens with its torque off: confirm the arm is clear (the page's
    "Torque on: the arm is clear", the loop's Reset), then wait until the loop holds the
    arm with its torque on. An arm held already is left alone."""
    from armlab.control.commands import Reset

    loop = lesson.loop
    wait_for(lambda: loop.status.held_off is not None or loop.status.active, timeout,
             "the loop holding the arm, or waiting for a person to confirm")
    if loop.status.held_off is not None:
        loop.post(Reset())
    # until the Reset is taken, a slider moved now is refused ("torque held off"): wait
    # for the arm held with its torque on, as the person sees it on the status line
    wait_for(lambda: loop.status.held_off is None and loop.status.active
             and loop.status.torque_on, timeout, "the arm held with its torque on")
