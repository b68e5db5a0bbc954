"""Run ``armlab emulate`` as a real subprocess on a real pty for the bus tests."""

from __future__ import annotations

import contextlib
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from armlab.hardware.families.xseries import packets as p2

ROOT = Path(__file__).resolve().parents[1]
START_TIMEOUT = 30.0  # s for the emulator to print its port (a loaded 2-core machine)


@dataclass
class EmulatorProcess:
    port: str
    proc: subprocess.Popen
    log: Path | None
    err: Path

    def stderr(self) -> str:
        return self.err.read_text()

    def packets(self, tag: str = "rx") -> list[bytes]:
        """Packets the emulator logged as received ("rx") or sent ("tx"), in order."""
        assert self.log is not None, "start the emulator with log=True"
        out = []
        for line in self.log.read_text().splitlines():
            parts = line.split(" ", 2)
            if len(parts) == 3 and parts[1] == tag:
                out.append(bytes.fromhex(parts[2]))
        return out

    def timed(self) -> list[tuple[float, str, bytes]]:
        assert self.log is not None
        out = []
        for line in self.log.read_text().splitlines():
            t, tag, hexs = line.split(" ", 2)
            out.append((float(t), tag, bytes.fromhex(hexs)))
        return out

    def cycle_traffic(self, backend: Any, position: Any, speed: Any
                      ) -> list[tuple[float, str, bytes]]:
        """The packets logged (:meth:`timed`) during one cycle of ``backend``: a write of
        ``position`` at ``speed``, then a read (what ``armlab bench --only bus`` times)."""
        seen = len(self.timed())
        backend.write(position, speed)
        backend.read()
        return self.timed()[seen:]

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 10.0) -> tuple[int, str]:
        """Signal the emulator and wait; returns (exit code, stderr)."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        return self.proc.returncode, self.stderr()


@contextlib.contextmanager
def emulator(*args: str, log_dir: Path | None = None) -> Iterator[EmulatorProcess]:
    """Start ``python -m armlab.app emulate ARGS``, yield once it printed its port, always kill it.

    An emulator that died on its own (not killed by the test) fails the test with its stderr;
    a test that fails is told whether the emulator was still running, and what it said
    (stopped with SIGTERM, it prints its packet counts and how far its plant slipped).
    """
    cmd = [sys.executable, "-m", "armlab.app", "emulate", *args]
    tmp = Path(tempfile.mkdtemp(prefix="armlab-emu-"))
    log = None
    if log_dir is not None:
        log = log_dir / f"emulator-{time.monotonic_ns()}.log"
        cmd += ["--log", str(log)]
    err = tmp / "stderr"
    with open(err, "w") as err_file:
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=err_file,
                                text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    emu = None
    try:
        ready, _, _ = select.select([proc.stdout], [], [], START_TIMEOUT)
        line = proc.stdout.readline() if ready else ""
        if not line.startswith("port: "):
            proc.kill()
            proc.wait(timeout=10)
            raise RuntimeError(f"emulator did not start: {line!r} {err.read_text()}")
        emu = EmulatorProcess(line.split(" ", 1)[1].strip(), proc, log, err)
        try:
            yield emu
        except BaseException as exc:  # say what the emulator was doing when the test failed
            died = proc.poll()
            code, said = emu.stop()  # the stop line of a live one; a dead one's last words
            exc.add_note(f"the emulator {'had died' if died is not None else 'was running'}"
                         f" (exit {code}); its stderr: {said.strip()}")
            raise
        code = proc.poll()
        if code not in (None, 0, -signal.SIGKILL, -signal.SIGTERM):
            raise RuntimeError(f"the emulator died (exit {code}): {err.read_text()}")
    finally:
        if proc.poll() is None:
            proc.kill()
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=10)
        proc.stdout.close()
        shutil.rmtree(tmp, ignore_errors=True)


def goal_positions(packets: list[bytes], servo_id: int) -> list[int]:
    """Goal positions sent to ``servo_id`` in protocol-2.0 SYNC_WRITEs of profile velocity
    and goal position (addresses 112..119), in order."""
    out = []
    for raw in packets:
        packet = p2.decode_instruction(raw)
        params = packet.params
        if packet.instruction != p2.Instruction.SYNC_WRITE or params[:4] != bytes(
                (112, 0, 8, 0)):
            continue
        for k in range(4, len(params), 9):
            if params[k] == servo_id:
                out.append(int.from_bytes(params[k + 5 : k + 9], "little"))
    return out


def page_shows(page: Any, text: str) -> int:
    """How many times the page's HTML elements (the status line...) hold ``text``."""
    return sum(str(e.props.get("content", "")).count(text) for e in page.gui.values()
               if e.kind == "GuiHtmlMessage")


def pull_the_cable(emu: EmulatorProcess, loop: Any, status: Any, page: Any) -> str:
    """SIGKILL ``emu`` under ``loop`` (holding the arm) and wait for what the page must then
    show: the link down, the torque-off unsent, the red banner once, and under it why
    (never "torque off"); the status line's text."""
    from armlab.app.lessons._loop_state import UNSENT_BANNER

    emu.stop(signal.SIGKILL)  # the link dies mid-run
    page.wait_for(lambda: loop.status.link_down, timeout=30, what="the loop to notice")
    page.wait_for(lambda: loop.status.torque_off_unsent, timeout=30,
                  what="the unsent torque-off")
    page.wait_for(lambda: page_shows(page, UNSENT_BANNER) == 1, timeout=30,
                  what="the red banner on the page")
    content = str(status.content)
    assert "torque off" not in content.replace(UNSENT_BANNER, ""), content
    assert "lost the serial link" in content  # why, under the banner
    return content


def sync_goals(packets: list[bytes], protocol: int | str) -> dict[int, list[int]]:
    """Raw Goal Positions per servo ID in the goals' SYNC_WRITEs the emulator received
    (``packets``: :meth:`EmulatorProcess.packets`), in order, for servos of ``protocol``
    (1, 2 or "sts"): each family lays its goal at the start of the SYNC_WRITE's block
    (protocol 1.0 and STS: the goal position's 2 bytes first; the X-series: the Profile
    Velocity's 4 bytes, then the goal position's 4)."""
    from armlab.hardware.servos.registry import family

    fam = family(protocol)
    codec = fam.codec
    goal_item = "goal_position"
    out: dict[int, list[int]] = {}
    for raw in packets:
        try:
            packet = codec.decode_instruction(raw)
        except ValueError:
            continue
        if packet.instruction != codec.Instruction.SYNC_WRITE:
            continue
        p = bytes(packet.params)
        if protocol == 2:
            address, size, body, offset, width = (p[0] | p[1] << 8, p[2] | p[3] << 8, p[4:],
                                                  4, 4)
            table = fam.default_table
            first = table.item("profile_velocity").address
        else:
            address, size, body, offset, width = p[0], p[1], p[2:], 0, 2
            table = fam.default_table
            first = table.item(goal_item).address
        if address != first or size < offset + width:
            continue
        for k in range(0, len(body) - size, size + 1):  # (ID, size bytes) a servo
            block = body[k + 1 : k + 1 + size]
            out.setdefault(body[k], []).append(
                table.decode(goal_item, bytes(block[offset : offset + width])))
    return out
