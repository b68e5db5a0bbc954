"""The serial port under a servo bus: opening it (one
:class:`~armlab.hardware.wire.errors.PortError` line naming the fix for each usual
failure), what kind of port it is (a pseudo-terminal or an adapter) and what waiting on
it takes (margins, retries, an FTDI adapter's latency timer, the reply timeout from the
bytes, the baud and the return delay).
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import serial

from armlab.hardware.servos.servo_spec import RETURN_DELAY_UNIT, wire_time
from armlab.hardware.wire.errors import PortError

TIOCGRS485 = 0x542E


SYSFS_USB_SERIAL = Path("/sys/bus/usb-serial/devices")


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


#: s at most spent polling (not sleeping) for the last reply a transaction waits for: a
#: woken thread comes back some 40 µs after the bytes, a polling one at once (the
#: official SDK polls the whole wait; this keeps the CPU for the servos' turn-around)
LAST_REPLY_POLL_S = 0.0003


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
