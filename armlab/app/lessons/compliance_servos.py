"""The servo panel: connection state, per-servo voltage, temperature, error bits, what to do.

On the serial backend the figures are read over the bus (Present Voltage and
Present Temperature, once a second; the bus lock keeps these reads between the
control loop's transactions); the simulated backend reports its simulated
servos' registers. Error bits are protocol 1.0's (the status packet's error
byte); each comes with what a lab technician should do about it.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

from armlab.control.backend import Backend, BackendError
from armlab.hardware.families.dynamixel1.packets import ErrorBits, error_names

#: What to do about each protocol 1.0 error bit (their names: ``protocol1.error_names``).
ERROR_ADVICE: dict[ErrorBits, str] = {
    ErrorBits.INPUT_VOLTAGE: "supply out of range: check the 12 V supply and its cable",
    ErrorBits.ANGLE_LIMIT: "a goal beyond the CW/CCW limits: check the joint map and limits",
    ErrorBits.OVERHEATING: "let the servo cool down; lower the load or the gains",
    ErrorBits.RANGE: "a value out of range was sent: check the configuration",
    ErrorBits.CHECKSUM: "noise on the bus: check the RS-485 wiring, terminator and baud",
    ErrorBits.OVERLOAD: "the arm is blocked or the load too high: free it, then press Reset",
    ErrorBits.INSTRUCTION: "an unknown instruction: check that nothing else talks on the bus",
}
VOLTAGE_RANGE = (9.0, 12.6)  #: V, RX-24F operating range
#: fraction of packets sent again (a reply late, lost or broken) above which the status
#: line warns that the link is unreliable
RETRY_WARN = 0.05
#: s of bus traffic the warning looks back over
RETRY_WINDOW_S = 10.0
HOT_C = 70.0  #: °C, warn above (RX-24F shuts down at its 80 °C limit)


@dataclass(frozen=True)
class ServoHealth:
    """One servo's state: ID, joint, V, °C, error byte, torque enabled (None = unknown)."""

    servo_id: int | None
    joint: str
    voltage: float | None
    temperature: float | None
    error: int
    torque_on: bool | None


def advice(h: ServoHealth) -> list[str]:
    """What to do about servo ``h`` (empty when healthy)."""
    out = [f"{h.joint}: {what}" for bit, what in ERROR_ADVICE.items() if h.error & bit]
    if h.voltage is not None and not VOLTAGE_RANGE[0] <= h.voltage <= VOLTAGE_RANGE[1]:
        out.append(f"{h.joint}: {h.voltage:.1f} V is outside {VOLTAGE_RANGE[0]:g}–"
                   f"{VOLTAGE_RANGE[1]:g} V: check the supply")
    if h.temperature is not None and h.temperature > HOT_C:
        out.append(f"{h.joint}: {h.temperature:.0f} °C: let it cool before it shuts down")
    return out


def read_health(backend: Backend, joint_names: tuple[str, ...]) -> tuple[list[ServoHealth], str]:
    """Every servo's health and a one-line link state.

    Raises:
        BackendError: when the serial link fails while reading.
    """
    plant = getattr(backend, "plant", None)
    if plant is not None:  # the simulated servos, named by the model they simulate
        reports = plant.reports()
        # (a classroom worker's arm names none: it simulates RX-24F servos only)
        models = sorted({s.name for s in getattr(backend, "specs", ())}) or ["RX-24F"]
        return ([ServoHealth(None, name, r.voltage / 10.0, float(r.temperature), int(r.error),
                             bool(r.torque_enable))
                 for name, r in zip(joint_names, reports, strict=True)],
                f"simulated servos ({', '.join(models)} model)")
    bus = getattr(backend, "bus", None)
    joint_map = getattr(backend, "map", None)
    if bus is None or joint_map is None:
        return [], f"{type(backend).__name__}: no servo details available"
    out = []
    for j in joint_map.joints:
        volts = float(bus.read_si(j.servo_id, "present_voltage"))
        temp = float(bus.read_si(j.servo_id, "present_temperature"))
        out.append(ServoHealth(j.servo_id, j.name, volts, temp,
                               int(bus.errors.get(j.servo_id, 0)), None))
    st = getattr(bus, "stats", None)
    port = getattr(bus, "port", "") or ""
    line = f"connected{(' on ' + str(port)) if port else ''} at {bus.baud:,.0f} bit/s"
    if st is not None:
        line += f" · {_stats_text(st)}"
    return out, line


