"""``BatchedWalls``: the walls of a class's private arms, one per arm, and the force each
one's hand feels (:class:`armlab.control.backend.Touchable` for
:class:`armlab.hardware.families.dynamixel1.batched_backend.BatchedArmBackend`).

A :class:`~armlab.hardware.families.dynamixel1.batched_plant.BatchedPlant` holds a wall
per arm (``set_wall``: a plane with stiffness, damping and friction, its force in each
arm's dynamics at every RK stage) and tells the normal force on each arm near its wall
at the state now (``wall_forces``: worked out with the next step's hold of its walls, so
at no forward kinematics of its own). The control loop records the wall's force every
period (``f_contact``) and its largest value at the end of any plant step since the
period before (``f_contact_peak``: an impact lasts a few steps, between two periods), as
:class:`armlab.hardware.sim.plant.Plant` keeps it. So this object keeps each arm's wall
as a :class:`~armlab.control.backend.WallSetting` (set through it, so it and the plant
agree), and after every plant step (:meth:`step`, what the class's clock calls in place
of ``plant.step``) raises the peak of every arm whose peak is being read and whose hand
presses on its wall.

Each wall is its own arm's: :meth:`set` names the arm, and one arm's wall never enters
another's force, peak or dynamics (the plant's rows are per arm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armlab.control.backend import WallSetting
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.sim.contact import checked_size


@dataclass
class _Tracked:
    """One arm's wall as this object keeps it."""

    setting: WallSetting
    #: N, the largest force at a step's end since :meth:`BatchedWalls.peak` was last
    #: called (None: never called; the steps skip the work until then)
    peak: float | None = None


class BatchedWalls:
    """The walls of ``plant``'s arms (module docstring). Not thread-safe: its owner holds
    the plant's lock (the clock's) around every call, as around the plant's.

    Args:
        plant: the class's plant; this object sets its walls and is stepped in its place.
    """

    def __init__(self, plant: BatchedPlant) -> None:
        self.plant = plant
        self._walls: dict[int, _Tracked] = {}
        self._read: set[int] = set()  #: arms whose peak was read while they had no wall
        self._peaks = 0  #: walls whose peak is read (the steps skip the work at none)
        #: the plant's forces last seen, and them by arm (the pressing ones)
        self._seen: np.ndarray | None = None
        self._by_arm: dict[int, float] = {}

    # -- the walls -------------------------------------------------------------------

    def set(self, arm: int, origin: np.ndarray | None, normal: np.ndarray | None = None, *,
            stiffness: float, damping: float, friction: float = 0.0,
            size: tuple[float, float, float] | None = None) -> None:
        """Arm ``arm``'s wall (:meth:`BatchedPlant.set_wall`: a plane its hand's tip
        meets, or a box, ``size``, its links meet too; the arguments as
        ``Touchable.set_wall``'s); None removes it.

        Raises:
            ValueError: as ``BatchedPlant.set_wall`` (no such arm, a bad argument): the
                arm's wall as it was.
        """
        arm = int(arm)
        self.plant.set_wall(arm, origin, normal, stiffness=stiffness, damping=damping,
                            friction=friction, size=size)
        old = self._drop(arm)
        if old is not None and old.peak is not None:  # (read once: Plant keeps its peak
            self._read.add(arm)  # from then on, across walls)
        if origin is None:
            return
        nrm = np.array(normal, dtype=float)
        nrm = nrm / float(np.linalg.norm(nrm))  # (the plant's own normalising)
        setting = WallSetting(np.array(origin, dtype=float), nrm, float(stiffness),
                              float(damping), float(friction),
                              checked_size(size))
        kept = old.peak if old is not None and old.peak is not None else (
            0.0 if arm in self._read else None)
        self._walls[arm] = _Tracked(setting, kept)
        self._peaks += kept is not None

    def setting(self, arm: int) -> WallSetting | None:
        """Arm ``arm``'s wall as :meth:`set` placed it (None: none)."""
        tracked = self._walls.get(int(arm))
        return None if tracked is None else tracked.setting

    def forget(self, arm: int) -> None:
        """Arm ``arm`` left the plant (or is leaving): its wall and peak go with it."""
        self._read.discard(int(arm))
        self._drop(int(arm))

    def _drop(self, arm: int) -> _Tracked | None:
        old = self._walls.pop(arm, None)
        if old is not None and old.peak is not None:
            self._peaks -= 1
        return old

    def force(self, arm: int) -> float:
        """N, the wall's normal force on arm ``arm``'s hand now (0 off it, or without one).

        Raises:
            ValueError: no such arm in the plant.
        """
        self.plant.row(int(arm))
        if int(arm) not in self._walls:
            return 0.0
        return self._now().get(int(arm), 0.0)

    def peak(self, arm: int) -> float:
        """N, the largest wall force on arm ``arm``'s hand at the end of any step since the
        last call (then forgotten), and at least the force now; from the first call on the
        steps keep it (``Plant.wall_peak``)."""
        now = self.force(arm)
        tracked = self._walls.get(int(arm))
        if tracked is None:
            self._read.add(int(arm))
            return now
        peak, tracked.peak = tracked.peak, 0.0
        if peak is None:
            self._peaks += 1  # (tracked from now on)
            return now
        return max(peak, now)

    def _now(self) -> dict[int, float]:
        """The plant's forces at the state now, by arm: those pressing on their walls."""
        ids, forces = self.plant.wall_forces()
        if forces is not self._seen:
            self._seen = forces
            self._by_arm = {a: f for a, f in zip(ids.tolist(), forces.tolist(), strict=True)
                            if f > 0.0}
        return self._by_arm

    # -- stepping --------------------------------------------------------------------

    def step(self) -> None:
        """Step the plant one ``dt``, then keep the peaks (module docstring)."""
        self.plant.step()
        self.after_step()

    def after_step(self) -> None:
        """Raise the peak of every arm whose peak is read, from the plant's state now."""
        if not self._peaks:
            return
        walls = self._walls
        for arm, force in self._now().items():
            tracked = walls.get(arm)
            if tracked is not None and tracked.peak is not None and force > tracked.peak:
                tracked.peak = force
