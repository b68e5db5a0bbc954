"""Emulated servos on one bus, whatever their family: a control-table image with EEPROM/RAM
semantics (:class:`TableImage`), the plant that moves them (:class:`Physics`) and the
network a family's emulator subclasses (:class:`ServoBus`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, Self, TypeVar

from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import Codec, Parser
from armlab.hardware.servos.registry import family
from armlab.hardware.servos.servo_spec import RETURN_DELAY_UNIT

EMULATED_FIRMWARE = 24  #: the firmware version an emulated servo reports
BAUD_TOLERANCE = 0.03  #: a UART still decodes bytes within about 3 % of its rate


@dataclass
class TableImage:
    """What every emulated servo keeps, whatever its protocol: its model's control table
    and the table's image.

    Attributes:
        table: the model's control table.
        memory: the table image (50 bytes on the AX-12A and RX-24F, 147 on the X-series).
        joint: index of the simulated servo this one is (see the network's physics).
        pending: a REG_WRITE waiting for ACTION (address, data).
    """

    table: ControlTable
    memory: bytearray
    joint: int
    pending: tuple[int, bytes] | None = None

    #: the firmware version the emulated servos report
    FIRMWARE: ClassVar[int] = EMULATED_FIRMWARE

    @classmethod
    def new(cls, table: ControlTable, servo_id: int, joint: int, *, baud_value: int,
            present_position: int) -> Self:
        """A servo fresh from power-on with ID ``servo_id`` at EEPROM baud value ``baud_value``."""
        mem = table.defaults(firmware=cls.FIRMWARE, servo_id=servo_id,
                             present_position=present_position, baud_value=baud_value)
        return cls(table, mem, joint)

    def get(self, name: str) -> int:
        return self.table.value_at(self.memory, name)

    def put(self, name: str, value: int) -> None:
        """Set an item from the servo's side (present values, shutdown), bypassing access."""
        item = self.table.item(name)
        self.memory[item.address : item.address + item.size] = int(value).to_bytes(
            item.size, "little", signed=item.signed)

    @property
    def servo_id(self) -> int:
        return self.get("id")

    @property
    def baud(self) -> float:
        return self.table.to_si("baud_rate", self.get("baud_rate"))

    @property
    def return_delay(self) -> float:
        """s before the status packet (2 µs a unit, thesis §2.3)."""
        return RETURN_DELAY_UNIT * self.get("return_delay_time")

    def hears(self, baud: float | None) -> bool:
        """Whether bytes at ``baud`` reach this servo's UART intact (None: unknown, yes)."""
        return baud is None or abs(baud - self.baud) <= BAUD_TOLERANCE * self.baud

    def factory_reset(self) -> None:
        """FACTORY_RESET (protocol 1.0; Feetech's RESET): everything back to the factory's
        (ID 1, the model's default baud), the horn where it is."""
        present = self.get("present_position")
        self.memory[:] = self.table.defaults(firmware=self.FIRMWARE, servo_id=1,
                                             present_position=present)
        self.pending = None


#: the kind of emulated servo a family's physics moves (a :class:`TableImage`)
S = TypeVar("S", bound=TableImage, contravariant=True)


class Physics(Protocol[S]):
    """What moves emulated servos (of a family's kind ``S``): the simulated plant behind
    their registers."""

    def advance_to(self, t: float) -> None:
        """Integrate the plant up to ``t`` s since the emulator started."""
        ...

    def apply(self, servo: S) -> None:
        """Copy the servo's RAM registers (torque enable, compliance, goal, speed,
        torque limit, punch) into its simulated servo."""
        ...

    def report(self, servo: S) -> None:
        """Write present position, speed, load, voltage, temperature and moving
        into the servo's table, as its firmware would."""
        ...


@dataclass
class ServoBus:
    """Emulated servos on one bus and the simulated plant that moves them. A protocol's
    network (``families/<family>/emulator.py``: ``ServoNetwork``, ``XServoNetwork``, ...) adds
    ``protocol`` and how its servos answer instruction packets (``handle``,
    ``checksum_error``): what :class:`PtyEmulator` serves.

    Attributes:
        servos: the emulated servos (IDs may change by WRITE or FACTORY_RESET).
        physics: the plant that moves them.
        t: s of plant time reached.
    """

    servos: list[Any]
    physics: Any
    t: float = 0.0

    if TYPE_CHECKING:  # what each protocol's network (a subclass) defines, for mypy only
        protocol: ClassVar[int | str]

        def handle(self, packet: Any, *, baud: float | None = None
                   ) -> list[tuple[Any, bytes]]: ...

        def checksum_error(self, raw: bytes, *, baud: float | None = None
                           ) -> list[tuple[Any, bytes]]: ...

    @property
    def codec(self) -> Codec:
        """The packet module of the family its servos are (by ``protocol``)."""
        return family(self.protocol).codec

    def parser(self) -> Parser:
        """A parser of the requests its servos hear (a family whose servos answer a packet
        with a broken checksum keeps those: its network overrides this)."""
        return self.codec.PacketParser()

    def tick(self, t: float) -> None:
        """Advance the plant to ``t`` s and refresh every servo's present values."""
        self.t = t
        self.physics.advance_to(t)
        for s in self.servos:
            self.physics.report(s)

    def _write_each(self, listeners: Sequence[TableImage], address: int, length: int,
                    body: bytes) -> None:
        """A SYNC_WRITE's body, (ID, ``length`` bytes) per servo: each listening servo
        named writes its bytes at ``address`` (as its WRITE would, refused or not) and its
        simulated firmware gets them; a body of another length is ignored whole."""
        if length == 0 or len(body) % (length + 1):
            return
        by_id = {s.servo_id: s for s in listeners}
        for k in range(0, len(body), length + 1):
            s = by_id.get(body[k])
            if s is not None:
                s.write(address, bytes(body[k + 1 : k + 1 + length]))  # type: ignore[attr-defined]  # each family's servo has write
                self.physics.apply(s)