def _stats_text(st: object) -> str:
    parts = []
    for name in ("transactions", "retries", "timeouts", "corrupt"):
        v = getattr(st, name, None)
        if v is not None:
            parts.append(f"{name} {v}")
    return ", ".join(parts)


def health_html(servos: list[ServoHealth], link: str, *, error: str | None = None) -> str:
    """An HTML table of the servos with advice under it."""
    esc = html.escape
    if error is not None:
        return (f"<div style='color:#b00020;font-weight:600'>link lost: {esc(error)}</div>"
                "<div>Check the cable and the servo power, then press Reset.</div>")
    rows = []
    for h in servos:
        bad = h.error != 0
        style = " style='color:#b00020;font-weight:600'" if bad else ""
        rows.append(
            f"<tr><td>{'' if h.servo_id is None else h.servo_id}</td><td>{esc(h.joint)}</td>"
            f"<td>{'—' if h.voltage is None else f'{h.voltage:.1f}'}</td>"
            f"<td>{'—' if h.temperature is None else f'{h.temperature:.0f}'}</td>"
            f"<td{style}>{esc(error_names(h.error))}</td>"
            f"<td>{'—' if h.torque_on is None else ('on' if h.torque_on else 'off')}</td></tr>")
    tips = [t for h in servos for t in advice(h)]
    tip_html = ("<ul style='margin:4px 0 0 16px;padding:0'>"
                + "".join(f"<li>{esc(t)}</li>" for t in tips) + "</ul>") if tips else \
        "<div style='color:#2e7d32'>all servos healthy</div>"
    return (f"<div style='font-size:0.85em'><div>{esc(link)}</div>"
            "<table style='width:100%;border-collapse:collapse;text-align:left'>"
            "<tr><th>ID</th><th>joint</th><th>V</th><th>°C</th><th>errors</th>"
            "<th>torque</th></tr>" + "".join(rows) + "</table>" + tip_html + "</div>")


class LinkMonitor:
    """How many packets the bus had to send again lately (a reply late, lost or broken):
    retries keep the arm held, but a link that needs many is told, not hidden."""

    def __init__(self) -> None:
        self._marks: list[tuple[float, int, int]] = []  # (time, transactions, retries)

    def warning(self, stats: object, now: float) -> str | None:
        """A sentence when over :data:`RETRY_WARN` of the last :data:`RETRY_WINDOW_S` s of
        packets were sent again; None otherwise (or for a backend without bus counters)."""
        sent, again = getattr(stats, "transactions", None), getattr(stats, "retries", None)
        if sent is None or again is None:
            return None
        self._marks.append((now, int(sent), int(again)))
        while len(self._marks) > 2 and self._marks[1][0] <= now - RETRY_WINDOW_S:
            self._marks.pop(0)
        _, sent0, again0 = self._marks[0]
        if sent - sent0 < 20:
            return None
        frac = (again - again0) / (sent - sent0)
        if frac <= RETRY_WARN:
            return None
        return (f"link unreliable: {100 * frac:.0f} % of packets sent again in the last "
                f"{RETRY_WINDOW_S:.0f} s (replies late, lost or broken): check the cable, "
                "the adapter's latency timer and the baud")


def safe_health_html(backend: Backend, joint_names: tuple[str, ...]) -> str:
    """:func:`health_html` of :func:`read_health`, a link failure shown instead of raised."""
    try:
        servos, link = read_health(backend, joint_names)
    except (BackendError, OSError) as exc:
        return health_html([], "", error=str(exc))
    return health_html(servos, link)
