"""Helpers for the projector / line-style tests: the charts a page receives."""

from __future__ import annotations

from typing import Any

from _helpers import client_of, wait_for


def chart_props(server: Any, timeout: float = 60.0, *, token: str | None = None) -> list[dict]:
    """The props (series, axes, ...) of every uPlot chart a new page of ``server`` receives
    (``token``: a gated lab's, armlab.app.classroom.gate)."""
    with client_of(server, token=token) as client:
        def charts():
            return [e for e in client.gui.values() if e.kind == "GuiUplotMessage"]
        wait_for(lambda: len(charts()) > 0, timeout, "the charts to arrive")
        return [dict(e.props) for e in charts()]
