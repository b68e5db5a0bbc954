"""A servo bus over pyserial (Dynamixel protocol 1.0 or 2.0, Feetech STS): one transaction
at a time, bounded retries.

Thesis §3.5: the controller sends an instruction packet, then waits for the
status packet before the next one (half duplex). :class:`Bus` does that for
any number of threads (a lock around each transaction), with a timeout
computed from the bytes on the wire, the baud and the servo's return delay
instead of the official SDK's fixed ~34 ms, a bounded number of retries
(counted in :attr:`Bus.stats`), optional echo cancellation for half-duplex
TTL adapters that hear their own transmission, and optional RS-485 mode for
native UARTs (not applicable on USB adapters and ptys, which is fine).

Every failure a person can cause ends in one :class:`BusError` line that says
what to do: port missing, permission denied (dialout group), port busy, no
reply (power, baud, ID, protocol), wrong model, link lost.

One bus speaks one servo family's protocol (``Bus(port, protocol=2)`` for X-series
servos, ``protocol="sts"`` for Feetech's; :mod:`armlab.hardware.families` says what each
family's packets and tables are): the packets differ, the timing and the named access
through the servo's control table do not. Protocol 2.0 and STS add reads of many servos
in one request (:meth:`Bus.sync_read`); protocol 2.0 BULK_READ and REBOOT.

Its parts: the port it opens and how long to wait on it (:mod:`~armlab.hardware.wire.port`),
what it raises (:mod:`~armlab.hardware.wire.errors`), its group reads
(:mod:`~armlab.hardware.wire.group_reads`) and its items by name
(:mod:`~armlab.hardware.wire.named_items`); this module holds the transactions and the
instructions.
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import select
import termios
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import serial

from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import Codec, ServoFamily, Status
from armlab.hardware.servos.registry import FAMILIES, family
from armlab.hardware.servos.servo_spec import RETURN_DELAY_UNIT, wire_time
from armlab.hardware.wire.errors import BusError, LinkLost, NoReply, PortError
from armlab.hardware.wire.group_reads import GroupReads
from armlab.hardware.wire.named_items import NamedItems
from armlab.hardware.wire.port import (
    LAST_REPLY_POLL_S,
    PTY_MARGIN,
    PTY_RETRIES,
    TIOCGRS485,
    WIRE_MARGIN,
    WIRE_RETRIES,
    ftdi_latency_check,
    ftdi_latency_ms,
    is_pty,
    open_port,
    reply_timeout,
)

log = logging.getLogger("armlab.bus")


@dataclass
class BusStats:
    """Counters since the bus was opened.

    Attributes:
        transactions: instruction packets sent.
        replies: valid status packets received.
        retries: packets sent again after a timeout or a broken reply.
        timeouts: waits that ended with no valid reply.
        corrupt: replies dropped for a bad checksum or wrong length/ID.
        failures: transactions that ran out of retries.
        bytes_out, bytes_in: bytes written and read.
    """

    transactions: int = 0
    replies: int = 0
    retries: int = 0
    timeouts: int = 0
    corrupt: int = 0
    failures: int = 0
    bytes_out: int = 0
    bytes_in: int = 0


class Bus(GroupReads, NamedItems):
    """Protocol 1.0 or 2.0 on one serial port.

    Args:
        port: device path (/dev/ttyUSB0, /dev/pts/N of the emulator).
        baud: bit/s (1 000 000 in the thesis).
        retries: extra attempts after a timeout or a broken reply (bounded; None: 2 on a
            serial adapter, 8 on a pseudo-terminal).
        timeout_margin: s added to the computed wire time of each reply (None: 20 ms
            on a serial adapter, 100 ms on a pseudo-terminal, whose "servos" are a process
            on this computer that answers when the scheduler lets it); raised to the
            adapter's FTDI latency timer + 5 ms where that is longer (a 16 ms timer
            would otherwise time out every reply).
        echo: the adapter echoes what it sends (half-duplex TTL with TX and RX tied).
        rs485: switch a native UART into kernel RS-485 mode (not applicable on a
            USB adapter or a pty; noted in :attr:`notes`, not an error).
        table: control table assumed for servos not yet identified (None: the family's
            default, the RX-24F's on protocol 1.0, the XM430-W350's on 2.0, the
            STS3215's on STS).
        exclusive: lock the port against other programs.
        protocol: 1 (AX, RX, MX servos), 2 (X-series) or "sts" (Feetech STS), or a
            :class:`~armlab.hardware.families.ServoFamily`.

    Attributes:
        stats: :class:`BusStats` counters.
        notes: one-line remarks from opening (latency timer, RS-485 not applicable).
        errors: last error reported by each servo ID (protocol 1.0 and STS: its error
            bits; 2.0: its :class:`~armlab.hardware.families.xseries.packets.StatusError`).
        family: the :class:`~armlab.hardware.families.ServoFamily` it speaks.
        late_ids: IDs whose status packet came while the bus waited for another servo's
            (a late reply: the scan pings them again).
        tables: control table of each identified servo ID.
        status_return_level: what each ID answers, as written to it (its family's
            ``replies_all_level`` and above: everything; below: PING and READ only).
        return_delay: each ID's return delay setting (2 µs units).
    """

    def __init__(self, port: str, baud: float = 1_000_000, *, retries: int | None = None,
                 timeout_margin: float | None = None, echo: bool = False, rs485: bool = False,
                 table: ControlTable | None = None, exclusive: bool = True,
                 protocol: int | str | ServoFamily = 1):
        try:
            fam = family(protocol)
        except ValueError:
            raise ValueError("protocol: 1 (AX, RX, MX servos), 2 (X-series) or \"sts\" "
                             f"(Feetech STS), got {protocol!r}") from None
        if retries is None:
            retries = PTY_RETRIES if is_pty(port) else WIRE_RETRIES
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        if timeout_margin is None:
            timeout_margin = PTY_MARGIN if is_pty(port) else WIRE_MARGIN
        if not timeout_margin > 0:
            raise ValueError(f"timeout_margin must be > 0 s, got {timeout_margin}")
        self.port = port
        self.family = fam
        self.protocol = fam.protocol
        self._p = fam.codec
        if table is None:
            table = fam.default_table
        self.retries = int(retries)
        self.timeout_margin = float(timeout_margin)
        self.echo = bool(echo)
        #: echoes of the packet last sent still to come: one for each time it was sent
        #: (a retry's echo may arrive after the one before's, both after the retry's
        #: flush, when the far end is slow), until another packet is sent
        self._echo_owed = 0
        self._last_sent = b""
        self.table = table
        self.stats = BusStats()
        self.notes: list[str] = []
        self.errors: dict[int, Any] = {}  # each family's own flags (Status.error)
        self.late_ids: set[int] = set()
        self.tables: dict[int, ControlTable] = {}
        self.status_return_level: dict[int, int] = {}
        self.return_delay: dict[int, int] = {}
        self._lock = threading.Lock()
        self._baud = float(baud)
        self._tx_free = 0.0  # monotonic time the UART will have sent all queued bytes
        self._ser = open_port(port, baud, exclusive=exclusive)
        self._fd = self._ser.fileno()
        if rs485:
            self._enable_rs485()
        latency = ftdi_latency_ms(port)
        if latency is not None:
            self.timeout_margin = max(self.timeout_margin, latency / 1000.0 + 0.005)
        note = ftdi_latency_check(port)
        if note:
            self.notes.append(note)
            log.warning(note)

    # -- port ---------------------------------------------------------------

    @property
    def baud(self) -> float:
        return self._baud

    def set_baud(self, baud: float) -> None:
        """Talk at another rate from now on (after the servos were told to switch)."""
        with self._lock:
            try:
                self._ser.baudrate = int(round(baud))
            except (serial.SerialException, OSError, ValueError) as exc:
                raise BusError(f"cannot set {self.port} to {baud:g} bps: {exc}") from None
            self._baud = float(baud)

    def close(self) -> None:
        """Release the port (idempotent)."""
        with self._lock:
            if self._ser.is_open:
                self._ser.close()

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _enable_rs485(self) -> None:
        try:
            fcntl.ioctl(self._fd, TIOCGRS485, bytearray(32))
        except OSError as exc:
            if exc.errno == errno.ENOTTY:
                note = f"{self.port}: RS-485 mode not applicable (USB adapter or pty)"
                self.notes.append(note)
                log.info(note)
                return
            raise PortError(f"cannot query RS-485 mode on {self.port}: {exc}") from None
        import serial.rs485

        self._ser.rs485_mode = serial.rs485.RS485Settings(
            rts_level_for_tx=True, rts_level_for_rx=False
        )
        self.notes.append(f"{self.port}: kernel RS-485 mode on")

    # -- transactions -------------------------------------------------------

    def status_length(self, data_bytes: int = 0) -> int:
        """Bytes of a status packet carrying ``data_bytes`` of data, in this bus's protocol
        (before protocol 2.0's byte stuffing)."""
        return self.family.status_length(data_bytes)

    @property
    def broadcast_id(self) -> int:
        """The ID every servo listens to (0xFE in every family; no servo answers it)."""
        return self._p.BROADCAST_ID

    def _id_of(self, packet: bytes) -> int:
        """The ID an encoded packet is sent to (or comes from)."""
        return self.family.id_of(packet)

    def transact(self, packet: bytes, *, reply: bool, reply_length: int | None = None,
                 tries: int | None = None, margin: float | None = None
                 ) -> Status | None:
        """Send one instruction packet; return its status packet (None when none is due).

        ``reply_length``: bytes of the expected status packet (default: one without
        data). Retries up to ``tries - 1`` more times (default ``retries + 1`` tries in
        all) on a timeout or a broken reply; :class:`NoReply` when all fail.
        """
        servo_id = self._id_of(packet)
        if reply_length is None:
            reply_length = self.status_length()
        tries = self.retries + 1 if tries is None else max(1, int(tries))
        delay = self.return_delay.get(servo_id, 254)
        want = {servo_id: reply_length - self.status_length()}
        with self._lock:
            bytes_in = self.stats.bytes_in
            for attempt in range(tries):
                if attempt:
                    self.stats.retries += 1
                backlog = self._send(packet)
                timeout = backlog + reply_timeout(
                    len(packet), reply_length, self._baud, delay,
                    self.timeout_margin if margin is None else margin)
                if not reply:
                    if self.echo:
                        self._receive(packet, {}, timeout=timeout, echo_only=True)
                    return None
                statuses = self._receive(packet, want, timeout=timeout)
                if statuses:
                    return statuses[servo_id]
            self.stats.failures += 1
            heard = self.stats.bytes_in - bytes_in - (tries * len(packet) if self.echo else 0)
        raise self._no_reply([servo_id], tries, heard=heard)

    def _no_reply(self, ids: list[int], tries: int, what: str = "", *,
                  heard: int = 0) -> NoReply:
        """The error for ``ids`` that never answered; ``heard``: bytes that came back all
        the same to a one-servo request (another servo's answers, or a wrong baud's
        noise), said when any did."""
        who = f"servo {ids[0]}" if len(ids) == 1 else \
            f"servos {', '.join(str(i) for i in ids)}"
        came = f" ({heard} bytes came back, none of them its reply)" if heard > 0 else ""
        error = NoReply(
            f"no reply{what} from {who} at {self._baud:.0f} bps on {self.port} "
            f"after {tries} tries{came}: check the servos' power (a U2D2 supplies none), "
            f"the baud (armlab scan --port {self.port}), the ID, and that they speak "
            f"protocol {self.family.label}"
        )
        error.ids = tuple(ids)
        return error

    def _send(self, packet: bytes) -> float:
        """Write a packet; return the s of earlier packets still on the wire before it
        (a reply can only come after the UART has sent everything queued)."""
        if not self._ser.is_open:  # its fd's number may belong to another file by now
            raise self._lost("the port is closed")
        try:  # the syscalls themselves, without pyserial's wait for a writable port after
            termios.tcflush(self._fd, termios.TCIFLUSH)
            try:
                sent = os.write(self._fd, packet)
            except BlockingIOError:
                sent = 0
            if sent < len(packet):  # the output buffer is full: pyserial waits for room
                self._ser.write(packet[sent:])
        except (serial.SerialException, OSError, termios.error) as exc:
            raise self._lost(exc) from None
        now = time.monotonic()
        backlog = max(0.0, self._tx_free - now)
        self._tx_free = now + backlog + wire_time(len(packet), self._baud)
        self.stats.transactions += 1
        self.stats.bytes_out += len(packet)
        if self.echo:
            self._echo_owed = self._echo_owed + 1 if packet == self._last_sent else 1
            self._last_sent = packet
        return backlog

    def _lost(self, exc: BaseException | str) -> LinkLost:
        return LinkLost(
            f"lost the serial link on {self.port} ({exc}): is the adapter unplugged, "
            "the servo power off, or the emulator stopped?"
        )

    def _receive(self, request: bytes, want: dict[int, int], *, timeout: float,
                 echo_only: bool = False, protocol: Codec | None = None
                 ) -> dict[int, Status]:
        """The status packets of the servos in ``want`` (ID -> bytes of data each answers
        with) that arrive within ``timeout`` s; all of them, or those that came when the
        wait ended (a timeout, or a broken reply after which nothing more is pending).

        ``protocol``: the packet module (a family's codec) to parse with, when not the
        bus's own (a probe of another protocol: its answers are not kept in
        :attr:`errors`)."""
        own = protocol is None or protocol is self._p
        p = self._p if protocol is None else protocol
        parser = p.PacketParser()
        deadline = time.monotonic() + timeout
        if self.echo:
            deadline += wire_time(len(request), self._baud)
        got: dict[int, Status] = {}
        while True:
            # past the deadline still look once (timeout 0): a client the OS paused
            # must not miss a reply that came in time
            last = len(want) - len(got) == 1 and not self._echo_owed
            chunk = self._read_chunk(max(0.0, deadline - time.monotonic()),
                                     poll=LAST_REPLY_POLL_S if last else 0.0)
            if chunk is None:
                break
            for raw in parser.feed(chunk):
                if self._echo_owed and raw == request:  # our own packet, come back
                    self._echo_owed -= 1
                    if echo_only and not self._echo_owed:
                        return got
                    continue
                try:
                    status = p.decode_status(raw, checked=True)
                except p.ProtocolError:  # an instruction: not ours
                    self.stats.corrupt += 1
                    continue
                if want.get(status.servo_id) != len(status.params) or status.servo_id in got:
                    log.debug("stray packet %s waiting for %s", raw.hex(" "), request.hex(" "))
                    self.stats.corrupt += 1
                    self.late_ids.add(status.servo_id)
                    continue
                self.stats.replies += 1
                if own:
                    self.errors[status.servo_id] = status.error
                got[status.servo_id] = status
                if len(got) == len(want):
                    return got
            if parser.broken and not parser.pending:
                break  # a broken reply: retry now rather than wait out the timeout
        self.stats.timeouts += 1
        self.stats.corrupt += parser.broken
        if not echo_only:
            log.debug("no valid reply to %s within %.1f ms", request.hex(" "), timeout * 1e3)
        return got

    def _read_chunk(self, timeout: float, *, poll: float = 0.0) -> bytes | None:
        """The bytes that arrive within ``timeout`` s (None: none did), polled for the first
        ``poll`` s (``select`` without sleeping), then waited for; :class:`LinkLost` when
        the device is gone."""
        now = time.monotonic()
        deadline, poll_until = now + timeout, now + min(poll, timeout)
        while True:
            now = time.monotonic()
            polling = now < poll_until
            try:
                ready, _, _ = select.select([self._fd], [], [],
                                            0.0 if polling else max(0.0, deadline - now))
                if not ready:
                    if polling:
                        continue
                    return None
                chunk = os.read(self._fd, 512)
            except InterruptedError:
                continue
            except OSError as exc:
                raise self._lost(exc) from None
            if not chunk:
                raise self._lost("device returned no data")
            self.stats.bytes_in += len(chunk)
            return chunk

    def collect_late(self, seconds: float) -> set[int]:
        """Listen ``seconds`` for status packets no request waits for (replies the machine
        held back past their timeout); their IDs join :attr:`late_ids`, which is returned."""
        parser = self._p.PacketParser()
        deadline = time.monotonic() + seconds
        with self._lock:
            while (left := deadline - time.monotonic()) > 0:
                chunk = self._read_chunk(left)
                if chunk is None:
                    break
                for raw in parser.feed(chunk):
                    self.late_ids.add(self._id_of(raw))
        return self.late_ids

    # -- instructions -------------------------------------------------------

    def ping(self, servo_id: int, *, tries: int | None = None,
             margin: float | None = None) -> Status:
        """PING one servo (answers at every status return level; on protocol 2.0 with its
        model number and firmware version as data)."""
        status = self.transact(self._p.ping(servo_id), reply=True, tries=tries, margin=margin,
                               reply_length=self.status_length(self.family.ping_data))
        assert status is not None
        return status

    def broadcast_ping(self, ids: list[int] | range | None = None, *,
                       margin: float | None = None) -> dict[int, Status]:
        """PING to broadcast (a family whose servos answer it one after the other:
        protocol 2.0's): every servo answers.

        Waits as long as answers from all of ``ids`` (default every ID, 0..252) would
        take, plus ``margin`` (default the bus's); returns the ones that came, by ID."""
        if not self.family.broadcast_ping:
            raise ValueError(f"a broadcast PING is answered on protocol 2.0 only (on "
                             f"{self.family.label} every servo would answer at once): "
                             "ping each ID")
        p, data = self._p, self.family.ping_data
        ids = list(range(p.MAX_ID + 1) if ids is None else ids)
        packet = p.ping(p.BROADCAST_ID)
        each = wire_time(self.status_length(data), self._baud) + RETURN_DELAY_UNIT * 254
        with self._lock:
            backlog = self._send(packet)
            timeout = backlog + wire_time(len(packet), self._baud) + len(ids) * each + \
                (self.timeout_margin if margin is None else margin)
            return self._receive(packet, {i: data for i in ids}, timeout=timeout)

    def ping_other_protocol(self, ids: Sequence[int]) -> tuple[int | str, list[int]]:
        """Which servos answer a PING in a protocol this bus does *not* speak, at its baud.

        How a backend tells "nothing answers here" from "servos of another family answer
        here" (a joint map naming the wrong servo model). Each other family whose PING is
        another packet than this bus's is asked in turn (one whose PING is the same bytes,
        Feetech's beside protocol 1.0, cannot be told apart): with one broadcast PING
        where every servo answers it one after the other (protocol 2.0), else a PING to
        each of ``ids``. Only PINGs are sent: nothing is written to any servo. On a
        pseudo-terminal the PINGs go twice (the machine may hold answers back). A lost
        link answers nothing.

        Returns:
            (the first other family's protocol whose servos answered, or the last asked;
            the IDs that answered in it, sorted; empty when none did).
        """
        mine = self._p.ping(1)
        others = [f for f in FAMILIES if f is not self.family and f.codec.ping(1) != mine]
        found: tuple[int | str, list[int]] = (self.protocol, [])
        for other in others:
            heard = self._pings_heard(other, ids)
            found = (other.protocol, heard)
            if heard:
                break
        return found

    def _pings_heard(self, other: ServoFamily, ids: Sequence[int]) -> list[int]:
        """The IDs that answer ``other``'s PING (see :meth:`ping_other_protocol`)."""
        p, data = other.codec, other.ping_data
        if other.broadcast_ping:
            asks = [(p.ping(p.BROADCAST_ID), {i: data for i in range(p.MAX_ID + 1)})]
        else:
            asks = [(p.ping(i), {i: data}) for i in ids if 0 <= i <= p.MAX_ID]
        tries = 2 if is_pty(self.port) else 1
        heard: set[int] = set()
        try:
            with self._lock:
                for _ in range(tries):
                    for packet, want in asks:
                        if set(want) <= heard:
                            continue
                        backlog = self._send(packet)
                        # every servo that answers a broadcast waits for the one before it
                        replies = len(want) * other.status_length(data)
                        timeout = backlog + reply_timeout(len(packet), replies, self._baud,
                                                          254 * len(want), self.timeout_margin)
                        heard |= set(self._receive(packet, want, timeout=timeout, protocol=p))
        except BusError:
            pass
        return sorted(heard)

    def read_bytes(self, servo_id: int, address: int, length: int) -> bytes:
        """READ ``length`` bytes at ``address`` of one servo (its error kept in ``errors``)."""
        if servo_id == self._p.BROADCAST_ID:
            raise ValueError("servo_id: READ cannot be broadcast (nobody would answer)")
        status = self.transact(self._p.read(servo_id, address, length), reply=True,
                               reply_length=self.status_length(length))
        assert status is not None
        return status.params

    def _answers_writes(self, servo_id: int) -> bool:
        level = self.family.replies_all_level  # a servo not configured yet answers all
        return (servo_id != self._p.BROADCAST_ID
                and self.status_return_level.get(servo_id, level) >= level)

    def write_bytes(self, servo_id: int, address: int, data: bytes
                    ) -> Status | None:
        """WRITE ``data`` at ``address``; raise the family's ServoError when the servo
        refuses it (its codec's ``write_refusal``: protocol 1.0's range, instruction or
        checksum bits, or the angle limit on a goal; 2.0's error number, where a hardware
        alert alone is no refusal; never an STS servo's bits, which describe its state).
        What a servo reports stays in :attr:`errors` either way."""
        status = self.transact(self._p.write(servo_id, address, data),
                               reply=self._answers_writes(servo_id))
        self._check_refused(servo_id, address, data, status)
        return status

    def _check_refused(self, servo_id: int, address: int, data: bytes,
                       status: Status | None) -> None:
        """Raise the family's ServoError when ``status``, the answer to a write of ``data``
        at ``address``, says the servo refused it (see :meth:`write_bytes`)."""
        if status is not None:
            refused = self._p.write_refusal(servo_id, status, address=address,
                                            length=len(data))
            if refused is not None:
                raise refused

    def write_unanswered(self, servo_id: int, address: int, data: bytes) -> None:
        """WRITE ``data`` at ``address`` without waiting for a reply, then drop whatever the
        servo may have answered (a write of the status return level: whether the servo
        answers that very write depends on the level it is changing)."""
        packet = self._p.write(servo_id, address, data)
        self.transact(packet, reply=False)
        time.sleep(reply_timeout(len(packet), self.status_length(), self._baud,
                                 self.return_delay.get(servo_id, 254), 0.002))
        with self._lock:
            try:
                self._ser.reset_input_buffer()
            except (serial.SerialException, OSError, termios.error) as exc:
                raise self._lost(exc) from None

    def sync_write(self, address: int, length: int, data: dict[int, bytes]) -> None:
        """SYNC_WRITE to several servos in one packet (no reply)."""
        self.transact(self._p.sync_write(address, length, data), reply=False)

    def reboot(self, servo_id: int) -> None:
        """REBOOT (protocol 2.0's): the servo restarts, clearing a hardware error (its
        torque is off afterwards)."""
        if self.family.reboot_packet is None:
            raise ValueError(f"REBOOT is a protocol 2.0 instruction, not "
                             f"{self.family.title}'s: power-cycle the servo instead")
        self.transact(self.family.reboot_packet(servo_id),
                      reply=self._answers_writes(servo_id))

    def factory_reset(self, servo_id: int, *, confirm: bool = False,
                      level: int | None = None) -> None:
        """FACTORY_RESET one servo: its ID becomes 1 and its baud the model's default
        (protocol 2.0's ``level``, a ``ResetLevel``, may keep the ID, or the ID and the
        baud; None resets everything).

        Refused (ValueError, nothing sent) unless ``confirm=True``.
        """
        packet = self._p.factory_reset(servo_id, level, confirm=confirm)
        self.transact(packet, reply=self._answers_writes(servo_id))
        self.status_return_level.pop(servo_id, None)
        self.return_delay.pop(servo_id, None)
        self.tables.pop(servo_id, None)

    def reg_write(self, servo_id: int, name: str, value: int) -> None:
        """REG_WRITE a raw value to an item: the servo checks it and holds it (Registered
        Instruction 1) until an ACTION (:meth:`action`) applies it, so goals registered
        on several servos start at one instant. Refused as :meth:`write` refuses: ValueError
        (nothing sent) for a read-only item or a value out of range, the protocol's
        ServoError when the servo refuses it."""
        address, data = self.table_of(servo_id).encode(name, value)
        status = self.transact(self._p.reg_write(servo_id, address, data),
                               reply=self._answers_writes(servo_id))
        self._check_refused(servo_id, address, data, status)

    def action(self) -> None:
        """Broadcast ACTION: apply every servo's registered REG_WRITE."""
        self.transact(self._p.action(), reply=False)
