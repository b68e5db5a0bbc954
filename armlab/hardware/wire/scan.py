"""Find the servos on a port: at each baud, PING every ID 0..253 in protocol 1.0's frame
(which Feetech STS servos answer too) and send one broadcast PING in protocol 2.0, then
read what answered; each servo's model number says its family
(:mod:`armlab.hardware.families`).

Time is bounded: an absent ID costs one ping timeout (wire time + margin), so a
scan takes at most about ``len(bauds) · 254 · timeout`` (see :func:`scan_time_bound`);
protocol 2.0's broadcast PING costs the time 253 answers would take. An answer that
comes after its ping's timeout (a busy machine held the emulator back, or an adapter
its reply) arrives while later IDs are pinged, or while the scan listens after the
last one; the bus notes its ID (:attr:`~armlab.hardware.wire.bus.Bus.late_ids`) and the
scan asks that servo again with the bus's own, longer, timeout. So a pseudo-terminal
(the emulator, which answers within microseconds unless held back) gets a short ping
and a long listen at the end, and no servo is missed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import ServoFamily
from armlab.hardware.servos.registry import FAMILIES, family
from armlab.hardware.servos.servo_spec import RETURN_DELAY_UNIT, wire_time
from armlab.hardware.wire.bus import Bus
from armlab.hardware.wire.errors import BusError, NoReply
from armlab.hardware.wire.port import PTY_MARGIN, is_pty, reply_timeout

#: The usual Dynamixel rates (2 000 000 / (n + 1) for n = 1, 3, 4, 7, 9, 16, 34, 103, 207).
COMMON_BAUDS = (1_000_000, 500_000, 400_000, 250_000, 200_000, 117_647, 57_600, 19_200, 9_600)
DEFAULT_BAUDS = (1_000_000, 57_600)


def default_protocols() -> tuple[int | str, ...]:
    """Every family's protocol tag: what a scan tries by default."""
    return tuple(f.protocol for f in FAMILIES)


def all_ids() -> range:
    """Every ID any family's servo may have: what a scan pings by default (0..253)."""
    return range(0, max(f.codec.MAX_ID for f in FAMILIES) + 1)
#: s beyond wire time a ping waits on a serial adapter (a servo answers within its
#: return delay, 0.5 ms at the thesis's setting).
WIRE_SCAN_MARGIN = 0.010
#: s a ping waits on a pseudo-terminal (the emulator answers within microseconds; an
#: answer the machine held back longer is caught late and asked again)
PTY_SCAN_MARGIN = 0.005
#: s the scan listens after a baud's last ping for answers that came late: on a serial
#: adapter the ping's margin and WIRE_LATE_S more, on a pseudo-terminal PTY_LATE_S
WIRE_LATE_S = 0.1
PTY_LATE_S = 0.5


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
        protocol: 1, 2 or "sts": the protocol tag of its family.
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
    protocol: int | str = 1


@dataclass(frozen=True)
class ScanPolicy:
    """How long a scan waits on one port (see :func:`scan_policy`).

    Attributes:
        ping_margin: s beyond wire time each ping waits.
        late_s: s the scan listens after a baud's last ping for answers that came late.
        answer_margin: s beyond wire time a broadcast PING, and each look at a servo
            that answered (its description, a second ask when its answer came late), waits.
        broadcasts: broadcast PINGs sent at each baud.
    """

    ping_margin: float
    late_s: float
    answer_margin: float
    broadcasts: int


def scan_policy(port: str, margin: float | None = None) -> ScanPolicy:
    """The waits of a scan on ``port``. On a serial adapter: ``margin`` (default
    :data:`WIRE_SCAN_MARGIN`) for every ping and answer, a listen of that and
    :data:`WIRE_LATE_S` more, one broadcast. On a pseudo-terminal: at least
    :data:`PTY_SCAN_MARGIN` a ping, a listen of :data:`PTY_LATE_S`, at least the bus's
    own margin (:data:`~armlab.hardware.wire.port.PTY_MARGIN`) for answers, and a second
    broadcast for answers the machine held back."""
    if is_pty(port):
        ping = max(margin or 0.0, PTY_SCAN_MARGIN)
        return ScanPolicy(ping, PTY_LATE_S, max(ping, PTY_MARGIN), 2)
    ping = WIRE_SCAN_MARGIN if margin is None else margin
    return ScanPolicy(ping, ping + WIRE_LATE_S, ping, 1)


