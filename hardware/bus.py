"""A protocol-1.0 servo bus over pyserial: one transaction at a time, bounded retries.

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
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import select
import struct
import termios
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import serial

from hardware import protocol1 as p1
from hardware.control_table import RX24F_TABLE, ControlTable, table_for
from hardware.protocol1 import wire_time
from hardware.servo_spec import RETURN_DELAY_UNIT, SPECS

log = logging.getLogger("armlab.bus")

TIOCGRS485 = 0x542E
#: Error bits that mean "this write was refused" (the others describe the servo's state).
REFUSED = p1.ErrorBits.RANGE | p1.ErrorBits.INSTRUCTION | p1.ErrorBits.CHECKSUM
SYSFS_USB_SERIAL = Path("/sys/bus/usb-serial/devices")


class BusError(OSError):
    """The bus cannot do what was asked; the message says what to check.

    An OSError (an I/O failure), which a command line prints as one line; the
    backend over the bus (:class:`~hardware.dynamixel_backend.DynamixelBackend`)
    hands it to the control loop as a :class:`~control.backend.BackendError`.
    """


class PortError(BusError):
    """The serial port cannot be opened (missing, permission, busy)."""


class NoReply(BusError):
    """A servo did not answer after every retry."""


class WrongModel(BusError):
    """A servo answered with another model number than expected."""


class LinkLost(BusError):
    """The serial device went away in the middle of a transaction."""


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


def reply_timeout(request: int, reply: int, baud: float, return_delay: int, margin: float) -> float:
    """Seconds to wait for a status packet: wire time of request + reply, the servo's
    return delay (2 µs a unit, thesis §2.3) and a margin for the adapter and the OS."""
    return wire_time(request + reply, baud) + RETURN_DELAY_UNIT * return_delay + margin


def ftdi_latency_ms(port: str, *, sysfs: Path = SYSFS_USB_SERIAL) -> int | None:
    """The FTDI latency timer of ``port`` in ms, or None when it is not a usb-serial device."""
    dev = Path(os.path.realpath(port)).name
    try:
        return int((sysfs / dev / "latency_timer").read_text().strip())
    except (OSError, ValueError):
        return None


def ftdi_latency_check(port: str, *, sysfs: Path = SYSFS_USB_SERIAL) -> str | None:
    """Warn when an FTDI adapter's latency timer will cost ~16 ms per transaction.

    Returns None when the port is not a usb-serial device or the timer is 1 ms,
    otherwise a one-line message naming the fix.
    """
    value = ftdi_latency_ms(port, sysfs=sysfs)
    if value is None or value <= 1:
        return None
    timer = sysfs / Path(os.path.realpath(port)).name / "latency_timer"
    return (
        f"{port}: FTDI latency timer is {value} ms, so every servo reply waits up to {value} ms; "
        f"fix: echo 1 | sudo tee {timer}  (or a udev rule ATTR{{latency_timer}}=\"1\")"
    )


WIRE_MARGIN = 0.020  #: s of reply timeout beyond the wire time on a serial adapter
PTY_MARGIN = 0.100  #: s on a pseudo-terminal (the emulator: a process, not a wire)
WIRE_RETRIES = 2  #: extra attempts after a lost or broken reply on a serial adapter
PTY_RETRIES = 8  #: on a pseudo-terminal: a busy CPU can hold the emulator ~0.5 s or more


def is_pty(port: str) -> bool:
    """``port`` is (a link to) a pseudo-terminal, e.g. ``armlab emulate``'s /dev/pts/N."""
    return os.path.realpath(port).startswith("/dev/pts/")


