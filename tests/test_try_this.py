"""The first minute: every lesson tells a newcomer what to do first, under its status line,
on the page itself (what a browser receives), naming a control that is really there."""

from __future__ import annotations

import re

import pytest
from _helpers import settled

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.lessons.catalog import all_lessons
from armlab.app.testing.wsclient import HeadlessClient


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
        settled(lab.server, page)  # the lesson's controls may follow its line
        labels = {str(el.label) for el in list(page.gui.values()) if el.label}
        labels |= {str(tab) for el in list(page.gui.values())  # a tab group's tabs
                   for tab in el.props.get("_tab_labels") or ()}
        named = re.findall(r"\*\*(.+?)\*\*", text)[1:]
        assert named, f"{name}: the line names no control in bold: {text!r}"
        for bold in named:  # each control it names exists
            assert bold in labels, (bold, sorted(labels))
