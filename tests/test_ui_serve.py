"""``armlab serve`` as a real process: the url line, loopback, a taken port, Ctrl-C, and the
serial backend on emulated servos (torque off when the lab stops)."""

from __future__ import annotations

import os
import select
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from pathlib import Path
from urllib.parse import parse_qs

import pytest
from _emulator import emulator
from _helpers import wait_for

from armlab.hardware.families.dynamixel1 import packets as p1

pytestmark = pytest.mark.realtime  # `armlab serve` processes on the wall clock

ROOT = Path(__file__).resolve().parents[1]
START_TIMEOUT = 60.0  # s: a loaded 2-core machine


def start_serve(*args: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen([sys.executable, "-m", "armlab.app", "serve", *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    deadline = time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.5)
        if ready:
            line = proc.stdout.readline()
            if line.startswith("url: "):
                return proc, line.split(" ", 1)[1].strip()
            if line == "" and proc.poll() is not None:
                break
    proc.kill()
    out, err = proc.communicate(timeout=10)
    raise AssertionError(f"no url line: {out!r} {err!r}")


def stop(proc: subprocess.Popen, sig: int = signal.SIGINT) -> tuple[int, str, str]:
    proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"serve did not stop on signal {sig}: {err}") from None
    return proc.returncode, out, err


def test_serve_prints_a_loopback_url_on_a_free_port_and_stops_on_ctrl_c():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc, url = start_serve("--http-port", str(port))
        try:
            parts = urllib.parse.urlsplit(url)  # http://127.0.0.1:PORT/?token=TOKEN
            assert parts.scheme == "http" and parts.hostname == "127.0.0.1"
            assert parts.port != port  # the taken port was skipped
            assert parts.path == "/" and len(parse_qs(parts.query)["token"][0]) >= 16
            with urllib.request.urlopen(url, timeout=10) as reply:
                assert reply.status == 200
        finally:
            code, out, err = stop(proc)
    assert code == 0, err
    assert "stopping" in out


def test_a_class_on_loopback_is_told_that_no_phone_can_join():
    """``serve --classroom`` without ``--host``: the console says the students cannot join
    and what to pass."""
    proc, url = start_serve("--classroom", "--http-port", "0")
    try:
        assert urllib.parse.urlsplit(url).hostname == "127.0.0.1"
    finally:
        code, out, err = stop(proc)
    assert code == 0, err
    warned = [line for line in err.splitlines() if "cannot join" in line]
    assert len(warned) == 1 and "--host 0.0.0.0" in warned[0], err


def test_serve_refuses_serial_without_a_port():
    res = subprocess.run([sys.executable, "-m", "armlab.app", "serve", "--backend", "serial"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert "armlab serve: port:" in res.stderr and "--port" in res.stderr


def _torque_off_packets(packets: list[bytes]) -> list[bytes]:
    """Packets that write 0 to Torque Enable (address 24): broadcast WRITE or SYNC_WRITE."""
    out = []
    for raw in packets:
        try:
            pkt = p1.decode_instruction(raw)
        except ValueError:
            continue
        params = bytes(pkt.params)
        if pkt.instruction == p1.Instruction.WRITE and params[:1] == b"\x18" \
                and params[1:] == b"\x00":
            out.append(raw)
        elif pkt.instruction == p1.Instruction.SYNC_WRITE and params[:1] == b"\x18" \
                and all(b == 0 for b in params[3::2]):
            out.append(raw)
    return out


@pytest.mark.timeout(240)
def test_serial_lab_switches_torque_off_when_stopped(tmp_path):
    with emulator("--robot", "receptionist_arm", log_dir=tmp_path) as emu:
        proc, url = start_serve("--backend", "serial", "--port", emu.port, "--http-port", "0")
        try:
            with urllib.request.urlopen(url, timeout=10) as reply:
                assert reply.status == 200
            wait_for(lambda: len(emu.packets("rx")) > 10, 60.0, "the lab talking to the servos")
        finally:
            code, out, err = stop(proc, signal.SIGTERM)
        assert code == 0, err
        # the emulator logs what it received in its own time: wait for the last packets
        wait_for(lambda: _torque_off_packets(emu.packets("rx")[-20:]), 30.0,
                 "the last packets to switch torque off")


def _next_line(proc: subprocess.Popen) -> str:
    """The next stdout line (printed with the url line: a blocking read; the test's
    timeout bounds it). No select here: the url line's read may have buffered it."""
    return proc.stdout.readline()


def test_classroom_prints_the_network_url_then_the_passcode():
    proc, url = start_serve("--classroom", "--host", "0.0.0.0", "--http-port", "0")
    try:
        line = _next_line(proc)
        assert line.startswith("passcode: "), line  # the line right after the url
        passcode = line.split(" ", 1)[1].strip()
        parts = urllib.parse.urlsplit(url)  # http://LAN-ADDRESS:PORT/?token=TOKEN
        assert parts.hostname != "0.0.0.0"
        socket.inet_aton(parts.hostname)  # an address a student can type
        assert len(passcode) >= 6 and passcode.isalnum()
        token = parse_qs(parts.query)["token"][0]
        # then the teacher's presenter link: the url with the passcode
        assert _next_line(proc).strip() == f"presenter: {url}&presenter={passcode}"
        # tests talk to loopback only: the same server through 127.0.0.1
        local = f"http://127.0.0.1:{parts.port}/?token={token}"
        with urllib.request.urlopen(local, timeout=10) as reply:
            assert reply.status == 200
    finally:
        code, out, err = stop(proc)
    assert code == 0, err
    assert "without --classroom" not in err


def test_listening_on_the_network_without_classroom_warns():
    proc, url = start_serve("--host", "0.0.0.0", "--http-port", "0")
    code, out, err = stop(proc)
    assert code == 0, err
    assert "without --classroom: every browser with the URL then controls the arm" in err
    assert "passcode" not in out


def test_serve_a_urdf_with_its_tip_link_and_a_package_path():
    """``armlab serve --robot FILE.urdf --tip-link LINK --package-path DIR``, as a person
    types it: the page gets a slider per joint of the chain to that link, and the meshes
    the package path finds are drawn (only the ones still missing are named, once)."""
    from armlab.app.testing.wsclient import HeadlessClient
    from armlab.kinematics import load_robot

    data = ROOT / "tests" / "data"
    urdf = data / "mobile_manipulator.urdf"
    chain = load_robot(urdf, tip_link="tcp_link")
    proc, url = start_serve("--robot", str(urdf), "--tip-link", "tcp_link",
                            "--package-path", str(data / "extra_packages"),
                            "--http-port", "0")
    try:
        parts = urllib.parse.urlsplit(url)
        local = f"ws://127.0.0.1:{parts.port}/?{parts.query}"  # loopback, as printed
        with HeadlessClient(local).connect() as page:
            labels = [f"{name} °" for name in chain.joint_names]
            page.wait_for(lambda: all(page.shows(label) for label in labels), 60.0,
                          "a slider per joint of the chain to tcp_link")
            assert not page.shows("camera_joint °")  # off the chain
    finally:
        code, out, err = stop(proc)
    assert code == 0, err
    assert err.count("shoulder.dae") == 1 and err.count("upper_arm.dae") == 1  # named once
    assert "camera.stl" not in err  # found through --package-path
