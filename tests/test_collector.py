"""The garbage collector kept out of the loops' way (armlab.app.collector): what a lab keeps is
frozen, a closed lesson's garbage is freed at the next tidy, not before."""

from __future__ import annotations

import gc
import weakref

from armlab.app import collector


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
