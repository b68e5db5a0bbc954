"""Find the servos on a port: at each baud, PING every ID 0..253 in protocol 1.0 and send
one broadcast PING in protocol 2.0, then read what answered.

Time is bounded: an absent ID costs one ping timeout (wire time + margin), so a
scan takes at most about ``len(bauds) · 254 · timeout`` (see :func:`scan_time_bound`);
protocol 2.0's broadcast PING costs the time 253 answers would take. On a
pseudo-terminal (the emulator: a process that a busy machine can hold back, not a
wire) each ID gets a longer margin and a second ping, so no servo is missed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

from armlab.hardware.servos.control_table import TABLES, ControlTable
from armlab.hardware.servos.servo_spec import RETURN_DELAY_UNIT
from armlab.hardware.servos.xseries import X_TABLES
from armlab.hardware.wire import protocol1 as p1
from armlab.hardware.wire import protocol2 as p2
from armlab.hardware.wire.bus import Bus, BusError, NoReply, is_pty, reply_timeout
from armlab.hardware.wire.protocol1 import wire_time

#: The usual Dynamixel rates (2 000 000 / (n + 1) for n = 1, 3, 4, 7, 9, 16, 34, 103, 207).
COMMON_BAUDS = (1_000_000, 500_000, 400_000, 250_000, 200_000, 117_647, 57_600, 19_200, 9_600)
DEFAULT_BAUDS = (1_000_000, 57_600)
ALL_IDS = range(0, p1.MAX_ID + 1)
#: s beyond wire time a ping waits on a serial adapter (a servo answers within its
#: return delay, 0.5 ms at the thesis's setting).
WIRE_SCAN_MARGIN = 0.010
#: s a ping waits on a pseudo-terminal (the emulator answers within microseconds unless the
#: machine holds it back; each ID is pinged twice there)
PTY_SCAN_MARGIN = 0.060


@dataclass(frozen=True)
class Found:
    """One servo that answered.

    Attributes:
        servo_id: its ID.
        model_number: address 0 (12 = AX-12A, 24 = RX-24F, 1020 = XM430-W350, ...).
        model: model name ("unknown" for other numbers).
        firmware: its firmware version (address 2; 6 on protocol 2.0).
        baud: bit/s it answered at.
        baud_value: its EEPROM baud value (address 4; 8 on protocol 2.0, another code).
        cw_limit, ccw_limit: raw angle limits (addresses 6, 8; both 0 = wheel mode; on
            protocol 2.0 Min and Max Position Limit, addresses 52 and 48).
        cw_limit_deg, ccw_limit_deg: the same as horn angles from the centre, degrees.
        error: the error byte of its reply.
        protocol: 1 or 2, the protocol it answered in.
    """

    servo_id: int
    model_number: int
    model: str
    firmware: int
    baud: float
    baud_value: int
    cw_limit: int
    ccw_limit: int
    cw_limit_deg: float
    ccw_limit_deg: float
    error: int
    protocol: int = 1


def ping_policy(port: str, margin: float | None = None) -> tuple[float, int]:
    """(margin s, pings per ID) for ``port``: ``margin`` (default :data:`WIRE_SCAN_MARGIN`)
    and one ping on a serial adapter; at least the bus's PTY margin and two pings on a
    pseudo-terminal."""
    if is_pty(port):
        return max(margin or 0.0, PTY_SCAN_MARGIN), 2
    return (WIRE_SCAN_MARGIN if margin is None else margin), 1


def broadcast_time(baud: float, n_ids: int, margin: float) -> float:
    """s a protocol-2.0 broadcast PING waits: ``n_ids`` answers of 14 bytes one after the
    other, each after the longest return delay."""
    return wire_time(10, baud) + n_ids * (wire_time(14, baud) + RETURN_DELAY_UNIT * 254) + \
        margin


def scan_time_bound(bauds: Sequence[float], ids: Iterable[int], margin: float,
                    tries: int = 1, protocols: Sequence[int] = (1, 2)) -> float:
    """Upper bound of a scan's time in s, if no servo answers (a PING is 6 + 6 bytes)."""
    n = len(list(ids))
    t = 0.0
    if 1 in protocols:
        t += sum(n * tries * reply_timeout(6, 6, b, 254, margin) for b in bauds)
    if 2 in protocols:
        t += sum(tries * broadcast_time(b, n, margin) for b in bauds)
    return t


