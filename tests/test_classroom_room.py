"""A room of 30 pages, each with a private arm playing the thesis line, beside the shared
arm (armlab/app/benches/classroom.py's room, shorter): nothing dies. The figures it measures are
the bench's (``armlab bench``), never asserted here: the machine is shared."""

from __future__ import annotations

import math

import pytest

from armlab.app.benches.classroom import room_of_30

pytestmark = [pytest.mark.realtime, pytest.mark.timeout(900)]


def test_thirty_pages_with_private_arms_and_nothing_dies():
    # raises if any arm or the shared loop stopped, or a page never drew its own arm
    figures = room_of_30(seconds=10.0, pages=30, settle=5.0)
    assert figures["classroom_30_pose_hz"] > 0  # every page got frames of its own arm
    assert all(math.isfinite(v) for v in figures.values()), figures
