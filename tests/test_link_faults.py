"""Faults told as they are: an e-stop over a dead serial link (real pty to the emulator)."""

from __future__ import annotations

import signal

from _emulator import emulator

from hardware.dynamixel_backend import DynamixelBackend
from kinematics.model import load_robot

ARM = load_robot("receptionist_arm")


def test_estop_over_a_dead_link_does_not_claim_torque_off(tmp_path):
    with emulator(log_dir=tmp_path) as emu:
        b = DynamixelBackend(ARM, emu.port, timeout_margin=0.1)
        try:
            b.configure()
            b.set_torque(True)
            assert b.read().torque_on[0]
            b.estop()  # link alive: sent, torque off
            assert not b.torque_off_unsent and not any(b.read().torque_on)
            b.set_torque(True)
            emu.stop(signal.SIGKILL)  # the link dies mid-run
            b.estop()  # never raises
            assert b.torque_off_unsent  # the lab shows the red banner
            assert b._torque  # and nothing claims the torque went off
        finally:
            b.close()


def test_emulator_link_keeps_its_name_across_a_restart(tmp_path):
    import os

    link = str(tmp_path / "serial-by-id-arm")
    with emulator("--link", link) as first:
        assert os.readlink(link) == first.port
        b = DynamixelBackend(ARM, link, timeout_margin=0.1)  # opened by the stable name
        try:
            assert b.configure()
        finally:
            b.close()
        first.stop(signal.SIGKILL)  # died hard: the stale link stays until replaced
        assert os.path.islink(link)
        with emulator("--link", link) as second:
            assert os.readlink(link) == second.port  # replaced on restart
            b = DynamixelBackend(ARM, link, timeout_margin=0.1)
            try:
                assert b.configure()
            finally:
                b.close()
            second.stop(signal.SIGTERM)
        assert not os.path.lexists(link)  # a clean stop removes its own link


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
                assert lab.lesson.rig.backend.torque_off_unsent
                status = lab.lesson.status
                page.wait_for(lambda: UNSENT_BANNER in str(status.content), timeout=30,
                              what="the red banner")
                assert "torque off" not in str(status.content).replace(UNSENT_BANNER, "")
                page.click("Run thesis line")
                page.wait_for(lambda: any("nothing happened" in b for _, b in page.notifications),
                              timeout=30, what="the Run refusal")
                assert sum("nothing happened" in b for _, b in page.notifications) == 1
