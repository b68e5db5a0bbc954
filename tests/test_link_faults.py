"""Faults told as they are: actions on a lab whose serial link died (real pty to the
emulator). The unsent torque-off itself: tests/test_bus_backend.py."""

from __future__ import annotations

import signal

import pytest
from _emulator import emulator

pytestmark = pytest.mark.realtime  # the emulator's real-time physics over a pseudo-terminal


def test_link_killed_mid_run_the_lab_says_so_and_run_says_why_nothing_happens(tmp_path):
    from app.lessons.compliance import UNSENT_BANNER
    from app.server import Lab, ServeOptions
    from app.wsclient import HeadlessClient

    with emulator(log_dir=tmp_path) as emu:
        with Lab(ServeOptions(backend="serial", port=emu.port, http_port=0)) as lab:
            loop = lab.lesson.rig.loop
            with HeadlessClient(lab.url.replace("http://", "ws://")).connect() as page:
                page.wait_for(lambda: any(e.label == "Run thesis line" for e in page.gui.values()),
                              timeout=30, what="the Run button")
                page.wait_for(lambda: loop.status.active, timeout=30, what="the loop holding")
                emu.stop(signal.SIGKILL)  # the link dies mid-run
                page.wait_for(lambda: loop.status.fault is not None, timeout=30,
                              what="the loop to notice")
                page.wait_for(lambda: loop.status.torque_off_unsent, timeout=30,
                              what="the unsent torque-off")
                status = lab.lesson.status
                page.wait_for(lambda: UNSENT_BANNER in str(status.content), timeout=30,
                              what="the red banner")
                assert "torque off" not in str(status.content).replace(UNSENT_BANNER, "")
                page.click("Run thesis line")
                page.wait_for(lambda: any("nothing happened" in b for _, b in page.notifications),
                              timeout=30, what="the Run refusal")
                assert sum("nothing happened" in b for _, b in page.notifications) == 1
