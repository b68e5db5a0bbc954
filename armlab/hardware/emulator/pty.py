"""The emulated servos served behind a pseudo-terminal: any family's network, its replies
paced at the line's baud, faults injected (``armlab emulate``).

``armlab emulate`` runs this in its own process (an emulator thread inside the client's
process showed ~23 ms latency spikes; docs/serial.md, "Timing"). The client's baud is
read from the pty master with TCGETS2; a servo set to another baud stays silent.
"""

from __future__ import annotations

import fcntl
import os
import random
import select
import struct
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TextIO

from armlab.hardware.emulator.network import ServoBus
from armlab.hardware.servos.servo_spec import wire_time
from armlab.kinematics.validate import scalar

TCGETS2 = 0x802C542A  #: _IOR('T', 0x2A, struct termios2) on Linux


PACKET_GAP = 0.1  #: s: a longer pause between bytes drops a partial packet




#: s of plant time integrated at most before answering; when the CPU cannot keep the
#: plant in real time, its clock slips instead of the replies coming late
MAX_CATCH_UP = 0.1


def line_baud(master_fd: int) -> float | None:
    """The baud rate the client set on the pty's slave side (TCGETS2 on the master)."""
    buf = bytearray(44)
    try:
        fcntl.ioctl(master_fd, TCGETS2, buf)
    except OSError:
        return None
    return float(struct.unpack_from("2I", buf, 36)[1])  # c_ospeed


@dataclass(frozen=True)
class Faults:
    """Fault injection on replies, each a probability per status packet.

    Attributes:
        drop: the reply is never sent.
        corrupt: one byte of the reply (after the header) is flipped.
        delay: the reply is held back ``delay_time`` s (later than a client's timeout).
        delay_time: s.
        seed: random seed (None: from the OS).
    """

    drop: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0
    delay_time: float = 0.05
    seed: int | None = None

    def __post_init__(self) -> None:
        for name in ("drop", "corrupt", "delay"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name}: a fraction of replies in [0, 1], got {v}")
        scalar("delay_time (s)", self.delay_time, nonnegative=True)


@dataclass
class EmulatorStats:
    """Counters of a running emulator (``slipped``: s the plant clock fell behind the wall
    clock because the CPU could not integrate it in real time)."""

    packets: int = 0
    replies: int = 0
    dropped: int = 0
    corrupted: int = 0
    delayed: int = 0
    wrong_baud: int = 0
    slipped: float = 0.0
    lost_bytes: int = 0