def broadcast_time(baud: float, n_ids: int, margin: float) -> float:
    """s a protocol-2.0 broadcast PING waits: ``n_ids`` answers of 14 bytes one after the
    other, each after the longest return delay."""
    return wire_time(10, baud) + n_ids * (wire_time(14, baud) + RETURN_DELAY_UNIT * 254) + \
        margin


def scan_time_bound(port: str, bauds: Sequence[float], ids: Iterable[int],
                    margin: float | None = None,
                    protocols: Sequence[int | str] | None = None) -> float:
    """Upper bound of a scan's time in s on ``port``, if no servo answers (a PING is 6 + 6
    bytes; one PING per ID serves every family pinged that way; ``margin`` as
    :func:`scan` takes it; ``protocols`` None: every family's)."""
    n = len(list(ids))
    policy = scan_policy(port, margin)
    fams = [family(p) for p in (default_protocols() if protocols is None else protocols)]
    t = 0.0
    if any(not f.broadcast_ping for f in fams):
        t += sum(n * reply_timeout(6, 6, b, 254, policy.ping_margin) + policy.late_s
                 for b in bauds)
    n_broadcast = sum(f.broadcast_ping for f in fams)  # families pinged by broadcast
    t += n_broadcast * policy.broadcasts * sum(broadcast_time(b, n, policy.answer_margin)
                                               for b in bauds)
    return t


def scan(port: str, bauds: Sequence[float] = DEFAULT_BAUDS, *, ids: Iterable[int] | None = None,
         margin: float | None = None, protocols: Sequence[int | str] | None = None,
         progress: Callable[[float, int, int], None] | None = None) -> list[Found]:
    """PING ``ids`` at each baud on ``port`` in each protocol; describe every servo that
    answers (servos found by a PING per ID first, then by a broadcast PING, each by baud
    and ID).

    Dynamixel protocol 1.0 and Feetech STS share one PING (the same frame), so one PING
    per ID finds both; the model number each answers with (read where each family keeps
    it, :mod:`armlab.hardware.families`) says which family it is.

    Args:
        port: serial device.
        bauds: bit/s to try, in order.
        ids: IDs to ping (None: :func:`all_ids`, 0..253).
        margin: s of timeout beyond wire time for each ping (None: :func:`scan_policy`'s).
        protocols: which families to try, by protocol tag (1 and "sts": a PING per ID;
            2: one broadcast PING; None: every family's, :func:`default_protocols`).
        progress: called as ``progress(baud, servo_id, n_found)`` before each ping.

    Raises:
        BusError: the port cannot be opened or is lost.
    """
    ids = list(all_ids() if ids is None else ids)
    protocols = default_protocols() if protocols is None else protocols
    found: list[Found] = []
    if not bauds:
        raise ValueError("bauds: give at least one baud rate")
    try:
        fams = [family(p) for p in protocols]
    except ValueError:
        fams = []
    if not fams:
        raise ValueError(f"protocols: some of {', '.join(map(repr, default_protocols()))}, "
                         f"got {list(protocols)}")
    policy = scan_policy(port, margin)
    each_id = [f for f in fams if not f.broadcast_ping]
    if each_id:
        found += _scan_each_id(port, bauds, ids, policy, progress, each_id)
    for fam in fams:
        if fam.broadcast_ping:
            found += _scan_broadcast(port, bauds, ids, policy, progress, len(found), fam)
    return found


def _scan_broadcast(port: str, bauds: Sequence[float], ids: list[int], policy: ScanPolicy,
                    progress: Callable[[float, int, int], None] | None,
                    n_before: int, fam: ServoFamily) -> list[Found]:
    """The servos of a family whose servos all answer one broadcast PING (protocol 2.0)."""
    found: list[Found] = []
    wanted = [i for i in ids if i <= fam.codec.MAX_ID]
    if not wanted:
        return found
    with Bus(port, bauds[0], retries=2, timeout_margin=policy.answer_margin,
             protocol=fam) as bus:
        for baud in bauds:
            bus.set_baud(baud)
            if progress is not None:
                progress(baud, fam.codec.BROADCAST_ID, n_before + len(found))
            answers: dict[int, Any] = {}
            for _ in range(policy.broadcasts):
                answers.update(bus.broadcast_ping(wanted))
            found += [_describe(bus, fam, i, baud, answers[i].error,
                                model=int.from_bytes(answers[i].params[:2], "little"),
                                firmware=answers[i].params[2])
                      for i in sorted(answers)]
    return found


