"""``make screenshots`` (docs/screenshots.py) takes real pictures of the page in Chromium:
one lesson at 1280x720 and the phone picture at 390x844, each showing the lab (the
red E-STOP among its pixels), not a blank or half-loaded page."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from _helpers import CHROMIUM

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

SCRIPT = Path(__file__).resolve().parents[1] / "docs" / "screenshots.py"


def _script():
    spec = importlib.util.spec_from_file_location("screenshots", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _red_share(path: Path) -> float:
    """Fraction of the picture's pixels in E-STOP's red (Mantine's red.6, #fa5252)."""
    from PIL import Image

    rgb = np.asarray(Image.open(path).convert("RGB")).astype(int)
    near = np.abs(rgb - np.array([250, 82, 82])).sum(axis=2) < 40
    return float(near.mean())


def test_make_screenshots_pictures_the_real_page(tmp_path):
    if not CHROMIUM.exists():
        pytest.skip(f"no Chromium at {CHROMIUM}")
    from PIL import Image

    shots = _script().take(tmp_path, ["arm"])
    assert [p.name for p in shots] == ["arm.png", "phone.png"]
    sizes = [Image.open(p).size for p in shots]
    assert sizes == [(1280, 720), (390, 844)]
    for path in shots:
        colours = np.unique(np.asarray(Image.open(path).convert("RGB")).reshape(-1, 3), axis=0)
        assert len(colours) > 500, (path.name, len(colours))  # a drawn page, not a blank one
        assert _red_share(path) > 0.002, path.name  # E-STOP is in the picture