@dataclass
class PtyEmulator:
    """Serves the emulated network of any servo family (a :class:`ServoBus`: the
    ``emulator.py`` of each ``armlab/hardware/families/<family>/``) on a new
    pseudo-terminal, in the network's packets (its ``codec`` and ``parser()``).

    Args:
        network: the servos.
        pace: hold each reply until the request and reply would have crossed the
            wire at the line's baud (10 bits a byte) plus the return delay.
        faults: fault injection on replies.
        echo: echo every received byte back first (a half-duplex TTL adapter).
        log: text stream for one line per received (``rx``) and sent (``tx``) packet.
        control: (a readable file descriptor, a handler): each line read from it is
            handed to the handler between packets (``armlab emulate --control``).
    """

    network: ServoBus
    pace: bool = False
    faults: Faults = field(default_factory=Faults)
    echo: bool = False
    log: TextIO | None = None
    control: tuple[int, Callable[[str], None]] | None = None
    stats: EmulatorStats = field(default_factory=EmulatorStats)

    def __post_init__(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self._rng = random.Random(self.faults.seed)
        self._p = self.network.codec
        self._parser = self.network.parser()
        self._queue: list[tuple[float, bytes]] = []  # (due time, bytes), sorted
        self._wire_free = 0.0
        self._last_byte = 0.0
        self._t0 = time.monotonic()  # wall time of plant time 0 (moves when the plant slips)
        self._log_t0 = self._t0
        self._control_buf = b""

    def close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def serve(self, stop: Callable[[], bool]) -> None:
        """Answer packets until ``stop()`` returns True (checked at least every 5 ms)."""
        while not stop():
            now = time.monotonic()
            wait = 0.005
            if self._queue:
                wait = min(wait, max(0.0, self._queue[0][0] - now - 2e-4))
            fds = [self._master] + ([self.control[0]] if self.control else [])
            ready, _, _ = select.select(fds, [], [], wait)
            now = time.monotonic()
            if self.control is not None and self.control[0] in ready:
                self._read_control()
            if self._master in ready:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    data = b""
                if data:
                    self._receive(data, now)
            self._tick(now)
            self._flush_due()

    def _read_control(self) -> None:
        """Hand each whole line waiting on the control descriptor to its handler (before
        the packets that came with it: a person's hand moved the arm first)."""
        assert self.control is not None
        fd, handler = self.control
        try:
            self._control_buf += os.read(fd, 4096)
        except BlockingIOError:
            return
        *lines, self._control_buf = self._control_buf.split(b"\n")
        for line in lines:
            if line.strip():
                handler(line.decode(errors="replace").strip())

    def _tick(self, now: float) -> None:
        """Advance the plant to ``now``, at most MAX_CATCH_UP at a time (the rest slips)."""
        t = now - self._t0
        behind = t - self.network.t
        if behind > MAX_CATCH_UP:
            self._t0 += behind - MAX_CATCH_UP
            self.stats.slipped += behind - MAX_CATCH_UP
            t = now - self._t0
        self.network.tick(t)

    def _receive(self, data: bytes, now: float) -> None:
        if self.echo:
            self._write(data)
        if self._parser.pending and now - self._last_byte > PACKET_GAP:
            self._parser.discard()
        self._last_byte = now
        baud = line_baud(self._master)
        wire_baud = baud or 1_000_000.0
        for raw in self._parser.feed(data):
            self.stats.packets += 1
            self._log("rx", raw, now)
            if not any(s.hears(baud) for s in self.network.servos):
                self.stats.wrong_baud += 1
                continue
            try:
                packet = self._p.decode_instruction(raw)
            except self._p.ProtocolError:  # a status packet: not ours
                continue
            self._tick(now)
            replies = self.network.handle(packet, baud=baud)
            self._schedule(raw, replies, now, wire_baud)
        bad = getattr(self._parser, "bad", [])  # broken checksums its servos answer
        for raw in bad:
            self._schedule(raw, self.network.checksum_error(raw, baud=baud), now, wire_baud)
        bad.clear()

    def _schedule(self, request: bytes, replies: list,
                  now: float, baud: float) -> None:
        t = now
        if self.pace:
            t = max(self._wire_free, now) + wire_time(len(request), baud)
            self._wire_free = t
        for servo, reply in replies:
            due = t + servo.return_delay
            if self.pace:
                due = max(due, self._wire_free) + wire_time(len(reply), baud)
                self._wire_free = due
            t = due  # the next servo answers after this one (a protocol-2.0 group read)
            reply = self._inject(reply)
            if reply is None:
                continue
            if self.faults.delay and self._rng.random() < self.faults.delay:
                self.stats.delayed += 1
                due += self.faults.delay_time
            self._queue.append((due, reply))
        self._queue.sort(key=lambda x: x[0])
        self._flush_due()

    def _inject(self, reply: bytes) -> bytes | None:
        f = self.faults
        if f.drop and self._rng.random() < f.drop:
            self.stats.dropped += 1
            return None
        if f.corrupt and self._rng.random() < f.corrupt:
            self.stats.corrupted += 1
            b = bytearray(reply)
            i = self._rng.randrange(4, len(b))
            b[i] ^= self._rng.randrange(1, 256)
            return bytes(b)
        return reply

    def _flush_due(self) -> None:
        while self._queue:
            due, reply = self._queue[0]
            left = due - time.monotonic()
            if left > 3e-4:
                return
            while left > 0:  # spin the last fraction of a millisecond
                left = due - time.monotonic()
            self._queue.pop(0)
            self._log("tx", reply, time.monotonic())  # logged first: a reader of the log
            self._write(reply)  # who got the reply finds it there
            self.stats.replies += 1

    def _write(self, data: bytes) -> None:
        """Put bytes on the line; when nobody has read the line for kilobytes they are
        lost, as on a bus without a listener (never block the servos)."""
        try:
            os.write(self._master, data)
        except BlockingIOError:
            self.stats.lost_bytes += len(data)

    def _log(self, tag: str, raw: bytes, now: float) -> None:
        if self.log is not None:
            self.log.write(f"{now - self._log_t0:.6f} {tag} {raw.hex(' ')}\n")
            self.log.flush()