def open_port(port: str, baud: float, *, exclusive: bool = True) -> serial.Serial:
    """Open ``port`` 8N1 at ``baud``; :class:`PortError` with the fix for the usual failures."""
    try:
        return serial.Serial(port, int(round(baud)), timeout=0, write_timeout=1.0,
                             exclusive=exclusive)
    except serial.SerialException as exc:
        code = exc.errno
        if code == errno.ENOENT or not os.path.exists(port):
            raise PortError(
                f"serial port {port} not found: is the adapter plugged in? "
                "(ls /dev/ttyUSB* /dev/ttyACM* /dev/serial/by-id/)"
            ) from None
        if code == errno.EACCES:
            raise PortError(
                f"permission denied on {port}: add yourself to the dialout group "
                "(sudo usermod -aG dialout $USER, then log out and in)"
            ) from None
        if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK):
            raise PortError(
                f"serial port {port} is busy: another program (another armlab, "
                "Dynamixel Wizard, ModemManager) has it open"
            ) from None
        raise PortError(f"cannot open serial port {port}: {exc}") from None


class Bus:
    """Protocol 1.0 on one serial port.

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
        table: control table assumed for servos not yet identified.
        exclusive: lock the port against other programs.

    Attributes:
        stats: :class:`BusStats` counters.
        notes: one-line remarks from opening (latency timer, RS-485 not applicable).
        errors: last error byte reported by each servo ID.
        late_ids: IDs whose status packet came while the bus waited for another servo's
            (a late reply: the scan pings them again).
        tables: control table of each identified servo ID.
        status_return_level: what each ID answers (2 = everything, 1 = READ only).
        return_delay: each ID's return delay setting (2 µs units).
    """

    def __init__(self, port: str, baud: float = 1_000_000, *, retries: int | None = None,
                 timeout_margin: float | None = None, echo: bool = False, rs485: bool = False,
                 table: ControlTable = RX24F_TABLE, exclusive: bool = True):
        if retries is None:
            retries = PTY_RETRIES if is_pty(port) else WIRE_RETRIES
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        if timeout_margin is None:
            timeout_margin = PTY_MARGIN if is_pty(port) else WIRE_MARGIN
        if not timeout_margin > 0:
            raise ValueError(f"timeout_margin must be > 0 s, got {timeout_margin}")
        self.port = port
        self.retries = int(retries)
        self.timeout_margin = float(timeout_margin)
        self.echo = bool(echo)
        self.table = table
        self.stats = BusStats()
        self.notes: list[str] = []
        self.errors: dict[int, p1.ErrorBits] = {}
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

    def transact(self, packet: bytes, *, reply: bool, reply_length: int = p1.OVERHEAD,
                 tries: int | None = None, margin: float | None = None) -> p1.StatusPacket | None:
        """Send one instruction packet; return its status packet (None when none is due).

        Retries up to ``tries - 1`` more times (default ``retries + 1`` tries in all)
        on a timeout or a broken reply; :class:`NoReply` when all fail.
        """
        servo_id = packet[2]
        tries = self.retries + 1 if tries is None else max(1, int(tries))
        delay = self.return_delay.get(servo_id, 254)
        with self._lock:
            for attempt in range(tries):
                if attempt:
                    self.stats.retries += 1
                backlog = self._send(packet)
                timeout = backlog + reply_timeout(
                    len(packet), reply_length, self._baud, delay,
                    self.timeout_margin if margin is None else margin)
                if not reply:
                    if self.echo:
                        self._receive(packet, reply_length=len(packet), timeout=timeout,
                                      echo_only=True)
                    return None
                status = self._receive(packet, reply_length=reply_length, timeout=timeout)
                if status is not None:
                    self.errors[status.servo_id] = status.error
                    return status
            self.stats.failures += 1
        raise NoReply(
            f"no reply from servo {servo_id} at {self._baud:.0f} bps on {self.port} "
            f"after {tries} tries: check the servos' power (a U2D2 supplies none), "
            f"the baud (armlab scan --port {self.port}), the ID, and that they speak "
            "protocol 1.0"
        )

    def _send(self, packet: bytes) -> float:
        """Write a packet; return the s of earlier packets still on the wire before it
        (a reply can only come after the UART has sent everything queued)."""
        try:
            self._ser.reset_input_buffer()
            self._ser.write(packet)
        except (serial.SerialException, OSError, termios.error) as exc:
            raise self._lost(exc) from None
        now = time.monotonic()
        backlog = max(0.0, self._tx_free - now)
        self._tx_free = now + backlog + wire_time(len(packet), self._baud)
        self.stats.transactions += 1
        self.stats.bytes_out += len(packet)
        return backlog

    def _lost(self, exc: BaseException) -> LinkLost:
        return LinkLost(
            f"lost the serial link on {self.port} ({exc}): is the adapter unplugged, "
            "the servo power off, or the emulator stopped?"
        )

    def _receive(self, request: bytes, *, reply_length: int, timeout: float,
                 echo_only: bool = False) -> p1.StatusPacket | None:
        parser = p1.PacketParser()
        deadline = time.monotonic() + timeout
        echo_pending = self.echo
        if echo_pending:
            deadline += wire_time(len(request), self._baud)
        while True:
            # past the deadline still look once (timeout 0): a client the OS paused
            # must not miss a reply that came in time
            chunk = self._read_chunk(max(0.0, deadline - time.monotonic()))
            if chunk is None:
                break
            for raw in parser.feed(chunk):
                if echo_pending and raw == request:
                    echo_pending = False
                    if echo_only:
                        return None
                    continue
                status = p1.decode_status(raw)
                if status.servo_id != request[2] or len(raw) != reply_length:
                    log.debug("stray packet %s waiting for %s", raw.hex(" "), request.hex(" "))
                    self.stats.corrupt += 1
                    self.late_ids.add(status.servo_id)
                    continue
                self.stats.replies += 1
                return status
            if parser.stats.bad_checksums and not parser.pending:
                break  # a broken reply: retry now rather than wait out the timeout
        self.stats.timeouts += 1
        self.stats.corrupt += parser.stats.bad_checksums
        if not echo_only:
            log.debug("no valid reply to %s within %.1f ms", request.hex(" "), timeout * 1e3)
        return None

    def _read_chunk(self, timeout: float) -> bytes | None:
        """The bytes that arrive within ``timeout`` s (None: none did); :class:`LinkLost`
        when the device is gone."""
        while True:
            try:
                ready, _, _ = select.select([self._fd], [], [], timeout)
                if not ready:
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
        parser = p1.PacketParser()
        deadline = time.monotonic() + seconds
        with self._lock:
            while (left := deadline - time.monotonic()) > 0:
                chunk = self._read_chunk(left)
                if chunk is None:
                    break
                for raw in parser.feed(chunk):
                    self.late_ids.add(p1.decode_status(raw).servo_id)
        return self.late_ids

    # -- instructions -------------------------------------------------------

    def ping(self, servo_id: int, *, tries: int | None = None,
             margin: float | None = None) -> p1.StatusPacket:
        """PING one servo (answers at every status return level)."""
        status = self.transact(p1.ping(servo_id), reply=True, tries=tries, margin=margin)
        assert status is not None
        return status

    def read_bytes(self, servo_id: int, address: int, length: int) -> bytes:
        """READ ``length`` bytes at ``address`` of one servo (error bits kept in ``errors``)."""
        if servo_id == p1.BROADCAST_ID:
            raise ValueError("servo_id: READ cannot be broadcast (nobody would answer)")
        status = self.transact(p1.read(servo_id, address, length), reply=True,
                               reply_length=p1.OVERHEAD + length)
        assert status is not None
        return status.params

    def write_bytes(self, servo_id: int, address: int, data: bytes) -> p1.StatusPacket | None:
        """WRITE ``data`` at ``address``; raise :class:`~hardware.protocol1.ServoError`
        when the servo refuses it (range, instruction, checksum, or an angle-limit
        error on a goal)."""
        reply = servo_id != p1.BROADCAST_ID and self.status_return_level.get(servo_id, 2) >= 2
        status = self.transact(p1.write(servo_id, address, data), reply=reply)
        if status is not None:
            refused = status.error & REFUSED
            if address <= 31 and address + len(data) > 30:
                refused |= status.error & p1.ErrorBits.ANGLE_LIMIT
            if refused:
                raise p1.ServoError(servo_id, refused)
        return status

    def sync_write(self, address: int, length: int, data: dict[int, bytes]) -> None:
        """SYNC_WRITE to several servos in one packet (no reply)."""
        self.transact(p1.sync_write(address, length, data), reply=False)

    def factory_reset(self, servo_id: int, *, confirm: bool = False) -> None:
        """FACTORY_RESET one servo: its ID becomes 1 and its baud the model's default.

        Refused (ValueError, nothing sent) unless ``confirm=True``.
        """
        packet = p1.factory_reset(servo_id, confirm=confirm)
        reply = servo_id != p1.BROADCAST_ID and self.status_return_level.get(servo_id, 2) >= 2
        self.transact(packet, reply=reply)
        self.status_return_level.pop(servo_id, None)
        self.return_delay.pop(servo_id, None)
        self.tables.pop(servo_id, None)

    def action(self) -> None:
        """Broadcast ACTION: apply every servo's registered REG_WRITE."""
        self.transact(p1.action(), reply=False)

    # -- named access -------------------------------------------------------

    def table_of(self, servo_id: int) -> ControlTable:
        """The control table of an identified servo, else the bus's default table."""
        return self.tables.get(servo_id, self.table)

    def read(self, servo_id: int, name: str) -> int:
        """Raw value of a control-table item, e.g. ``bus.read(1, "present_position")``."""
        table = self.table_of(servo_id)
        item = table.item(name)
        return table.decode(name, self.read_bytes(servo_id, item.address, item.size))

    def read_si(self, servo_id: int, name: str) -> float:
        """An item converted to SI (rad, rad/s, N·m, V, °C, s, bit/s)."""
        return self.table_of(servo_id).to_si(name, self.read(servo_id, name))

    def write(self, servo_id: int, name: str, value: int) -> None:
        """Write a raw value to an item; ValueError (nothing sent) if read-only or out of range.

        The status return level is written without waiting for a reply (whether
        the servo answers that very write depends on the level it is changing).
        """
        table = self.table_of(servo_id)
        address, data = table.encode(name, value)
        if name == "status_return_level":
            self.transact(p1.write(servo_id, address, data), reply=False)
            time.sleep(reply_timeout(len(data) + 7, p1.OVERHEAD, self._baud,
                                     self.return_delay.get(servo_id, 254), 0.002))
            with self._lock:
                try:
                    self._ser.reset_input_buffer()
                except (serial.SerialException, OSError, termios.error) as exc:
                    raise self._lost(exc) from None
            self.status_return_level[servo_id] = int(value)
            return
        self.write_bytes(servo_id, address, data)
        if name == "return_delay_time":
            self.return_delay[servo_id] = int(value)

    def write_si(self, servo_id: int, name: str, value: float) -> None:
        """Write an SI value (converted by the servo's ServoSpec) to an item."""
        self.write(servo_id, name, self.table_of(servo_id).from_si(name, value))

    def identify(self, servo_id: int, *, expect: int | str | None = None) -> ControlTable:
        """Read the model number of ``servo_id`` and remember its table.

        Raises :class:`WrongModel` when ``expect`` (model number or name) differs.
        """
        model = self.read(servo_id, "model_number")  # same address on every model
        if expect is not None:
            want = table_for(expect)
            if model != want.spec.model_number:
                found = SPECS[model].name if model in SPECS else "unknown model"
                raise WrongModel(
                    f"servo {servo_id} is a {found} (model number {model}), expected a "
                    f"{want.name} ({want.spec.model_number}): fix the joint map or --servo"
                )
        if model not in SPECS:
            raise WrongModel(
                f"servo {servo_id} has model number {model}, not an AX-12A (12) or RX-24F (24)"
            )
        table = table_for(model)
        self.tables[servo_id] = table
        return table


def sync_data(values: dict[int, tuple[int, ...]], sizes: tuple[int, ...]) -> dict[int, bytes]:
    """Pack raw item values per servo into SYNC_WRITE chunks (little-endian, given sizes)."""
    out = {}
    for servo_id, vals in values.items():
        out[servo_id] = b"".join(struct.pack("<H" if s == 2 else "<B", v)
                                 for v, s in zip(vals, sizes, strict=True))
    return out
