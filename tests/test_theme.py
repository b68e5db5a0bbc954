"""Each page's own Projector switch: ``armlab serve --projector``, the style sheet, and
the sizes one page gets (its sheet, its charts' axes, its 3D labels) while the other
pages, and the arm, stay as they were; a browser's choice is kept across a reload."""

from __future__ import annotations

import argparse
import re

import pytest
from _helpers import wait_for

from armlab.app.commands import serve
from armlab.app.page import theme
from armlab.app.testing.wsclient import HeadlessClient


def test_serve_projector_flag_parses():
    parser = argparse.ArgumentParser()
    serve.add_arguments(parser)
    assert parser.parse_args(["--projector"]).projector is True
    assert parser.parse_args([]).projector is False


def test_style_sheet_and_chart_sizes():
    assert "font-size:22px" in theme.style_sheet(theme.PROJECTOR)
    assert "font-size:14px" in theme.style_sheet(theme.NORMAL)
    assert theme.chart_font(theme.PROJECTOR).startswith("20px")
    assert theme.chart_font(theme.NORMAL, bold=True).startswith("bold 13px")


def _page(lab, stored: str | None = None):
    """A headless page of ``lab`` whose browser holds ``stored`` as its choice (None:
    none), returned with its client id once the lab has settled its mode."""
    before = set(lab.server.get_clients())
    page = HeadlessClient(f"ws://127.0.0.1:{lab.server.get_port()}/?token={lab.token}")
    if stored is not None:
        page.local_storage[theme.PROJECTOR_KEY] = stored
    page.connect(30.0)
    ids: list[int] = []

    def registered() -> bool:
        ids[:] = sorted(set(lab.server.get_clients()) - before)
        return bool(ids) and lab.page_style.settled(ids[0])

    wait_for(registered, 120.0, "the page's text size to settle")
    return page, ids[0]


def _tick_px(page, title: str | None = None) -> list[float]:
    """px of every chart axis font the page shows now (of the charts titled ``title``)."""
    return [float(re.match(r"(?:bold )?(\d+)px", a["font"]).group(1))
            for e in list(page.gui.values()) if e.kind == "GuiUplotMessage"
            and title in (None, e.props.get("title")) for a in e.props["axes"]]


#: a chart of the hand lesson (the test switches to it: the compliance lesson has none)
HAND_CHART = "Motor current (measured)"


def _sheet(page) -> str:
    """The page's chart style sheet ("" while the page has none)."""
    return next((e.props["content"] for e in list(page.gui.values())
                 if e.kind == "GuiHtmlMessage" and "<style>" in e.props.get("content", "")
                 and ".u-title" in e.props["content"]), "")


def _label_scales(page) -> list[float]:
    """The font_screen_scale updates the page got for its 3D labels."""
    return [n["SceneNodeUpdateMessage"]["font_screen_scale"] for n in list(page.scene.values())
            if "font_screen_scale" in n.get("SceneNodeUpdateMessage", {})]


#: the compliance lesson's 3D labels (its shoulder's and the thesis path's)
COMPLIANCE_LABELS = 2


@pytest.fixture(scope="module")
def lab():
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0)) as running:
        yield running


@pytest.mark.slow
def test_one_page_switches_to_projector_the_others_and_the_arm_do_not(lab):
    lesson, rig = lab.lesson, lab.lesson.rig
    a, a_id = _page(lab)
    b, b_id = _page(lab)
    with a, b:
        for page in (a, b):
            page.wait_for(lambda p=page: bool(_tick_px(p)), 60.0, "the charts")
            assert max(_tick_px(page)) < 18.0 and "14px" in _sheet(page)
        assert not lab.page_style.is_projector(a_id)
        # a's own switch, as its person clicks it
        a.set_value(lab.page_style.switch(a_id), True)
        # the sizes go out one element after another: wait for the last of them, whichever
        a.wait_for(lambda: _tick_px(a) and min(_tick_px(a)) >= 18.0 and "22px" in _sheet(a)
                   and len(_label_scales(a)) == COMPLIANCE_LABELS
                   and a.local_storage.get(theme.PROJECTOR_KEY) == "1", 60.0,
                   "a's charts, sheet and 3D labels in projector sizes, kept in its browser")
        assert min(_label_scales(a)) >= theme.LABEL_SCALE[True]
        # b, the server's own handles and the arm are untouched
        assert max(_tick_px(b)) < 18.0 and "14px" in _sheet(b) and not _label_scales(b)
        assert "14px" in lab.page_style.sheet.content
        assert lab.lesson is lesson and lesson.rig is rig  # nothing re-opened or rebuilt
        # a chart built from now on (a lesson switch) reaches a in projector sizes
        lab.switch("hand")  # the pages may still show the old charts: wait for the new
        a.wait_for(lambda: _tick_px(a, HAND_CHART) and min(_tick_px(a)) >= 18.0, 60.0,
                   "the new lesson's charts in projector sizes on a")
        b.wait_for(lambda: _tick_px(b, HAND_CHART) and max(_tick_px(b)) < 18.0, 60.0,
                   "the new lesson's charts in normal sizes on b")
        # and back off
        a.set_value(lab.page_style.switch(a_id), False)
        a.wait_for(lambda: _tick_px(a) and max(_tick_px(a)) < 18.0 and "14px" in _sheet(a)
                   and a.local_storage.get(theme.PROJECTOR_KEY) == "0", 60.0,
                   "a back to normal sizes, kept in its browser")
    lab.switch("compliance")


def test_a_reload_keeps_the_browser_choice(lab):
    page, cid = _page(lab, stored="1")  # this browser chose projector before
    with page:
        assert lab.page_style.is_projector(cid)
        assert lab.page_style.switch(cid).value is True
        page.wait_for(lambda: _tick_px(page) and min(_tick_px(page)) >= 18.0, 60.0,
                      "projector charts after the reload")
    page, cid = _page(lab)  # a browser that never chose: the lab's default (normal)
    with page:
        assert not lab.page_style.is_projector(cid)


@pytest.mark.slow
def test_serve_projector_is_the_default_of_a_browser_without_a_choice():
    from armlab.app.lab.server import Lab, ServeOptions

    with Lab(ServeOptions(http_port=0, projector=True)) as lab:
        fresh, fresh_id = _page(lab)
        chose, chose_id = _page(lab, stored="0")
        with fresh, chose:
            assert lab.page_style.is_projector(fresh_id)
            assert not lab.page_style.is_projector(chose_id)
            fresh.wait_for(lambda: _tick_px(fresh) and min(_tick_px(fresh)) >= 18.0, 60.0,
                           "projector charts on the fresh page")
            assert theme.PROJECTOR_KEY not in fresh.local_storage  # the default is no choice
            chose.wait_for(lambda: _tick_px(chose) and max(_tick_px(chose)) < 18.0, 60.0,
                           "normal charts on the page that chose them")