def _degrees(table: ControlTable | None, raw: int) -> float:
    """A raw position limit as a horn angle from the centre, degrees (NaN for a model the
    lab does not know)."""
    return float("nan") if table is None else math.degrees(table.spec.raw_to_position(raw))


def _scan_each_id(port: str, bauds: Sequence[float], ids: list[int], policy: ScanPolicy,
                  progress: Callable[[float, int, int], None] | None,
                  fams: list[ServoFamily]) -> list[Found]:
    """The servos of families that are pinged one ID at a time (they share one frame:
    Dynamixel 1.0 and Feetech STS), each told apart by its model number."""
    found: list[Found] = []
    ids = [i for i in ids if i <= fams[0].codec.MAX_ID]  # STS: 0..252
    with Bus(port, bauds[0], retries=2, timeout_margin=policy.answer_margin,
             protocol=fams[0]) as bus:
        for baud in bauds:
            bus.set_baud(baud)
            bus.late_ids.clear()
            here: list[Found] = []
            missed = []
            for servo_id in ids:
                if progress is not None:
                    progress(baud, servo_id, len(found) + len(here))
                try:
                    status = bus.ping(servo_id, tries=1, margin=policy.ping_margin)
                except NoReply:
                    missed.append(servo_id)
                    continue
                here.append(_identify(bus, fams, servo_id, baud, int(status.error)))
            # a servo whose answer came late (the machine held the reply back) answered
            # all the same: ask it again, with the bus's own margin and retries
            if missed:
                bus.collect_late(policy.late_s)  # the last IDs' answers may be coming
            for servo_id in sorted(bus.late_ids.intersection(missed)):
                try:
                    status = bus.ping(servo_id)
                except NoReply:
                    continue
                here.append(_identify(bus, fams, servo_id, baud, int(status.error)))
            found += sorted(here, key=lambda f: f.servo_id)
    return found


def _head_span(fam: ServoFamily) -> int:
    """Bytes from address 0 that hold a family's model number, firmware, baud and limits."""
    table = fam.default_table
    items = [table.item(n) for n in ("model_number", fam.firmware_item, "baud_rate",
                                     *fam.limit_items)]
    return max(i.address + i.size for i in items)


def _identify(bus: Bus, fams: list[ServoFamily], servo_id: int, baud: float,
              error: int) -> Found:
    """Which of ``fams`` a servo that answered a PING is (the first whose model number,
    read where that family keeps it, is one of its models), described; the first family's
    "unknown" when none knows it."""
    span = max(_head_span(f) for f in fams)
    try:
        head = bus.read_bytes(servo_id, 0, span)
    except BusError:
        head = bytes(span)  # answers PING but not READ (status return level 0 still reads)
    for fam in fams:
        at = fam.model_address
        if int.from_bytes(head[at:at + 2], "little") in fam.tables:
            return _describe(bus, fam, servo_id, baud, error, head=head)
    return _describe(bus, fams[0], servo_id, baud, error, head=head)


def _describe(bus: Bus, fam: ServoFamily, servo_id: int, baud: float, error: Any, *,
              head: bytes | None = None, model: int | None = None,
              firmware: int | None = None) -> Found:
    """A servo of family ``fam`` as a :class:`Found`, from ``head`` (its table from address
    0) or read now (READs that fail leave the baud value and limits 0); ``model`` and
    ``firmware`` when its PING answered them (protocol 2.0)."""
    layout = fam.default_table
    at = fam.model_address
    if head is None:
        try:
            head = bus.read_bytes(servo_id, 0, _head_span(fam))
        except BusError:  # answers PING but not READ (status return level 0)
            head = None
    number = model if model is not None else \
        (int.from_bytes(head[at:at + 2], "little") if head is not None else 0)
    table = fam.tables.get(number)

    def raw(name: str) -> int:
        if head is None:
            return 0
        item = layout.item(name)
        return layout.decode(name, head[item.address:item.address + item.size])

    if firmware is None:
        firmware = raw(fam.firmware_item)
    cw, ccw = raw(fam.limit_items[0]), raw(fam.limit_items[1])
    return Found(
        servo_id=servo_id, model_number=number,
        model=table.name if table is not None else "unknown", firmware=firmware,
        baud=float(baud), baud_value=raw("baud_rate"), cw_limit=cw, ccw_limit=ccw,
        cw_limit_deg=_degrees(table, cw), ccw_limit_deg=_degrees(table, ccw),
        error=error.byte if hasattr(error, "byte") else int(error), protocol=fam.protocol)