def scan(port: str, bauds: Sequence[float] = DEFAULT_BAUDS, *, ids: Iterable[int] = ALL_IDS,
         margin: float = 0.010, protocols: Sequence[int] = (1, 2),
         progress: Callable[[float, int, int], None] | None = None) -> list[Found]:
    """PING ``ids`` at each baud on ``port`` in each protocol; describe every servo that
    answers (protocol 1.0 servos first, then 2.0, each by baud and ID).

    Args:
        port: serial device.
        bauds: bit/s to try, in order.
        ids: IDs to ping (default 0..253).
        margin: s of timeout beyond wire time for each ping (None: :func:`ping_policy`'s).
        protocols: which protocols to try (1: a PING per ID; 2: one broadcast PING).
        progress: called as ``progress(baud, servo_id, n_found)`` before each ping.

    Raises:
        BusError: the port cannot be opened or is lost.
    """
    ids = list(ids)
    found: list[Found] = []
    if not bauds:
        raise ValueError("bauds: give at least one baud rate")
    if not protocols or set(protocols) - {1, 2}:
        raise ValueError(f"protocols: 1 and/or 2, got {list(protocols)}")
    margin, tries = ping_policy(port, margin)
    if 1 in protocols:
        found += _scan_protocol1(port, bauds, ids, margin, tries, progress)
    if 2 in protocols:
        found += _scan_protocol2(port, bauds, ids, margin, tries, progress, len(found))
    return found


def _scan_protocol2(port: str, bauds: Sequence[float], ids: list[int], margin: float,
                    tries: int, progress: Callable[[float, int, int], None] | None,
                    n_before: int) -> list[Found]:
    found: list[Found] = []
    wanted = [i for i in ids if i <= p2.MAX_ID]
    if not wanted:
        return found
    with Bus(port, bauds[0], retries=2, timeout_margin=margin, protocol=2) as bus:
        for baud in bauds:
            bus.set_baud(baud)
            if progress is not None:
                progress(baud, p2.BROADCAST_ID, n_before + len(found))
            answers: dict[int, p2.StatusPacket] = {}
            for _ in range(tries):  # a pty: a second broadcast for answers held back
                answers.update(bus.broadcast_ping(wanted))
            found += [_describe2(bus, i, baud, answers[i]) for i in sorted(answers)]
    return found


def _describe2(bus: Bus, servo_id: int, baud: float, status: p2.StatusPacket) -> Found:
    model_number = int.from_bytes(status.params[:2], "little")
    table = X_TABLES.get(model_number)
    try:  # Baud Rate (8); Max and Min Position Limit (48, 52)
        baud_value = bus.read_bytes(servo_id, 8, 1)[0]
        limits = bus.read_bytes(servo_id, 48, 8)
        ccw, cw = (int.from_bytes(limits[k:k + 4], "little") for k in (0, 4))
    except BusError:  # answers PING but not READ (status return level 0)
        baud_value, cw, ccw = 0, 0, 0
    return Found(
        servo_id=servo_id, model_number=model_number,
        model=table.name if table is not None else "unknown", firmware=status.params[2],
        baud=float(baud), baud_value=baud_value, cw_limit=cw, ccw_limit=ccw,
        cw_limit_deg=_degrees(table, cw), ccw_limit_deg=_degrees(table, ccw),
        error=status.error.byte, protocol=2)


def _degrees(table: ControlTable | None, raw: int) -> float:
    """A raw position limit as a horn angle from the centre, degrees (NaN for a model the
    lab does not know)."""
    return float("nan") if table is None else math.degrees(table.spec.raw_to_position(raw))


def _scan_protocol1(port: str, bauds: Sequence[float], ids: list[int], margin: float,
                    tries: int, progress: Callable[[float, int, int], None] | None
                    ) -> list[Found]:
    found: list[Found] = []
    with Bus(port, bauds[0], retries=2, timeout_margin=margin) as bus:
        for baud in bauds:
            bus.set_baud(baud)
            bus.late_ids.clear()
            here: list[Found] = []
            missed = []
            for servo_id in ids:
                if progress is not None:
                    progress(baud, servo_id, len(found) + len(here))
                try:
                    status = bus.ping(servo_id, tries=tries)
                except NoReply:
                    missed.append(servo_id)
                    continue
                here.append(_describe(bus, servo_id, baud, status))
            # a servo whose answer came late (the machine held the reply back) answered
            # all the same: ask it again, with the bus's own retries
            if missed:
                bus.collect_late(tries * margin + 0.1)  # the last IDs' answers may be coming
            for servo_id in sorted(bus.late_ids.intersection(missed)):
                try:
                    status = bus.ping(servo_id)
                except NoReply:
                    continue
                here.append(_describe(bus, servo_id, baud, status))
            found += sorted(here, key=lambda f: f.servo_id)
    return found


def _describe(bus: Bus, servo_id: int, baud: float, status: p1.StatusPacket) -> Found:
    try:
        head = bus.read_bytes(servo_id, 0, 10)
    except BusError:
        head = bytes(10)  # answers PING but not READ (status return level 0 still reads)
    model_number = int.from_bytes(head[0:2], "little")
    table = TABLES.get(model_number)
    cw = int.from_bytes(head[6:8], "little")
    ccw = int.from_bytes(head[8:10], "little")
    return Found(
        servo_id=servo_id, model_number=model_number,
        model=table.name if table is not None else "unknown",
        firmware=head[2], baud=float(baud),
        baud_value=head[4], cw_limit=cw, ccw_limit=ccw, cw_limit_deg=_degrees(table, cw),
        ccw_limit_deg=_degrees(table, ccw), error=int(status.error),
    )
