"""The garbage collector kept out of the loops' way (armlab.control.collector): what a lab keeps is
frozen, a closed lesson's garbage is freed at the next tidy, not before; a closed lab's
is handed back to the collector's own passes."""

from __future__ import annotations

import gc
import weakref

import pytest

from armlab.control import collector


class _Node:
    """A cycle: only the cyclic collector frees it."""

    def __init__(self) -> None:
        self.me = self


def _kept_cycle() -> weakref.ref:
    """A cycle made garbage after :func:`collector.keep` froze it."""
    node = _Node()
    gone = weakref.ref(node)
    collector.keep()
    del node
    return gone


def test_kept_objects_are_out_of_the_full_passes_and_tidy_frees_what_closed() -> None:
    try:
        gone = _kept_cycle()
        assert gc.get_freeze_count() > 0
        gc.collect()  # a full pass does not see a frozen cycle
        assert gone() is not None
        collector.tidy()  # whatever earlier tests closed
        gone = _kept_cycle()
        assert collector.tidy() is None  # nothing closed since: nothing to do
        assert gone() is not None
        collector.closed()
        pause = collector.tidy()
        assert pause is not None and pause >= 0.0
        assert gone() is None
        assert gc.get_freeze_count() > 0  # what is alive is frozen again
        # in a running class, at most one tidy a while
        gone = _kept_cycle()
        collector.closed()
        assert collector.tidy(every_s=1e9) is None and gone() is not None
        assert collector.tidy() is not None and gone() is None
    finally:
        gc.unfreeze()  # leave the test process as it was


def test_a_closed_lab_hands_what_it_kept_back_to_the_collector_without_a_full_pass() -> None:
    try:
        gone = _kept_cycle()
        collector.closed()  # a lesson closed earlier, not yet tidied
        collector.release()
        assert gc.get_freeze_count() == 0  # nothing hidden from the collector any more
        assert gone() is not None  # not collected by release itself: no pause at the close
        assert collector.tidy() is None  # and nothing left waiting for a tidy
        gc.collect()  # the collector's own pass frees it
        assert gone() is None
    finally:
        gc.unfreeze()


@pytest.mark.slow  # a lab served
def test_a_lab_keeps_what_it_built_while_it_runs_and_hands_it_back_when_it_closes() -> None:
    from armlab.app.lab.server import Lab, ServeOptions

    try:
        with Lab(ServeOptions(http_port=0)):
            assert gc.get_freeze_count() > 0  # the lab and its lesson: out of full passes
        assert gc.get_freeze_count() == 0
        assert collector.tidy() is None  # no full pass owed for it either
    finally:
        gc.unfreeze()
