"""Publishers making their frames on one shared thread (armlab.app.page.publisher.FrameThread):
every page gets its frames, a failing frame or a closed publisher leaves the others going, and
the turns are fair when the thread cannot keep up. Real viser server, headless pages."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager

import pytest
import viser

from armlab.app.classroom.private_page import Page
from armlab.app.page.publisher import FrameThread, Publisher
from tests._helpers import client_of, wait_for


@contextmanager
def pages(n: int) -> Iterator[list[Page]]:
    """``n`` headless pages of one real viser server, as :class:`Page` "servers"."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        with ExitStack() as stack:
            for _ in range(n):
                stack.enter_context(client_of(server))
            clients = server.get_clients()
            yield [Page(c) for _, c in sorted(clients.items())]
    finally:
        server.stop()


class Counter:
    """A lesson's frame functions: counts each frame and the thread that made it."""

    def __init__(self, page: Page, *, fail: bool = False, cost_s: float = 0.0) -> None:
        self.page = page
        self.poses = self.plots = 0
        self.threads: set[str] = set()
        self.fail = fail
        self.cost_s = cost_s
        self.node = page.scene.add_frame("/probe", show_axes=False)

    def pose(self) -> None:
        self.threads.add(threading.current_thread().name)
        self.poses += 1
        if self.fail:
            raise RuntimeError("a lesson's frame that fails")
        self.node.position = (float(self.poses), 0.0, 0.0)
        if self.cost_s:  # a frame that takes the frame thread's time; it sleeps, so that
            time.sleep(self.cost_s)  # the pages' sender is not starved of the GIL instead

    def plot(self, force: bool) -> None:
        self.plots += 1


@pytest.fixture
def frames() -> Iterator[FrameThread]:
    thread = FrameThread(name="test-frames")
    yield thread
    thread.close()


def publish(counter: Counter, frames: FrameThread, *, pose_hz: float = 30.0,
            plot_hz: float = 11.0) -> Publisher:
    publisher = Publisher(counter.page, pose=counter.pose, plots=counter.plot,  # type: ignore[arg-type]
                          pose_hz=pose_hz, plot_hz=plot_hz, frames=frames)
    publisher.start()
    return publisher


def test_pages_share_one_thread_and_each_gets_its_frames(frames: FrameThread) -> None:
    with pages(3) as three:
        counters = [Counter(p) for p in three]
        publishers = [publish(c, frames) for c in counters]
        wait_for(lambda: all(c.poses > 20 and c.plots > 5 for c in counters), 60.0,
                 lambda: f"frames of every page: {[(c.poses, c.plots) for c in counters]}")
        assert {name for c in counters for name in c.threads} == {"test-frames"}
        assert not any(p._thread.is_alive() for p in publishers)  # no thread of their own
        for publisher in publishers:
            publisher.close(settle_s=0.0)


@pytest.mark.slow
def test_a_failing_frame_or_a_closed_publisher_leaves_the_others_going(frames: FrameThread) -> None:
    with pages(3) as three:
        bad, gone, good = Counter(three[0], fail=True), Counter(three[1]), Counter(three[2])
        publishers = [publish(c, frames) for c in (bad, gone, good)]
        wait_for(lambda: gone.poses > 10 and bad.poses > 10, 60.0, "frames")
        publishers[1].close(settle_s=0.0)
        after_close = gone.poses
        seen = good.poses
        wait_for(lambda: good.poses > seen + 20, 60.0, "the good page's frames")
        assert gone.poses == after_close  # none once close returned
        assert publishers[0].stats.errors > 10 and publishers[2].stats.errors == 0
        for publisher in (publishers[0], publishers[2]):
            publisher.close(settle_s=0.0)


@pytest.mark.slow
def test_close_waits_for_the_frame_being_made(frames: FrameThread) -> None:
    with pages(1) as one:
        inside, release, made = threading.Event(), threading.Event(), threading.Event()
        counter = Counter(one[0])
        order: list[str] = []

        def slow_pose() -> None:
            inside.set()
            release.wait(30.0)
            order.append("frame made")
            made.set()

        def close() -> None:
            publisher.close(settle_s=0.0)
            order.append("close returned")

        publisher = Publisher(one[0], pose=slow_pose, plots=counter.plot,  # type: ignore[arg-type]
                              frames=frames)
        publisher.start()
        assert inside.wait(30.0)
        closer = threading.Thread(target=close)
        closer.start()
        wait_for(lambda: publisher._stop.is_set(), 30.0, "close to begin")
        closer.join(1.0)  # a close that did not wait would return now, the frame unmade
        assert order == [] and closer.is_alive()
        release.set()
        closer.join(30.0)
        assert not closer.is_alive() and made.is_set()
        assert order == ["frame made", "close returned"]  # close returned after the frame


@pytest.mark.slow
def test_turns_are_fair_when_the_thread_cannot_keep_up(frames: FrameThread) -> None:
    with pages(4) as four:
        # 4 pages asking 200 frames/s each, every frame 5 ms: about 200 fit in a second
        counters = [Counter(p, cost_s=0.005) for p in four]
        publishers = [publish(c, frames, pose_hz=200.0, plot_hz=1.0) for c in counters]

        def turns() -> list[int]:
            """Each page's turns: a frame made, or one given up because viser had not yet
            sent the page its last one (how soon it does is viser's sender's business, and
            on a busy machine it differs from page to page)."""
            return [c.poses + p.stats.skipped_behind
                    for c, p in zip(counters, publishers, strict=True)]

        # count from when all four take turns (the first one started alone, for as long
        # as a busy machine took to start the others), to the same moment for all four
        wait_for(lambda: min(c.poses for c in counters) > 5, 120.0, "every page's frames")
        start = turns()

        def since() -> list[int]:
            return [n - s for n, s in zip(turns(), start, strict=True)]

        wait_for(lambda: min(since()) > 150, 120.0, "150 turns more for every page")
        counts = since()
        for publisher in publishers:
            publisher.close(settle_s=0.0)
        assert min(counts) > 0.8 * max(counts), counts


def test_a_closed_frame_thread_takes_no_publisher() -> None:
    frames = FrameThread()
    frames.close()
    assert not frames._thread.is_alive()
    with pages(1) as one, pytest.raises(RuntimeError, match="closed"):
        publish(Counter(one[0]), frames)


def test_a_page_not_yet_sent_its_last_frame_gets_none_until_it_is_or_a_second_passed(
        frames: FrameThread) -> None:
    with pages(1) as one:
        page = one[0]
        counter = Counter(page)
        publisher = publish(counter, frames)
        stats = publisher.stats
        wait_for(lambda: counter.poses > 5, 60.0, "frames")
        with page.atomic():  # viser sends the page nothing while a block is open
            skipped, waited = stats.skipped_behind, stats.waited_behind
            # once a frame waits unsent, each frame due is looked at again, then given up
            wait_for(lambda: stats.skipped_behind > skipped, 60.0, lambda: f"{stats}")
            made, forced = counter.poses, stats.forced_behind
            wait_for(lambda: stats.skipped_behind > skipped + 3
                     and stats.waited_behind > waited, 60.0, lambda: f"{stats}")
            # ... but a page behind for BEHIND_MAX_S gets a frame all the same (never frozen)
            wait_for(lambda: stats.forced_behind > forced + 1, 60.0, lambda: f"{stats}")
            wait_for(lambda: counter.poses - made == stats.forced_behind - forced, 10.0,
                     lambda: f"{counter.poses - made} frames, {stats}")  # only those
        wait_for(lambda: counter.poses > made + 5, 60.0, "frames once the page was sent")
        publisher.close(settle_s=0.0)
