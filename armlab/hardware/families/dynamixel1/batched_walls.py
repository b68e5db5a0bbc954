"""``BatchedWalls``: the walls of a class's private arms, one per arm, and the force each
one's hand feels (:class:`armlab.control.backend.Touchable` for
:class:`armlab.hardware.families.dynamixel1.batched_backend.BatchedArmBackend`).

A :class:`~armlab.hardware.families.dynamixel1.batched_plant.BatchedPlant` already holds a
wall per arm (``set_wall``: a plane with stiffness, damping and friction, its force in
each arm's dynamics at every RK stage) but says nothing of its force. The control loop
records the wall's force every period (``f_contact``) and its largest value at the end
of any plant step since the period before (``f_contact_peak``: an impact lasts a few
steps, between two periods), as :class:`armlab.hardware.sim.plant.Plant` keeps it. So
this object keeps each arm's wall as a :class:`~armlab.control.backend.WallSetting` (set
through it, so it and the plant agree), and after every plant step (:meth:`step`, what
the class's clock calls in place of ``plant.step``) updates the peak of every arm whose
peak is being read.

The force is Plant's: at the hand (the last link's tip), n · p − n · o = d < 0 behind the
plane, F = max(0, −k d − c vₙ), worked out with the float code of the arm's generated
kinematics (:func:`armlab.kinematics.dynamics.dynamics_model`), one arm at a time,
in Plant's order of operations. Most steps most hands are far from their wall: each
tracked arm keeps a lower bound of its hand's distance to the plane, lowered every step
by how far the joints' speeds can move the hand (2 dt · reach · Σ|θ̇|, the larger of the
step's two ends: the plant's own bound, ``_near_fields``); only a hand whose bound falls
under :data:`MARGIN_M` is worked out (forward kinematics), so an arm away from its wall
costs a few numpy operations shared by all arms a step, not its kinematics. The force
worked out at a step's end is kept, so the loop's reads of it and of the peak in its
period (:meth:`force`, :meth:`peak`) cost no kinematics of their own.

Each wall is its own arm's: :meth:`set` names the arm, and one arm's wall never enters
another's force, peak or dynamics (the plant's rows are per arm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armlab.control.backend import WallSetting
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.kinematics.dynamics import dynamics_model

#: m: a hand whose distance to its wall may be under this is worked out at the step's end
MARGIN_M = 0.001


@dataclass
class _Tracked:
    """One arm's wall as this object keeps it."""

    setting: WallSetting
    origin: tuple[float, float, float]
    normal: tuple[float, float, float]
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
        model = plant.model
        self._dyn = dynamics_model(model)
        self._last = 12 * (plant.n - 1)  #: the hand's link's offset in the frames
        self._tip = tuple(float(x) for x in model.tip[:3, 3])
        #: m a point of the hand moves at most per rad of the joints (Plant's bound)
        reach = float(sum(np.linalg.norm(j.origin[:3, 3]) for j in model.joints)
                      + np.linalg.norm(model.tip[:3, 3]))
        self._travel = 2.0 * plant.dt * reach
        self._walls: dict[int, _Tracked] = {}
        self._read: set[int] = set()  #: arms whose peak was read while they had no wall
        # the arms whose peak is read, their plant rows and distance bounds (rebuilt when
        # the plant's arms or the tracked walls change)
        self._ids: np.ndarray = np.zeros(0, dtype=np.int64)
        self._plant_ids: np.ndarray = np.zeros(0, dtype=np.int64)
        self._rows: np.ndarray = np.zeros(0, dtype=np.int64)
        self._index: dict[int, int] = {}  #: arm id -> its place in ``_ids``
        self._gap: np.ndarray = np.zeros(0)
        self._speed: np.ndarray = np.zeros(0)  #: Σ|θ̇| at the last step's end
        self._force: np.ndarray = np.zeros(0)  #: N, each one's force at the last step's end
        self._at_step = -1  #: the plant's step count :meth:`after_step` last saw
        self._stale = True

    # -- the walls -------------------------------------------------------------------

    def set(self, arm: int, origin: np.ndarray | None, normal: np.ndarray | None = None, *,
            stiffness: float, damping: float, friction: float = 0.0,
            size: tuple[float, float, float] | None = None) -> None:
        """Arm ``arm``'s wall (:meth:`BatchedPlant.set_wall`, the hand its contact point;
        the arguments as ``Touchable.set_wall``'s); None removes it.

        Raises:
            ValueError: as ``BatchedPlant.set_wall`` (no such arm, a bad argument, a box:
                ``size`` given, which the batched plant takes none of): the arm's wall as
                it was.
        """
        arm = int(arm)
        self.plant.set_wall(arm, origin, normal, stiffness=stiffness, damping=damping,
                            friction=friction, size=size)
        old = self._walls.pop(arm, None)
        self._stale = True
        if old is not None and old.peak is not None:  # (read once: Plant keeps its peak
            self._read.add(arm)  # from then on, across walls)
        if origin is None:
            return
        o = np.array(origin, dtype=float)
        nrm = np.array(normal, dtype=float)
        nrm = nrm / float(np.linalg.norm(nrm))  # (the plant's own normalising)
        setting = WallSetting(o, nrm, float(stiffness), float(damping), float(friction))
        self._walls[arm] = _Tracked(setting, (float(o[0]), float(o[1]), float(o[2])),
                                    (float(nrm[0]), float(nrm[1]), float(nrm[2])),
                                    old.peak if old is not None and old.peak is not None
                                    else (0.0 if arm in self._read else None))

    def setting(self, arm: int) -> WallSetting | None:
        """Arm ``arm``'s wall as :meth:`set` placed it (None: none)."""
        tracked = self._walls.get(int(arm))
        return None if tracked is None else tracked.setting

    def forget(self, arm: int) -> None:
        """Arm ``arm`` left the plant (or is leaving): its wall and peak go with it."""
        self._read.discard(int(arm))
        if self._walls.pop(int(arm), None) is not None:
            self._stale = True

    def force(self, arm: int) -> float:
        """N, the wall's normal force on arm ``arm``'s hand now (0 off it, or without one).

        Raises:
            ValueError: no such arm in the plant.
        """
        tracked = self._walls.get(int(arm))
        row = self.plant.row(int(arm))
        if tracked is None:
            return 0.0
        i = self._fresh_index(arm)
        if i is not None:  # (worked out at this state by the step's end)
            return float(self._force[i])
        return self._push(tracked, self.plant.q[row].tolist(), self.plant.qd[row].tolist())[1]

    def peak(self, arm: int) -> float:
        """N, the largest wall force on arm ``arm``'s hand at the end of any step since the
        last call (then forgotten), and at least the force now; from the first call on the
        steps keep it (``Plant.wall_peak``)."""
        tracked = self._walls.get(int(arm))
        if tracked is not None and tracked.peak is not None and \
                self._fresh_index(arm) is not None:  # the step's end, this state: in it
            kept, tracked.peak = tracked.peak, 0.0
            return kept
        now = self.force(arm)
        if tracked is None:
            self._read.add(int(arm))
            return now
        peak, tracked.peak = tracked.peak, 0.0
        if peak is None:
            self._stale = True  # (tracked from now on)
            return now
        return max(peak, now)

    def _fresh_index(self, arm: int) -> int | None:
        """Arm ``arm``'s place among the tracked arms when :meth:`after_step` worked out
        its force at the plant's state now (None: not tracked, or not since)."""
        if self._stale or self._at_step != self.plant.steps:
            return None
        return self._index.get(int(arm))

    # -- stepping --------------------------------------------------------------------

    def step(self) -> None:
        """Step the plant one ``dt``, then keep the peaks (module docstring)."""
        self.plant.step()
        self.after_step()

    def after_step(self) -> None:
        """Update the peak of every arm whose peak is read, from the plant's state now."""
        if not self._walls:
            return
        plant_ids = self.plant.arm_ids
        if self._stale or plant_ids.size != self._plant_ids.size or \
                not np.array_equal(plant_ids, self._plant_ids):
            self._rebuild(plant_ids)
        if not self._ids.size:
            return
        self._at_step = self.plant.steps
        qd_all = self.plant.qd
        speed = np.abs(qd_all[self._rows]).sum(axis=1)
        self._gap -= self._travel * np.maximum(speed, self._speed)
        self._speed = speed
        near = np.flatnonzero(self._gap < MARGIN_M)
        self._force.fill(0.0)  # (off their walls: none)
        if not near.size:
            return
        q_all = self.plant.q
        rows, ids, walls = self._rows, self._ids, self._walls
        for i in near.tolist():
            tracked = walls[int(ids[i])]
            r = int(rows[i])
            depth, force = self._push(tracked, q_all[r].tolist(), qd_all[r].tolist())
            self._gap[i] = depth
            self._force[i] = force
            if tracked.peak is not None and force > tracked.peak:
                tracked.peak = force

    def _rebuild(self, plant_ids: np.ndarray) -> None:
        """The tracked arms' rows again (arms joined or left, walls set or read)."""
        row_of = {int(a): r for r, a in enumerate(plant_ids.tolist())}
        for arm in [a for a in self._walls if a not in row_of]:  # left without forget()
            del self._walls[arm]
        self._read &= row_of.keys()
        ids = [a for a, w in self._walls.items() if w.peak is not None]
        self._ids = np.array(ids, dtype=np.int64)
        self._index = {a: i for i, a in enumerate(ids)}
        self._rows = np.array([row_of[a] for a in ids], dtype=np.int64)
        self._gap = np.full(len(ids), -np.inf)  # (worked out at this step)
        self._speed = np.zeros(len(ids))
        self._force = np.zeros(len(ids))
        self._plant_ids = plant_ids
        self._stale = False

    def _push(self, tracked: _Tracked, q: list[float], qd: list[float]) -> tuple[float, float]:
        """(the hand's distance to the plane m, negative behind it; the wall's push N) at
        (q, qd) (n,) (Plant's ``wall_force``: its arithmetic in its order)."""
        fr = self._dyn.frames(q)
        o = self._last
        px, py, pz = self._tip
        p = (fr[o] * px + fr[o + 1] * py + fr[o + 2] * pz + fr[o + 9],
             fr[o + 3] * px + fr[o + 4] * py + fr[o + 5] * pz + fr[o + 10],
             fr[o + 6] * px + fr[o + 7] * py + fr[o + 8] * pz + fr[o + 11])
        origin, nrm, wall = tracked.origin, tracked.normal, tracked.setting
        # (sums written out left to right: the bits of Plant's sum(), which starts at 0)
        depth = ((p[0] - origin[0]) * nrm[0] + (p[1] - origin[1]) * nrm[1]
                 + (p[2] - origin[2]) * nrm[2])
        if depth >= 0.0:
            return depth, 0.0
        vx = vy = vz = 0.0  # the hand's velocity J q̇, Plant's sum over joints in order
        for j, w in enumerate(qd):
            a = self._dyn.axes[j]
            b = 12 * j
            z0 = fr[b] * a[0] + fr[b + 1] * a[1] + fr[b + 2] * a[2]
            z1 = fr[b + 3] * a[0] + fr[b + 4] * a[1] + fr[b + 5] * a[2]
            z2 = fr[b + 6] * a[0] + fr[b + 7] * a[1] + fr[b + 8] * a[2]
            rx, ry, rz = p[0] - fr[b + 9], p[1] - fr[b + 10], p[2] - fr[b + 11]
            vx += (z1 * rz - z2 * ry) * w
            vy += (z2 * rx - z0 * rz) * w
            vz += (z0 * ry - z1 * rx) * w
        vn = vx * nrm[0] + vy * nrm[1] + vz * nrm[2]
        return depth, max(0.0, -wall.stiffness * depth - wall.damping * vn)
