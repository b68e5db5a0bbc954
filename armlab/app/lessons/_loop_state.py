"""What a lesson tells a person about its control loop when the loop holds nothing (a
helper module, not a lesson): the red state of the status line (a torque-off that could
not be sent, E-STOP, a fault) and why an action on a stopped loop did nothing.

Shared by the lessons that drive a servo arm through a
:class:`~armlab.control.loop.ControlLoop` (compliance, your own arm), so a lost link, an
unreliable one, a servo's alarm or an E-STOP reads the same in each.
"""

from __future__ import annotations

import time

from armlab.app.lessons._common import esc
from armlab.app.lessons.compliance_servos import LinkMonitor
from armlab.control.commands import Reconnect, Reset
from armlab.control.loop import ControlLoop, LoopStatus

#: Status when an e-stop's torque-off write could not go out (the link is gone).
UNSENT_BANNER = "Torque off could not be sent: switch the servo power off"
#: Colour of a stopped loop's state.
STOPPED_COLOR = "#b00020"


def stopped_state(st: LoopStatus) -> str | None:
    """The status line's state while the loop holds nothing, None while it runs: the
    unsent torque-off first (never claim a torque-off that did not reach the servos),
    then E-STOP, then the fault."""
    if st.torque_off_unsent:
        return UNSENT_BANNER
    if st.estopped:
        return "E-STOPPED: torque off (press Reset)"
    if st.fault:
        return f"stopped: {st.fault}"
    if st.held_off:
        return "torque off: confirm the arm is clear"
    return None


def check_running(st: LoopStatus) -> None:
    """Raise ValueError saying why nothing would happen when the loop is stopped (a
    stopped loop takes a command and does nothing with it); return while it runs."""
    if st.link_down:
        raise ValueError(f"nothing happened: the link to the servos is down ({st.fault}); "
                         "the lab retries every second (Reset tries at once)")
    if st.fault is not None:
        raise ValueError(f"nothing happened: the control loop is stopped ({st.fault}); "
                         "press Reset first")
    if st.estopped:
        raise ValueError("nothing happened: E-STOP is in force; press Reset first")
    if st.held_off:
        raise ValueError(f"nothing happened: the torque is off until you confirm the arm is "
                         f"clear ({st.held_off})")


def post_reset(loop: ControlLoop) -> None:
    """Clear a fault or E-STOP, or confirm an uncalibrated arm is clear: torque on, hold
    where the arm is (the loop's Reset).

    Raises:
        ValueError: the link to the servos is down, so nothing can be reset: the
            message says so; a reconnection is tried at once instead.
    """
    st = loop.status
    if st.link_down:
        loop.post(Reconnect())
        raise ValueError(f"nothing happened: the link to the servos is down ({st.fault}); "
                         "trying to reconnect now (the lab also tries once a second); "
                         "press Reset again once the status says the link is back")
    loop.post(Reset())


def link_note(monitor: LinkMonitor, backend: object) -> str:
    """HTML of the status line's orange note while the link to the servos needs many
    retries (:class:`~armlab.app.lessons.compliance_servos.LinkMonitor` of ``backend``'s bus
    counters); "" otherwise."""
    text = monitor.warning(getattr(backend, "stats", None), time.monotonic())
    return "" if text is None else \
        f"<div style='color:#a15c00;font-size:0.85em'>{esc(text)}</div>"
