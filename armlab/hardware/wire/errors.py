"""What a servo bus raises: one :class:`BusError` a person can act on, and its kinds
(the port cannot be opened, no reply, the wrong model, the link lost).
"""

from __future__ import annotations


class BusError(OSError):
    """The bus cannot do what was asked; the message says what to check.

    An OSError (an I/O failure), which a command line prints as one line; the
    backend over the bus (:class:`~armlab.hardware.families.dynamixel1.backend.DynamixelBackend`)
    hands it to the control loop as a :class:`~armlab.control.backend.BackendError`.
    """


class PortError(BusError):
    """The serial port cannot be opened (missing, permission, busy)."""


class NoReply(BusError):
    """A servo did not answer after every retry (``ids``: the ones that did not)."""

    ids: tuple[int, ...] = ()


class WrongModel(BusError):
    """A servo answered with another model number than expected."""


class LinkLost(BusError):
    """The serial device went away in the middle of a transaction."""
