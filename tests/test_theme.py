"""The Projector switch: ``armlab serve --projector`` and the page's style sheet."""

from __future__ import annotations

import argparse

from app import theme
from app.commands import serve


def test_serve_projector_flag_parses():
    parser = argparse.ArgumentParser()
    serve.add_arguments(parser)
    assert parser.parse_args(["--projector"]).projector is True
    assert parser.parse_args([]).projector is False


def test_style_sheet_sizes_and_lab_state():
    from app.server import Lab, ServeOptions

    assert "font-size:22px" in theme.style_sheet(theme.PROJECTOR)
    assert "font-size:14px" in theme.style_sheet(theme.NORMAL)
    with Lab(ServeOptions(http_port=0, projector=True)) as lab:
        assert theme.projector() and lab.page_style.switch.value is True
        assert "22px" in lab.page_style.sheet.content
        assert theme.chart_font().startswith("20px")
        lab.page_style.set(False)
        assert "14px" in lab.page_style.sheet.content and lab.page_style.switch.value is False
        assert lab.lesson is not None  # the lesson re-opened with normal charts
    assert not theme.projector()
