"""N simulated quadrupeds of one model stepped together: ``QuadrupedSimBackend``, numpy over
robots.

A classroom gives every student a private quadruped (12 AX-12A: legs RF, LF, RH, LH, each
hip yaw, hip pitch, knee). Instead of N ``QuadrupedSimBackend`` objects (four ``Plant``
each, stepped in Python), :class:`BatchedQuadrupeds` keeps one
:class:`armlab.hardware.families.dynamixel1.batched_plant.BatchedPlant` per group of legs with the
same dynamics
(:func:`leg_groups`, checked when the batch is made: every field of the leg chains but
names and hip mounts, and the servos: :func:`same_dynamics`), every robot an arm per leg
in its group's plant. The lab's model mirrors its left legs (axes and y reversed), so RF
and RH share a plant of 2N arms, LF and LH another; a model whose four legs were alike
would get one plant of 4N arms, one whose legs all differ four of N. A robot's arms
interleave in a shared plant by join order; each leg's rows are kept per robot row
(:class:`BatchedLeg`), renewed as robots join and leave. The batch carries every robot's
body as :class:`armlab.hardware.families.dynamixel1.quadruped.BodyOnLegs` does, for all robots at
once:

1. every :data:`~armlab.hardware.families.dynamixel1.quadruped.LOAD_STEP` s of a robot's own time
   (from the step
   it joined) the floor plane its body rests on is found from where its feet really are
   (:func:`armlab.kinematics.body_statics.rest_planes`, the vectorised ``rest_plane``), its weight
   is shared among the feet that touch it (:func:`~armlab.kinematics.body_statics.floor_forces`,
   the vectorised ``contact_forces``) and each contact foot is pushed by its share along
   the floor's normal for LOAD_STEP (one :meth:`BatchedPlant.push_rows` per leg for all
   robots due, on that leg's arm rows); a robot whose servos let go (any torque off) sits
   down on its body, as does one whose feet no longer reach below its belly;
2. then every plant steps once (:meth:`BatchedPlant.step`).

The semantics are those of N ``QuadrupedSimBackend`` each synced to multiples of
LOAD_STEP of its own time (the lesson's gait loop syncs every 20 ms):
tests/test_batched_quadruped.py checks q, qd to 1e-9 and the servos' reports exactly.
One difference: ``QuadrupedSimBackend.sync(t)`` renews the load at ``t`` too when ``t`` is
not a multiple of LOAD_STEP of its time; here the renewals are every LOAD_STEP of the
robot's time whatever its loop syncs to.

:class:`BatchedQuadrupedBackend` is one robot of a batch behind the
:class:`armlab.control.backend.Backend` protocol (12 joints, as ``QuadrupedSimBackend``), for a
:class:`armlab.control.gait_loop.GaitLoop`. As
:class:`armlab.hardware.families.dynamixel1.batched_backend.BatchedArmBackend`,
its ``sync`` does not step the batch (one clock thread steps it for every robot; ``sync``
waits until the batch has reached the loop's time) unless it is made with ``drive=True``
(a batch without a clock: ``sync`` steps the whole batch, every robot in it, to the time;
loops that take turns write every robot's goals before the first of them syncs).
A :class:`armlab.control.gait_loop.GaitLoop` runs on a pacer of its own (it has no ``clock=`` as
``ControlLoop`` has): with a clock stepping the batch in another thread its ``sync`` waits
for the clock, and reads the batch where the clock has put it.

Cost: no per-robot Python call is left in a step. The load is one call for the robots
due (~0.6 ms for 1 robot, ~0.9 ms for 100 on the lab's machine), every LOAD_STEP per
phase of joining (robots that joined 1..4 steps apart at dt = 2 ms renew at different
steps); the rest is the plants' steps, mostly numpy's fixed cost per call whatever the
arms, so two plants of 2N arms cost little more than two of N, far less than four. At
the class's 5 ms step (a shared, busy 2-core machine, the fastest of 15 runs of 40 steps)
a step of the lab's model unloaded took ~0.27 ms for 1 robot and ~0.8 ms for 30 (four
plants of N: ~0.4 and ~1.6 ms), loaded ~0.9 and ~1.5 ms (four plants: ~1.3 and ~2.5 ms);
``armlab.app.benches.classroom.quadrupeds_cost``, the trot on the class's clock, went from 0.31
to 0.23 wall s per simulated s for 1 robot and from 0.94 to 0.66 for 30 (medians of 9).

Frames and units: forces and points as ``QuadrupedSimBackend``'s (each leg's hip-mount
frame, the body frame's axes), N, m, s; joint angles rad, legs in order.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from armlab.control.backend import BackendError, GoalLimits, JointState
from armlab.control.batch_rows import BatchRows
from armlab.hardware.families.dynamixel1.batched_backend import (
    add_sim_arm,
    decode_words,
    reset_sim_arm,
    word_tables,
)
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant, ReportWords
from armlab.hardware.families.dynamixel1.quadruped import (
    BELLY_RAMP,
    LEG_JOINTS,
    LOAD_STEP,
    G,
    total_mass,
)
from armlab.hardware.families.dynamixel1.sim_backend import raw_goals, servo_limits
from armlab.hardware.servos.servo_spec import AX12A, ServoSpec
from armlab.kinematics.body_statics import feet_and_coms, floor_forces, rest_planes
from armlab.kinematics.model import Quadruped, SerialChain
from armlab.kinematics.quadruped import LEGS, QuadrupedGeometry, foot_in_tibia
from armlab.kinematics.validate import index, scalar, vector

if TYPE_CHECKING:
    from armlab.control.periodic import HandOverLock

#: The link each foot is on (the tibia).
FOOT_LINK = LEG_JOINTS - 1
#: SerialChain fields that do not move a leg's plant: names, the viewer's files, and the
#: hip mount (``base_pose``: a plant works in its leg's base frame, forces and points too).
_NOT_DYNAMICS = frozenset({"name", "base_pose", "urdf_path", "link_names", "package_paths"})


def _equal(a: Any, b: Any) -> bool:  # any two field values
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if dataclasses.is_dataclass(a) and type(a) is type(b):  # a Joint, a Link: but its name
        return all(_equal(getattr(a, f.name), getattr(b, f.name))
                   for f in dataclasses.fields(a) if f.name != "name")
    return bool(a == b)


def same_dynamics(a: SerialChain, b: SerialChain) -> bool:
    """Whether leg chains ``a`` and ``b`` move alike in a :class:`BatchedPlant`: every field
    of the chains, of their joints (kind, origin, axis, limits, velocity, effort) and links
    (mass, COM, inertia), their tips and gravity equal exactly; only names, viewer files
    and the hip mount (``base_pose``) may differ. Every field not known to be harmless is
    compared, so a field added to the model later keeps legs apart until listed."""
    return type(a) is type(b) and all(
        _equal(getattr(a, f.name), getattr(b, f.name))
        for f in dataclasses.fields(a) if f.name not in _NOT_DYNAMICS)


def leg_groups(chains: Sequence[SerialChain], specs: Sequence[Sequence[ServoSpec]],
               directions: Sequence[Sequence[float]]) -> tuple[tuple[int, ...], ...]:
    """The legs (indices into ``chains``) that can share one :class:`BatchedPlant`: same
    dynamics (:func:`same_dynamics`), same servos (``specs``) and directions per joint.
    Groups in the order of their first leg, legs in order within a group."""
    groups: list[list[int]] = []
    for k, chain in enumerate(chains):
        for g in groups:
            j = g[0]
            if (same_dynamics(chains[j], chain) and tuple(specs[j]) == tuple(specs[k])
                    and tuple(map(float, directions[j])) == tuple(map(float, directions[k]))):
                g.append(k)
                break
        else:
            groups.append([k])
    return tuple(tuple(g) for g in groups)


# -- the robots ---------------------------------------------------------------------------

class BatchedLeg:
    """Leg ``index`` (``model.legs`` order) of every robot of a batch: its arms in its
    group's :class:`BatchedPlant`, read in robot rows and written by robot id.

    Attributes:
        batch: the :class:`BatchedQuadrupeds`. index: the leg's place (0..3). name: "RF", ...
        plant: the plant its arms are in (shared with the legs of the same dynamics).
        model: the leg's own chain. specs, directions: its servos (per joint).
    """

    def __init__(self, batch: BatchedQuadrupeds, index: int, name: str, plant: BatchedPlant,
                 model: SerialChain, specs: Sequence[ServoSpec],
                 directions: Sequence[float]) -> None:
        self.batch = batch
        self.index = index
        self.name = name
        self.plant = plant
        self.model = model
        self.specs = tuple(specs)
        self.directions = tuple(float(d) for d in directions)
        self.n = LEG_JOINTS

    @property
    def rows(self) -> np.ndarray:
        """(N,) the plant row of this leg's arm of the robot in each robot row."""
        return self.batch._leg_rows[self.index].copy()

    def arm(self, robot: int) -> int:
        """The id, in :attr:`plant`, of robot ``robot``'s arm for this leg."""
        return self.batch._arm(robot, self.index)

    @property
    def q(self) -> np.ndarray:
        """(N, 3) this leg's true joint positions, rad, robot rows."""
        return self.plant.q[self.batch._leg_rows[self.index]]

    def register(self, name: str) -> np.ndarray:
        """(N, 3) register ``name`` of this leg's servos, robot rows."""
        return self.plant.register(name)[self.batch._leg_rows[self.index]]

    def present_position(self) -> np.ndarray:
        """(N, 3) Present Position words of this leg's servos, robot rows."""
        return self.plant.present_position()[self.batch._leg_rows[self.index]]

    def push(self, robot: int, force: np.ndarray, *, link: int, point: np.ndarray,
             duration: float) -> None:
        """:meth:`BatchedPlant.push` on robot ``robot``'s leg (the leg's hip-mount frame)."""
        self.plant.push(self.arm(robot), force, link=link, point=point, duration=duration)

    def set_spring(self, robot: int, anchor: np.ndarray | None, *, stiffness: float,
                   link: int, point: np.ndarray) -> None:
        """:meth:`BatchedPlant.set_spring` on robot ``robot``'s leg (hip-mount frame)."""
        self.plant.set_spring(self.arm(robot), anchor, stiffness=stiffness, link=link,
                              point=point)


