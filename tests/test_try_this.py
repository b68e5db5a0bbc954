"""The first minute: every lesson tells a newcomer what to do first, under its status line,
on the page itself (what a browser receives), naming a control that is really there."""

from __future__ import annotations

import contextlib
import re

import pytest

from app.lessons import all_lessons
from app.server import Lab, ServeOptions
from app.wsclient import HeadlessClient


@pytest.mark.parametrize("name", sorted(all_lessons()))
def test_every_lesson_shows_a_try_this_line_naming_a_real_control(name):
    with Lab(ServeOptions(http_port=0, lesson=name, realtime=False)) as lab, \
            HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
        def try_line() -> str | None:
            for el in list(page.gui.values()):
                content = str(el.props.get("_markdown") or "")
                if content.startswith("**Try this:**"):
                    return content
            return None

        page.wait_for(lambda: try_line() is not None, timeout=60, what="the Try this line")
        text = try_line()
        assert len(text) > len("**Try this:**") + 20
        named = re.findall(r"\*\*(.+?)\*\*", text)[1:]  # the controls it names, if any

        def missing() -> list[str]:
            labels = {str(el.label) for el in list(page.gui.values()) if el.label}
            return [bold for bold in named if bold not in labels]

        # each control it names exists: the lesson's controls may arrive after the line
        with contextlib.suppress(TimeoutError):
            page.wait_for(lambda: not missing(), timeout=60, what="the controls it names")
        assert not missing(), (missing(), text)
