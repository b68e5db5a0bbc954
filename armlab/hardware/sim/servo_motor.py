"""What every servo model's simulation shares: the physical constants a datasheet does not
give (:class:`ServoParams`) and the horn torque between firmware ticks
(:class:`GearedMotor`: the DC-motor line at the held duty minus gear friction). Each
family's firmware model (``armlab.hardware.families.<family>.firmware``) builds on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class ServoParams:
    """Physical constants the datasheet does not give (estimates; docs/servo-model.md).

    Attributes:
        rotor_inertia: motor rotor inertia seen at the horn (J_rotor · gear²), kg m².
        coulomb_friction: gear-train dry friction at the horn, N·m.
        viscous_friction: gear-train viscous friction at the horn, N·m·s/rad.
        friction_speed: speed below which dry friction is smoothed (tanh), rad/s.
        overload_time: seconds at full duty without moving before the overload error.
        stall_speed: horn speed under which the servo counts as stalled, rad/s.
        voltage: supply voltage reported as Present Voltage, V.
        temperature: reported Present Temperature, °C.
    """

    rotor_inertia: float = 3.0e-3
    coulomb_friction: float = 0.03
    viscous_friction: float = 0.005
    friction_speed: float = 0.02
    overload_time: float = 2.0
    stall_speed: float = 0.05
    voltage: float = 12.0
    temperature: float = 35.0


#: No friction, no rotor: the bare rigid body (for energy checks and teaching).
IDEAL = ServoParams(rotor_inertia=0.0, coulomb_friction=0.0, viscous_friction=0.0)


class GearedMotor:
    """The horn torque between firmware ticks, the same for every servo model: the
    DC-motor line at the duty the firmware holds over the tick (``drive − damping · ω``,
    set by each tick) minus gear friction (:attr:`params`).

    It is the base of every family's firmware model (its folder's ``firmware.py``), and
    what the plant calls of one: :meth:`update` each tick, :meth:`report` for a READ. The
    datasheet :attr:`spec` and the control-table registers :attr:`regs` are the family's
    own types; :meth:`inject_error` raises one of its ``fault_flags``.
    """

    params: ServoParams
    spec: Any  # the family's datasheet (ServoSpec, XSpec, StsSpec)
    regs: Any  # the family's RAM registers (ServoRegisters, XRegisters, StsRegisters)
    #: Horn torque coefficients for the current tick: tau = drive - damping * omega.
    drive: float = 0.0
    damping: float = 0.0

    def torque(self, velocity: float) -> float:
        """Horn torque N·m at horn ``velocity`` rad/s: motor line minus gear friction."""
        return self.drive - self.damping * velocity - self.friction(velocity)

    def motor_torque(self, velocity: float) -> float:
        """Motor torque at the horn (the torque–speed line at the present duty), N·m."""
        return self.drive - self.damping * velocity

    def update(self, dt: float, angle: float, velocity: float) -> None:
        """One firmware tick of ``dt`` s at horn ``angle`` rad and ``velocity`` rad/s: sets
        :attr:`drive` and :attr:`damping` for the tick (each family's firmware)."""
        raise NotImplementedError

    def report(self) -> Any:
        """What the servo would answer to a READ, raw words (the family's report type)."""
        raise NotImplementedError

    def present_position(self) -> int:
        """The raw Present Position word."""
        raise NotImplementedError

    def inject_error(self, bits: int, *, after: float = 0.0) -> None:
        """Raise the status error or alarm ``bits`` (the family's ``fault_flags``) once the
        torque has been on for ``after`` s (a family whose firmware flags none: refused)."""
        raise NotImplementedError(f"{type(self).__name__} raises no faults")

    def friction(self, velocity: float) -> float:
        """Gear-train friction torque opposing ``velocity`` (positive = resisting CCW), N·m."""
        p = self.params
        f = p.viscous_friction * velocity
        if p.coulomb_friction:
            f += p.coulomb_friction * math.tanh(velocity / p.friction_speed)
        return f