class BatchedQuadrupeds:
    """N simulated quadrupeds of one model (AX-12A servos), stepped together at ``dt``.

    Args:
        model: the quadruped (``kinematics.load_robot("quadruped")``).
        dt: plant step and servo tick, s; LOAD_STEP must be a whole number of steps.
        body_mass: kg every robot's feet carry (default the whole robot; 0: legs unloaded).
        belly: m from the body frame's origin down to the body's underside (BodyOnLegs').

    Attributes:
        plants: one :class:`BatchedPlant` per group of legs with the same dynamics and
            servos (:func:`leg_groups`; the lab's model: RF+RH, LF+LH), each robot an arm
            per leg of the group in it.
        groups: per plant the legs (indices, ``model.legs`` order) whose arms it holds.
        legs: the four :class:`BatchedLeg`, ``model.legs`` order (each robot's arm of
            that leg, read in robot rows).
        weight: N each robot's feet carry.

    Robots are named by a stable id (:meth:`add`); rows are the robots in the order they
    joined (as a BatchedPlant's arms). A robot's arms (:meth:`arms_of`) have ids of their
    own in their plants; in a plant of several legs the robots' arms interleave by join
    order, and the rows of each leg's arms are kept per robot row (:attr:`BatchedLeg.rows`,
    renewed as robots join and leave). Not thread-safe: the owner holds a lock around
    every use (the backends take the one they are given).
    """

    def __init__(self, model: Quadruped, *, dt: float = 1e-3, body_mass: float | None = None,
                 belly: float = QuadrupedGeometry().body_size[2] / 2) -> None:
        if not isinstance(model, Quadruped):
            raise ValueError("model: BatchedQuadrupeds needs a Quadruped")
        self.model = model
        chains = list(model.legs.values())
        specs = [(AX12A,) * LEG_JOINTS for _ in chains]  # as QuadrupedSimBackend's legs
        directions = [(1.0,) * LEG_JOINTS for _ in chains]
        self.groups = leg_groups(chains, specs, directions)
        self.plants = tuple(BatchedPlant(chains[g[0]], specs[g[0]], dt=dt,
                                         directions=directions[g[0]]) for g in self.groups)
        plant_of = {k: i for i, g in enumerate(self.groups) for k in g}
        self._plant_of_leg = tuple(plant_of[k] for k in range(len(chains)))
        self.legs = tuple(BatchedLeg(self, k, name, self.plants[plant_of[k]], chain, specs[k],
                                     directions[k])
                          for k, (name, chain) in enumerate(model.legs.items()))
        self.dt = self.plants[0].dt
        every = LOAD_STEP / self.dt
        if abs(every - round(every)) > 1e-9:
            raise ValueError(f"dt must divide LOAD_STEP = {LOAD_STEP} s, got {dt}")
        self.load_every = int(round(every))  #: steps between load renewals
        self.belly = scalar("belly", belly, nonnegative=True)
        self.weight = G * (total_mass(model) if body_mass is None
                           else scalar("body_mass", body_mass, nonnegative=True))
        self._feet_points = [foot_in_tibia(leg) for leg in LEGS]
        limits = [servo_limits(leg.model, leg.specs, leg.directions) for leg in self.legs]
        self.lower = np.concatenate([lo for lo, _ in limits])  #: (12,) rad, servo limits
        self.upper = np.concatenate([hi for _, hi in limits])  #: (12,) rad
        self._rows = BatchRows()  # the robots' ids in row order
        self._arms: dict[int, tuple[int, ...]] = {}  # robot id -> its arm id per leg
        self._robot_of: list[dict[int, int]] = [{} for _ in self.plants]  # arm id -> robot
        self._leg_rows = np.zeros((len(self.legs), 0), dtype=np.int64)  # (4, N) plant rows
        self._k0 = np.zeros(0, dtype=np.int64)  # the step each robot joined at
        self._tilt = np.zeros(0)
        self._contact = np.zeros((0, len(self.legs)), dtype=bool)
        self._forces = np.zeros((0, len(self.legs)))

    # -- robots ---------------------------------------------------------------------

    @property
    def n_robots(self) -> int:
        """N, the number of robots."""
        return len(self._rows)

    @property
    def ids(self) -> np.ndarray:
        """(N,) the id of the robot in each row."""
        return np.array(self._rows.ids, dtype=np.int64)

    def row(self, robot: int) -> int:
        """The row of robot id ``robot``; ValueError when there is no such robot."""
        if (not isinstance(robot, bool) and isinstance(robot, int | np.integer)
                and int(robot) in self._arms):
            return self._rows.row(int(robot))
        raise ValueError(f"robot must be a robot id in this batch (ids: "
                         f"{list(self._rows.ids)}), got {robot!r}")

    def arms_of(self, robot: int) -> tuple[tuple[BatchedPlant, int], ...]:
        """Robot ``robot``'s arms: per leg (``model.legs`` order) its plant and arm id."""
        self.row(robot)
        return tuple((leg.plant, arm) for leg, arm in zip(self.legs, self._arms[int(robot)],
                                                           strict=True))

    def _arm(self, robot: int, leg: int) -> int:
        self.row(robot)
        return self._arms[int(robot)][leg]

    def add(self, q0: Sequence[float] | np.ndarray | None = None, *,
            torque_on: bool = True) -> int:
        """A new robot at ``q0`` (12,) rad (default zeros), at rest, its servos as a fresh
        ``QuadrupedSimBackend``'s (thesis registers, Angle Limits at the joint limits, goal
        at ``q0``; torque on unless ``torque_on`` is False). Its time starts now. Returns
        its id."""
        n = LEG_JOINTS * len(self.legs)
        q = np.zeros(n) if q0 is None else vector("q0", q0, n)
        arms: list[int] = []
        try:
            for k, leg in enumerate(self.legs):
                arms.append(add_sim_arm(leg.plant, q0=q[LEG_JOINTS * k:LEG_JOINTS * (k + 1)],
                                        torque_on=torque_on))
        except BaseException:
            for leg, arm in zip(self.legs, arms, strict=False):
                leg.plant.remove_arm(arm)
            raise
        robot = self._rows.join()
        self._arms[robot] = tuple(arms)
        for k, arm in enumerate(arms):
            self._robot_of[self._plant_of_leg[k]][arm] = robot
        self._k0 = np.append(self._k0, self.steps)
        self._tilt = np.append(self._tilt, 0.0)
        self._contact = np.vstack([self._contact, np.ones((1, len(self.legs)), dtype=bool)])
        self._forces = np.vstack([self._forces, np.zeros((1, len(self.legs)))])
        self._reindex()
        return robot

    def reset(self, robot: int, q0: Sequence[float] | np.ndarray | None = None, *,
              torque_on: bool = True) -> None:
        """Robot ``robot`` made again in its row, under its id, as :meth:`add` makes a new
        one: at ``q0`` (12,) rad (default zeros), at rest, its servos fresh (torque on
        unless ``torque_on`` is False), its pushes and springs gone, its body resting as
        a new robot's, and its time started again now (its load renewed from this step,
        as a robot that joined now)."""
        r = self.row(robot)
        n = LEG_JOINTS * len(self.legs)
        q = np.zeros(n) if q0 is None else vector("q0", q0, n)
        for k, (leg, arm) in enumerate(zip(self.legs, self._arms[int(robot)], strict=True)):
            reset_sim_arm(leg.plant, arm, q0=q[LEG_JOINTS * k:LEG_JOINTS * (k + 1)],
                          torque_on=torque_on)
        self._k0[r] = self.steps
        self._tilt[r] = 0.0
        self._contact[r] = True
        self._forces[r] = 0.0

    def remove(self, robot: int) -> None:
        """Remove robot ``robot`` (its arms, pushes and springs); the rows after it move up."""
        r = self.row(robot)
        self._rows.leave(int(robot))
        arms = self._arms.pop(int(robot))
        for k, (leg, arm) in enumerate(zip(self.legs, arms, strict=True)):
            leg.plant.remove_arm(arm)
            del self._robot_of[self._plant_of_leg[k]][arm]
        self._k0 = np.delete(self._k0, r)
        self._tilt = np.delete(self._tilt, r)
        self._contact = np.delete(self._contact, r, axis=0)
        self._forces = np.delete(self._forces, r, axis=0)
        self._reindex()

    def _reindex(self) -> None:
        """Rows of the robots and, per leg, of their arms in its plant (after a join or a
        leave: the plants' rows moved)."""
        ids = self._rows.ids
        rows = np.empty((len(self.legs), len(ids)), dtype=np.int64)
        for p, legs in zip(self.plants, self.groups, strict=True):
            at = {arm: i for i, arm in enumerate(p.arm_ids.tolist())}
            for k in legs:
                rows[k] = [at[self._arms[robot][k]] for robot in ids]
        self._leg_rows = rows

    # -- state ----------------------------------------------------------------------

    @property
    def steps(self) -> int:
        """Steps taken since the batch was made."""
        return self.plants[0].steps

    @property
    def t(self) -> float:
        """The batch's time, s (steps · dt)."""
        return self.plants[0].t

    def time_of(self, robot: int) -> float:
        """Robot ``robot``'s own time: s since it joined."""
        return (self.steps - int(self._k0[self.row(robot)])) * self.dt

    def behind(self, robot: int, t: float) -> bool:
        """Whether the batch must step further for robot ``robot``'s time to reach ``t`` s
        (to within dt/2, as ``Plant.advance_to``)."""
        return (self.steps - int(self._k0[self.row(robot)]) + 0.5) * self.dt <= t

    def _per_leg(self, per_plant: Sequence[np.ndarray], rows: np.ndarray | None = None,
                 ) -> list[np.ndarray]:
        """Per leg the rows of its plant's (M, 3) array ``per_plant[i]`` for the robot rows
        ``rows`` (default all), each (R, 3), in robot rows."""
        leg_rows = self._leg_rows if rows is None else self._leg_rows[:, rows]
        return [per_plant[i][r] for i, r in zip(self._plant_of_leg, leg_rows, strict=True)]

    @property
    def q(self) -> np.ndarray:
        """(N, 12) true joint positions, rad, legs in order."""
        return np.concatenate(self._per_leg([p.q for p in self.plants]), axis=1)

    @property
    def qd(self) -> np.ndarray:
        """(N, 12) true joint velocities, rad/s."""
        return np.concatenate(self._per_leg([p.qd for p in self.plants]), axis=1)

    @property
    def tilt_deg(self) -> np.ndarray:
        """(N,) each body's tilt at its last load renewal, degrees."""
        return self._tilt.copy()

    @property
    def contact(self) -> np.ndarray:
        """(N, 4) which feet touched the floor then."""
        return self._contact.copy()

    @property
    def forces(self) -> np.ndarray:
        """(N, 4) the floor's normal force on each foot then, N."""
        return self._forces.copy()

    # -- forces ---------------------------------------------------------------------

    def leg_of(self, link: int) -> tuple[BatchedLeg, int]:
        """The leg of joint ``link`` (0..11) and the link in it."""
        k = index("link", link, LEG_JOINTS * len(self.legs))
        return self.legs[k // LEG_JOINTS], k % LEG_JOINTS

    def push(self, robot: int, force: np.ndarray, *, link: int, point: np.ndarray,
             duration: float) -> None:
        """Apply ``force`` (3,) N, the leg's hip-mount frame, at ``point`` (3,) m in link
        ``link``'s frame (0..11: leg ``link // 3``, its link ``link % 3``) of robot
        ``robot`` for ``duration`` s from now."""
        self.row(robot)
        leg, i = self.leg_of(link)
        leg.push(robot, force, link=i, point=point, duration=duration)

    def set_spring(self, robot: int, anchor: np.ndarray | None, *, stiffness: float,
                   link: int, point: np.ndarray) -> None:
        """Pull ``point`` on ``link`` (0..11) of robot ``robot`` towards ``anchor`` (3,) m,
        hip-mount frame, with ``stiffness`` N/m; None releases that leg's spring."""
        self.row(robot)
        leg, i = self.leg_of(link)
        leg.set_spring(robot, anchor, stiffness=stiffness, link=i, point=point)

    # -- stepping -------------------------------------------------------------------

    def step(self) -> None:
        """Renew the body load of the robots due (every LOAD_STEP of their time), then
        step every plant once. FloatingPointError naming the robots that diverged (after
        every plant has stepped)."""
        if self.weight > 0.0 and self._k0.size:
            due = np.flatnonzero((self.steps - self._k0) % self.load_every == 0)
            if due.size:
                self._load(due)
        bad: set[int] = set()
        for p, robot_of in zip(self.plants, self._robot_of, strict=True):
            try:
                p.step()
            except FloatingPointError:
                bad.update(robot_of[arm] for arm in p.diverged().tolist())
        if bad:
            raise FloatingPointError(f"robots {sorted(bad)} diverged at t = "
                                     f"{self.t:.3f} s")

    def advance_to(self, t: float) -> int:
        """Step until the batch's time reaches ``t`` s (to within dt/2); returns the steps."""
        target = scalar("t", t)
        steps = 0
        while (self.steps + 0.5) * self.dt <= target:
            self.step()
            steps += 1
        return steps

    def advance_robot_to(self, robot: int, t: float) -> int:
        """Step the batch (every robot) until robot ``robot``'s own time reaches ``t`` s."""
        target = scalar("t", t)
        steps = 0
        while self.behind(robot, target):
            self.step()
            steps += 1
        return steps

    def _load(self, rows: np.ndarray) -> None:
        """:meth:`BodyOnLegs.load` for the robots in ``rows`` (R,), for LOAD_STEP from now."""
        q = self._per_leg([p.q for p in self.plants], rows)
        holding = np.ones(rows.size, dtype=bool)
        for te in self._per_leg([p.register("torque_enable") for p in self.plants], rows):
            holding &= np.all(te != 0, axis=1)
        feet, com = feet_and_coms(self.model, q)
        n, d, contact, ok = rest_planes(feet, com)
        contact &= (ok & holding)[:, None]  # no plane, or a servo let go: the body sits down
        share = np.where(contact.any(axis=1),
                         np.clip((-d - self.belly) / BELLY_RAMP, 0.0, 1.0), 0.0)
        carried = share > 0.0
        contact &= carried[:, None]
        f = floor_forces(feet, com, share * self.weight, n, contact)
        duration = self.load_every * self.dt
        for i, leg in enumerate(self.legs):
            on = f[:, i] > 0.0
            if on.any():
                leg.plant.push_rows(self._leg_rows[i, rows[on]], f[on, i, None] * n[on],
                                    link=FOOT_LINK, point=self._feet_points[i],
                                    duration=duration)
        self._contact[rows], self._forces[rows] = contact, f
        self._tilt[rows] = np.where(carried, np.degrees(np.arccos(np.clip(n[:, 2], -1.0, 1.0))),
                                    0.0)


# -- one robot as a Backend ------------------------------------------------------------------

class RobotBody:
    """One robot's body in a batch, read as :class:`BodyOnLegs` is (``backend.body``):
    ``tilt_deg``, ``contact`` (4,), ``forces`` (4,) N at its last load renewal, ``weight``
    N, ``q()`` (12,) rad. Every read holds ``lock``."""

    def __init__(self, batch: BatchedQuadrupeds, robot: int,
                 lock: threading.RLock | HandOverLock) -> None:
        self.batch = batch
        self.robot = robot
        self.weight = batch.weight
        self._lock = lock

    @property
    def tilt_deg(self) -> float:
        with self._lock:
            return float(self.batch.tilt_deg[self.batch.row(self.robot)])

    @property
    def contact(self) -> np.ndarray:
        with self._lock:
            return self.batch.contact[self.batch.row(self.robot)]

    @property
    def forces(self) -> np.ndarray:
        with self._lock:
            return self.batch.forces[self.batch.row(self.robot)]

    def q(self) -> np.ndarray:
        """(12,) the legs' true joint angles now, rad."""
        with self._lock:
            return self.batch.q[self.batch.row(self.robot)]


class BatchedQuadrupedBackend(GoalLimits):
    """Robot id ``robot`` of ``batch`` behind the 12-joint ``Backend`` and ``Pushable``
    protocols, as :class:`QuadrupedSimBackend` (joints legs in order; goals clamped to the
    servos' limits; raw words written and read).

    Args:
        batch: the shared robots (the caller adds the robot first and removes it after
            :meth:`close`).
        robot: the robot's id in ``batch``.
        lock: held around every use of the batch (the shared clock holds it while it steps).
        drive: ``sync`` steps the whole batch itself (no clock); default: a clock steps it.
        wait_s: most wall time ``sync`` waits for the clock, s (then BackendError).

    Attributes:
        batch: the shared :class:`BatchedQuadrupeds`. model: its quadruped.
        body: this robot's :class:`RobotBody` (as ``QuadrupedSimBackend.body``).

    Time (``read().t``, ``sync``'s ``t``) is the robot's own (since it joined the batch).
    The torque limits restored by ``set_torque(True)`` after an overload shutdown are the
    robot's Torque Limit registers when the backend is made.
    """

    def __init__(self, batch: BatchedQuadrupeds, robot: int, *,
                 lock: threading.RLock | HandOverLock,
                 drive: bool = False, wait_s: float = 1.0) -> None:
        self.batch = batch
        self.model = batch.model
        self.robot = int(robot)
        self.drive = bool(drive)
        self.wait_s = scalar("wait_s", wait_s, nonnegative=True)
        self.body = RobotBody(batch, self.robot, lock)
        self._lock = lock
        self._lower, self._upper = batch.lower, batch.upper
        self._legs = [(leg.specs, leg.directions) for leg in batch.legs]
        self._tables = [word_tables(s, d) for specs, dirs in self._legs
                        for s, d in zip(specs, dirs, strict=True)]
        with lock:
            # per leg its plant and this robot's arm id in it (ids never change)
            self._arms = batch.arms_of(self.robot)
            self._torque_limits = [tuple(r.torque_limit for r in p.registers(arm))
                                   for p, arm in self._arms]
        self._t = 0.0
        self._closed = False

    # -- Backend protocol ---------------------------------------------------------

    @property
    def n(self) -> int:
        """Number of joints (12)."""
        return LEG_JOINTS * len(self.batch.legs)

    @property
    def t(self) -> float:
        """The loop time of the last :meth:`sync`, s."""
        return self._t

    def sync(self, t: float) -> None:
        """Bring the robot to loop time ``t`` s: ``drive``: step the batch (every robot)
        until then; else wait for the clock to have stepped it there (BackendError after
        ``wait_s``). A batch already past ``t`` is read where it is."""
        t = scalar("t", t)
        deadline = time.perf_counter() + self.wait_s
        while True:
            with self._lock:
                self._check_open()
                if self.drive:
                    self.batch.advance_robot_to(self.robot, t)
                if not self.batch.behind(self.robot, t):
                    self._t = t
                    return
                now = self.batch.time_of(self.robot)
            if time.perf_counter() >= deadline:
                raise BackendError(f"the batch did not reach t = {t:.3f} s (it is at "
                                   f"{now:.3f} s): is its clock running?")
            time.sleep(self.batch.dt / 2)

    def read(self) -> JointState:
        """Every servo's report, legs in order (decoded raw words, quantised)."""
        with self._lock:
            self._check_open()
            t = self.batch.time_of(self.robot)  # ValueError naming the robot when it left
            words = [p.report_words(arm) for p, arm in self._arms]
        merged = ReportWords(*([x for w in words for x in getattr(w, f)]
                               for f in ReportWords._fields))
        return decode_words(merged, self._tables, t)

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Goal positions (12,) rad and moving speeds (12,) rad/s, clamped per servo.

        Raises:
            ValueError: a wrong shape or a non-finite value (nothing is written).
        """
        p, s = self.checked_goal(position, speed)
        raw = [raw_goals(specs, dirs, p[LEG_JOINTS * k:LEG_JOINTS * (k + 1)],
                         s[LEG_JOINTS * k:LEG_JOINTS * (k + 1)])
               for k, (specs, dirs) in enumerate(self._legs)]
        with self._lock:
            self._check_open()
            self.batch.row(self.robot)
            for (plant, arm), (goals, speeds) in zip(self._arms, raw, strict=True):
                plant.set_goal(arm, goals, speeds)

    def set_torque(self, on: bool) -> None:
        """Torque Enable on all 12 servos; switching on restores a Torque Limit an overload
        shutdown set to 0 (as :meth:`SimBackend.set_torque`)."""
        with self._lock:
            self._check_open()
            self.batch.row(self.robot)
            for (plant, arm), limits in zip(self._arms, self._torque_limits, strict=True):
                for j, (r, limit) in enumerate(zip(plant.registers(arm), limits,
                                                   strict=True)):
                    if on and r.torque_limit == 0:
                        plant.set_registers(arm, j, torque_limit=limit)
                plant.set_registers(arm, torque_enable=int(bool(on)))

    def estop(self) -> bool:
        """Torque off on all 12 servos now; never raises. True (a robot already removed
        from the batch holds no torque either)."""
        with self._lock:
            for plant, arm in self._arms:
                try:
                    plant.set_registers(arm, torque_enable=0)
                except ValueError:  # the owner removed the robot (arm ids are never reused)
                    pass
        return True

    def close(self) -> None:
        """Release the backend; later calls raise BackendError (the robot stays in the
        batch, its torque as it is: the owner removes it)."""
        with self._lock:
            self._closed = True

    # -- Pushable -------------------------------------------------------------------

    def push(self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float) -> None:
        """Apply ``force`` (3,) N, in the leg's hip-mount frame, at ``point`` (3,) m in the
        frame of link ``link`` (0..11: leg ``link // 3``, its link ``link % 3``), for
        ``duration`` s of simulated time."""
        with self._lock:
            self.batch.push(self.robot, force, link=link, point=point, duration=duration)

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """Pull ``point`` on ``link`` (0..11) towards ``anchor`` (hip-mount frame); None
        releases that leg's spring."""
        with self._lock:
            self.batch.set_spring(self.robot, anchor, stiffness=stiffness, link=link,
                                  point=point)

    def _check_open(self) -> None:
        if self._closed:
            raise BackendError("the simulated quadruped is closed; open a new backend")


__all__ = ["BatchedLeg", "BatchedQuadrupeds", "BatchedQuadrupedBackend", "RobotBody",
           "FOOT_LINK", "leg_groups", "same_dynamics"]
