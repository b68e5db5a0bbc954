"""A page's drag events handled in the order the page sent them (armlab.app.page.in_order),
on a real viser server, sent by a real websocket client."""

from __future__ import annotations

import threading
import time

import pytest
import viser
from _helpers import client_of, wait_for

from armlab.app.page.in_order import InOrder


@pytest.fixture
def server():
    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


def _send_drag(client, name: str, phases: list[str]) -> None:
    for i, phase in enumerate(phases):
        client.drag(name, phase, start=(0.0, 0.0, 0.0), end=(float(i), 0.0, 0.0))


def test_a_slow_start_is_not_overtaken_by_the_drags_update_and_end(server):
    """The start's handler takes a while (a private arm's command waits for its worker):
    the update and end sent after it are still handled after it, in order."""
    lane = InOrder("test-drags")
    seen: list[tuple[str, float]] = []
    node = server.scene.add_icosphere("/grab", radius=0.03)

    def dragged(event: viser.SceneNodeDragEvent) -> None:
        if event.phase == "start":
            time.sleep(0.3)
        seen.append((event.phase, float(event.end_position[0])))

    node.on_drag(lane(dragged))
    phases = ["start", "update", "update", "update", "end"]
    with client_of(server) as client:
        _send_drag(client, "/grab", phases)
        wait_for(lambda: len(seen) == len(phases), 30.0, "every drag event handled")
    assert seen == [(p, float(i)) for i, p in enumerate(phases)]
    lane.close()


def test_the_handlers_run_one_at_a_time_on_the_lanes_own_thread(server):
    lane = InOrder("test-one-thread")
    threads: set[str] = set()
    handled: list[str] = []
    running: list[int] = []
    overlapped: list[str] = []
    node = server.scene.add_icosphere("/grab", radius=0.03)

    def dragged(event: viser.SceneNodeDragEvent) -> None:
        running.append(1)
        if len(running) > 1:
            overlapped.append(event.phase)
        threads.add(threading.current_thread().name)
        time.sleep(0.01)
        running.pop()
        handled.append(event.phase)

    node.on_drag(lane(dragged))
    with client_of(server) as client:
        for _ in range(10):
            _send_drag(client, "/grab", ["start", "update", "end"])
        wait_for(lambda: len(handled) == 30, 30.0, "thirty drag events handled")
    assert handled == ["start", "update", "end"] * 10
    assert not overlapped
    assert len(threads) == 1 and next(iter(threads)).startswith("test-one-thread")
    lane.close()


def test_a_failing_handler_does_not_stop_the_lane_and_a_closed_lane_drops_events(server, capfd):
    lane = InOrder("test-errors")
    handled: list[str] = []
    node = server.scene.add_icosphere("/grab", radius=0.03)

    def dragged(event: viser.SceneNodeDragEvent) -> None:
        if event.phase == "start":
            raise RuntimeError("a handler's bug")
        handled.append(event.phase)

    node.on_drag(lane(dragged))
    with client_of(server) as client:
        _send_drag(client, "/grab", ["start", "update", "end"])
        wait_for(lambda: handled == ["update", "end"], 30.0, "the events after the error")
        wait_for(lambda: "a handler's bug" in capfd.readouterr().err, 30.0,
                 "the error printed")
        lane.close()
        _send_drag(client, "/grab", ["start", "update", "end"])
        marker = server.scene.add_icosphere("/marker", radius=0.01)  # sent after the drags
        got: list[str] = []
        marker.on_drag(lambda event: got.append(event.phase))
        client.drag("/marker", "start", start=(0.0, 0.0, 0.0), end=(0.0, 0.0, 0.0))
        wait_for(lambda: got == ["start"], 30.0, "an event sent after the closed lane's")
    assert handled == ["update", "end"]
