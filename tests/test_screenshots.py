"""``make screenshots`` (docs/screenshots.py) takes real pictures of the page in Chromium:
one lesson at 1280x720 and the phone picture at 390x844, each showing the lab (the
red E-STOP among its pixels), not a blank or half-loaded page."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _helpers import CHROMIUM

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

SCRIPT = Path(__file__).resolve().parents[1] / "docs" / "screenshots.py"


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

    # in a process of its own, as `make screenshots` runs it (this worker's Playwright, the
    # suite's shared Chromium, holds the event loop of this thread)
    out = subprocess.run([sys.executable, str(SCRIPT), "arm", "--out", str(tmp_path)],
                         cwd=SCRIPT.parents[1], capture_output=True, text=True, timeout=540)
    assert out.returncode == 0, out.stderr[-2000:]
    shots = [Path(line) if Path(line).is_absolute() else SCRIPT.parents[1] / line
             for line in out.stdout.split()]
    assert [p.name for p in shots] == ["arm.png", "phone.png"]
    sizes = [Image.open(p).size for p in shots]
    assert sizes == [(1280, 720), (390, 844)]
    for path in shots:
        colours = np.unique(np.asarray(Image.open(path).convert("RGB")).reshape(-1, 3), axis=0)
        assert len(colours) > 500, (path.name, len(colours))  # a drawn page, not a blank one
        assert _red_share(path) > 0.002, path.name  # E-STOP is in the picture
