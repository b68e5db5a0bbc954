"""Faults told as they are: actions on a lab whose serial link died (real pty to the
emulator). The unsent torque-off itself: tests/test_bus_backend.py."""

from __future__ import annotations

import contextlib
import signal
import time

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


def test_emulator_restarted_under_its_link_the_lab_reconnects_and_waits_for_reset(tmp_path):
    """A re-plug: the device path (here ``emulate --link``, as a /dev/serial/by-id name)
    comes back with new servos behind it; the lab finds them, configures them, keeps the
    torque off and says so; Reset while the link is down says why nothing happened."""
    from app.server import Lab, ServeOptions
    from app.wsclient import HeadlessClient

    link = tmp_path / "by-id" / "usb-armlab-emulator"
    link.parent.mkdir()
    with contextlib.ExitStack() as stack:
        emu = stack.enter_context(emulator("--link", str(link)))
        lab = stack.enter_context(Lab(ServeOptions(backend="serial", port=str(link),
                                                   http_port=0)))
        lesson = lab.lesson
        loop = lesson.rig.loop
        page = stack.enter_context(HeadlessClient(lab.url.replace("http://", "ws://")).connect())
        page.wait_for(lambda: loop.status.active, timeout=30, what="the loop holding")
        emu.stop(signal.SIGKILL)  # the cable is pulled
        page.wait_for(lambda: loop.status.link_down, timeout=30, what="the loop to notice")
        page.wait_for(lambda: lesson.reconnect_button.visible, timeout=30,
                      what="the Reconnect button")
        page.click("Reset")
        page.wait_for(lambda: any("link to the servos is down" in b
                                  for _, b in page.notifications),
                      timeout=30, what="the Reset refusal")
        assert sum("link to the servos is down" in b for _, b in page.notifications) == 1
        assert not loop.status.active

        stack.enter_context(emulator("--link", str(link)))  # plugged in again
        page.wait_for(lambda: not loop.status.link_down, timeout=60, what="the reconnection")
        st = loop.status
        assert not st.active and not st.torque_on  # torque off until the teacher says so
        assert st.fault is not None and st.fault.startswith("link back")
        page.wait_for(lambda: not lesson.reconnect_button.visible, timeout=30,
                      what="the Reconnect button to go")
        page.wait_for(lambda: "link back" in str(lesson.status.content), timeout=30,
                      what="the status to say so")
        page.click("Reset")
        page.wait_for(lambda: loop.status.active and loop.status.torque_on, timeout=30,
                      what="the arm held again after Reset")


#: how long a lab must hold under a light fault rate, s of loop time
HOLD_S = 3.0


def _outcome(kind: str, rate: float) -> tuple[str, str]:
    """Serve the lab on an emulator whose replies are ``kind`` at ``rate``; returns
    ("refused" | "stopped" | "hold" | "hold, told", the message or status line)."""
    from app.server import Lab, ServeOptions
    from app.wsclient import HeadlessClient
    from control.backend import BackendError

    args = [f"--{kind}", str(rate), "--seed", "7"]
    if kind == "delay":
        args += ["--delay-time", "0.2"]  # later than the reply timeout: a lost reply
    with emulator(*args) as emu:
        try:
            lab = Lab(ServeOptions(backend="serial", port=emu.port, http_port=0))
        except BackendError as exc:
            return "refused", str(exc)
        # a page watches: the lab updates its status line for pages only
        with lab, HeadlessClient(lab.url.replace("http://", "ws://")).connect():
            loop, status = lab.lesson.rig.loop, lab.lesson.status
            deadline = time.monotonic() + 120.0
            while time.monotonic() < deadline:  # poll: the loop's own clock decides
                st = loop.status
                if st.fault is not None:
                    assert not st.active
                    return "stopped", st.fault
                if st.active and "link unreliable" in str(status.content):
                    return "hold, told", str(status.content)
                if st.active and st.t >= HOLD_S and rate < 0.15:
                    return "hold", str(status.content)
                time.sleep(0.05)
            return "hold, not told", str(status.content)


@pytest.mark.parametrize("kind", ["drop", "corrupt", "delay"])
@pytest.mark.parametrize("rate", [0.02, 0.15, 0.5])
def test_fault_matrix_holds_or_stops_with_a_message_never_a_traceback(kind, rate, capfd):
    """2 % of replies lost: the retries absorb them and the arm is held. 15 % and 50 %: held
    with the status line telling the link is unreliable, or stopped (or refused at start)
    with a message naming the servo, torque off. Never held silently, no traceback."""
    outcome, message = _outcome(kind, rate)
    if rate <= 0.02:
        assert outcome.startswith("hold"), message
    else:
        assert outcome in ("refused", "stopped", "hold, told"), (outcome, message)
    if outcome in ("refused", "stopped"):
        assert "servo" in message and len(message) < 400, message
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-2000:]
