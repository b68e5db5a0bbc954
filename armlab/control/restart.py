"""A simulated arm that a challenge's run can start again from a pose at rest.

A challenge's judged run must be a function of the gains, the challenge and the robot
alone (issue 50 item 3), whatever the arm did before and however busy the machine is.
So its run does not start from where the arm happens to be: :class:`RestartableArm`
wraps a simulated backend (``make(q)`` opens a fresh one at ``q``, at rest: a new
``SimBackend``, or a new arm of a class's batched plant) and, asked to
(:meth:`RestartableArm.restart`), puts a fresh one in its place inside the loop's own
period, as follows (all in loop time, none of it on the wall clock):

1. ``restart(q, plan, post)`` arms it; the caller then posts ``Reset`` to the loop;
2. at every period's ``sync`` while armed the arm is made fresh again at ``q`` (so the
   periods before the Reset is applied leave nothing behind) and goals are not written;
3. the Reset's torque-on (``set_torque(True)``, the loop's ``_start``, in the period the
   Reset is applied) ends it: the controller starts at rest from the fresh arm's
   reading. That period's loop time is :attr:`RestartableArm.restarted_at`;
4. each ``(periods, command)`` of ``plan`` is posted (``post``) at the ``sync``
   ``periods + 1`` periods after that one, so the loop applies it ``periods + 2`` periods
   after the restart, whatever the wall clock did meanwhile.

A loop that applies its Reset before it syncs (the quadruped's
:class:`armlab.control.gait_loop.GaitLoop`: ``sync_first=False``) ends the restart at the
sync of the period its Reset is applied in, so both orders give the same restart period.
With ``period`` the backend in use is brought to whole numbers of periods from its start
(k · period, the same numbers for every run) rather than to the loop time less the
restart's (whose last bits depend on when the run was made).

Pushes and springs asked for while armed are dropped (the fresh arm starts unpushed). A
wall (:class:`armlab.control.backend.Touchable`) is the world's, not the arm's: the fresh
arm meets the wall the one it replaces had, or the one :meth:`RestartableArm.meet_wall`
names for the restart (a contact challenge's: never put in front of the old arm, whose
hand may be behind it).

:class:`Schedule` is the plan's part alone (commands timed in periods from an instant
the loop marks), for a loop that starts its own plant again (the hand's
:class:`armlab.control.grip_loop.GripLoop`).

A real (serial) arm cannot be put back: its challenge runs are judged from the run's
own start (where the arm was), and the lab says so.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from armlab.control.backend import Backend, JointState, Touchable, WallSetting


class Schedule:
    """Commands timed in loop periods from an instant the loop marks: :meth:`begin` at the
    restart's period, then :meth:`tick` at every later period posts each ``(periods,
    command)`` of the plan at the tick ``periods + 1`` after that one (the loop applies
    it at its next period: ``periods + 2`` periods after the restart). Not thread-safe:
    its owner's lock (or its loop's thread) calls it."""

    def __init__(self) -> None:
        self._plan: list[tuple[int, Any]] = []  #: (periods, a loop's command)
        self._post: Callable[[Any], None] | None = None
        self._since = 0  #: periods since :meth:`begin`

    def begin(self, plan: Sequence[tuple[int, Any]], post: Callable[[Any], None]) -> None:
        """The restart is this period: ``plan``'s commands go to ``post`` from the next."""
        self._plan = sorted(plan, key=lambda p: p[0])
        self._post, self._since = (post if self._plan else None), 0

    def tick(self) -> None:
        """One period later: post the commands due."""
        if self._post is None:
            return
        self._since += 1
        due = [c for k, c in self._plan if k < self._since]
        self._plan = [(k, c) for k, c in self._plan if k >= self._since]
        post = self._post
        if not self._plan:
            self._post = None
        for command in due:
            post(command)

    def cancel(self) -> None:
        """Post nothing more (the run was cut short)."""
        self._plan, self._post = [], None

    @property
    def pending(self) -> bool:
        """Commands are left to post."""
        return self._post is not None


class RestartableArm:
    """A simulated backend that :meth:`restart` replaces by a fresh one at a pose, at rest,
    in step with the loop (module docstring). Every other call goes to the backend in use.

    Args:
        make: opens a fresh backend at ``q`` (n,) rad, at rest, torque on (the old one is
            closed through ``drop`` when replaced).
        q0: the first backend's pose.
        drop: lets a replaced backend go (default: its ``close()``).
        period: the loop's period, s: the backend in use is brought to k · period from
            its start (module docstring; None: to the loop time less its start's).
        sync_first: the loop syncs before it applies a Reset (the arm's loop); False: it
            applies the Reset first (the quadruped's), and the restart ends at that
            period's sync.
    """

    def __init__(self, make: Callable[[np.ndarray], Backend], q0: np.ndarray, *,
                 drop: Callable[[Backend], None] | None = None,
                 period: float | None = None, sync_first: bool = True) -> None:
        self._make = make
        self._drop = drop or (lambda b: b.close())
        self._lock = threading.RLock()
        self.inner: Backend = make(np.asarray(q0, dtype=float))
        self._offset = 0.0  #: the loop time the backend in use started at
        self._t = 0.0
        self._armed: tuple[np.ndarray, list[tuple[int, Any]], Callable[[Any], None]
                           ] | None = None
        self._fresh = False  #: armed, and the backend in use was made at this period's sync
        self._schedule = Schedule()
        self._period = period
        self._syncs = 0  #: syncs of the backend in use since it was made
        self._sync_first = sync_first
        self._torque_asked = False  #: (sync_first False) a Reset's torque-on while armed
        self.restarts = 0  #: restarts done
        self.restarted_at: float | None = None  #: loop time of the last restart's period
        #: the wall the armed restart's fresh arm meets ((None,): none), or None: the old's
        self._wall_next: tuple[WallSetting | None] | None = None

    # -- restarting -------------------------------------------------------------------

    def restart(self, q: np.ndarray, plan: Sequence[tuple[int, Any]],
                post: Callable[[Any], None]) -> int:
        """Arm a restart at ``q`` (n,) rad (then post ``Reset`` to the loop); ``plan``'s
        commands go to ``post`` that many periods after it. Returns the restart's number
        (:attr:`restarts` reaches it once done)."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n,) or not np.all(np.isfinite(q)):
            raise ValueError(f"restart: the pose must be {self.n} finite angles, got {q!r}")
        with self._lock:
            self._armed = (q.copy(), sorted(plan, key=lambda p: p[0]), post)
            self._schedule.cancel()
            self._torque_asked = False
            return self.restarts + 1

    def meet_wall(self, wall: WallSetting | None) -> None:
        """The next restart's fresh arm meets ``wall`` (None: no wall) instead of the wall
        of the arm it replaces; the arm in use keeps its own until then."""
        with self._lock:
            self._wall_next = (wall,)

    @property
    def armed(self) -> bool:
        """A restart is asked for and not done yet."""
        return self._armed is not None

    def sync(self, t: float) -> None:
        """The loop's period at loop time ``t``: armed, a fresh arm at the pose; else the
        backend in use brought to ``t``, and the plan's due commands posted."""
        with self._lock:
            self._t = float(t)
            if self._armed is not None:
                old, self.inner = self.inner, self._make(self._armed[0])
                _carry_wall(old, self.inner, self._wall_next)
                self._drop(old)
                self._offset, self._fresh, self._syncs = self._t, True, 0
                if self._torque_asked:  # the Reset came before this sync (sync_first False)
                    self._end()
            else:
                self._syncs += 1
                self._schedule.tick()
            if self._period is None:
                self.inner.sync(self._t - self._offset)
            else:
                self.inner.sync(self._syncs * self._period)

    def set_torque(self, on: bool) -> None:
        """Torque on or off; the torque-on of the Reset that follows a fresh arm ends the
        restart (module docstring, 3)."""
        with self._lock:
            self.inner.set_torque(on)
            if on and self._armed is not None:
                if not self._sync_first:
                    self._torque_asked = True  # ended at this period's sync, still to come
                elif self._fresh:
                    self._end()

    def _end(self) -> None:
        """The restart is done in this period: the plan from the next (holding the lock)."""
        assert self._armed is not None
        _, plan, post = self._armed
        self._armed, self._fresh, self._torque_asked = None, False, False
        self._wall_next = None
        self._schedule.begin(plan, post)
        self.restarted_at = self._t
        self.restarts += 1

    def cancel(self) -> None:
        """Post nothing more of the last restart's plan (the run was cut short); a restart
        still armed gives its fresh arm the old arm's wall, not one :meth:`meet_wall`
        named."""
        with self._lock:
            self._schedule.cancel()
            self._wall_next = None

    # -- the Backend protocol, to the backend in use ------------------------------------

    @property
    def n(self) -> int:
        return self.inner.n

    @property
    def lower(self) -> np.ndarray:
        return self.inner.lower

    @property
    def upper(self) -> np.ndarray:
        return self.inner.upper

    def read(self) -> JointState:
        with self._lock:
            return self.inner.read()

    def write(self, position: np.ndarray, speed: np.ndarray) -> None:
        """Goals to the backend in use (none while armed: the fresh arm holds its pose)."""
        with self._lock:
            if self._armed is None:
                self.inner.write(position, speed)

    def estop(self) -> bool:
        with self._lock:
            return self.inner.estop()

    def close(self) -> None:
        with self._lock:
            self.inner.close()

    def push(self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float) -> None:
        """A push on the backend in use (none while armed: the fresh arm starts unpushed,
        even by a push applied in the Reset's period before the Reset)."""
        with self._lock:
            if self._armed is not None:
                return
            self.inner.push(force, link=link, point=point, duration=duration)  # type: ignore[attr-defined]  # a restartable arm is simulated: it can be pushed

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """A spring on the backend in use (none while armed, as :meth:`push`)."""
        with self._lock:
            if self._armed is not None:
                return
            self.inner.set_spring(anchor, stiffness=stiffness, link=link,  # type: ignore[attr-defined]  # a restartable arm is simulated: it has a spring
                                  point=point)

    def __getattr__(self, name: str) -> Any:
        """Anything else (``plant``, ``specs``, ``checked_goal``, a batched arm's ``arm``)
        from the backend in use."""
        if name.startswith("__") or name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)


def _carry_wall(old: Backend, new: Backend,
                named: tuple[WallSetting | None] | None = None) -> None:
    """The wall of ``old``'s world (if any), or the one ``named`` ((wall,) of
    :meth:`RestartableArm.meet_wall`), put into ``new``'s: an arm started again meets the
    same wall (the Contact tab's across any challenge's restart) or the challenge's."""
    if not isinstance(old, Touchable) or not isinstance(new, Touchable):
        return
    wall = old.wall_setting() if named is None else named[0]
    if wall is not None:
        new.set_wall(wall.origin, wall.normal, stiffness=wall.stiffness, damping=wall.damping,
                     friction=wall.friction, size=wall.size)
