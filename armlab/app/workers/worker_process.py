"""Simulated arms in a process of their own, mirrored into the server.

A class of 30 private arms stepped at 1 kHz (:class:`armlab.app.workers.class_arms.ClassArms`)
costs about a third of one interpreter's time, and a paced control loop (the classroom's shared
arm) waits for the GIL behind every thread of the server: the pages' publishers, the
web server's event loop. So in a classroom these run in worker processes (a fresh
interpreter, ``python -m armlab.app.workers.worker``, talking over a socket pair as a
``multiprocessing`` connection), each on a core the OS gives it, and the server keeps,
per arm, what a lesson reads of it. One worker runs the class (``kind="class"``: the
batched plants on one clock), another the shared arm (``kind="own"``:
:class:`armlab.app.workers.class_arms.OwnArms`, a ``SimBackend`` and a paced loop).

- :class:`RemoteLoop`: the ``ControlLoop`` surface a lesson uses. ``status``,
  ``recorder`` (a :class:`armlab.control.recorder.Recorder` the worker's rows are copied into),
  ``spare_joints`` and ``gripper`` are mirrored: the worker sends every arm's status and
  new rows every :data:`MIRROR_S` s in one message. ``post``, ``set_params`` go to the
  worker's loop and wait for its answer, so a refused command raises here as it would in
  process.
- :class:`RemoteBackend`: E-STOP, the hand's push and drag, the arm's wall
  (``Touchable``: set and read as calls, its force from the mirrored record), a
  challenge's restart, each a call the worker answers; the Servos panel's
  ``plant.reports()`` are mirrored too, every :data:`REPORTS_S` s (a page's frame never
  waits for the worker).
- :class:`armlab.app.workers.remote_hand.RemoteHand`,
  :class:`armlab.app.workers.remote_gait.RemoteGait`: a student's
  copy of the thesis's hand and of the seed 003 quadruped, one of the class worker's
  :class:`armlab.app.workers.class_hands.ClassHands` or
  :class:`armlab.app.workers.class_quadrupeds.ClassQuadrupeds`,
  mirrored the same way (their messages are listed there).

The worker's side is :mod:`armlab.app.workers.worker`. A call waits at most
:data:`CALL_TIMEOUT_S` s
(E-STOP: :data:`ESTOP_TIMEOUT_S`). When a worker ends (killed, crashed), its arms' status
says so as a fault and calls raise ``BackendError``: the server and the other lessons go
on.

Messages (tuples; the server's ``Connection`` end sends calls, the worker's answers)::

    server -> worker   (op, call_id, arm_id, *args)      op: add, post, set_params,
                                                         estop, push, spring, read, free,
                                                         restart, restarted, cancel, wall,
                                                         wall_setting, meet_wall;
                                                         hand_add, hand_post, hand_free,
                                                         quad_add, quad_post, quad_estop,
                                                         quad_restart, quad_cancel, quad_free
                       ("close",)
    worker -> server   ("ready", scheduling)
                       ("reply", call_id, ok, value)     value: result or exception
                       ("mirror", [(arm_id, status, rows, capacity, spare, gripper,
                                    reports or None)...])
                       ("hand", [...]), ("quad", [...])
                       (armlab.app.workers.remote_hand, remote_gait)
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import os
import pickle
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np

import armlab
from armlab.app.workers.class_arms import Arm
from armlab.app.workers.remote_gait import RemoteGait
from armlab.app.workers.remote_hand import RemoteHand
from armlab.app.workers.worker_link import CALL_TIMEOUT_S, ESTOP_TIMEOUT_S
from armlab.control.backend import BackendError, GripperState, JointState, WallSetting
from armlab.control.commands import Command, EStop, UseSpareJoints
from armlab.control.grip import GripParams
from armlab.control.loop import LoopStatus
from armlab.control.params import GainCheck, Params
from armlab.control.recorder import Recorder
from armlab.control.walking import GaitSpec
from armlab.hardware.families.dynamixel1.firmware import ServoReport
from armlab.hardware.sim.hand_plant import GraspObject
from armlab.kinematics.model import SerialChain

#: s between two mirror messages (every arm's new rows and status)
MIRROR_S = 0.02
#: what else a class's worker runs besides arms: a kind's proxy, ops (``KIND_add``,
#: ``KIND_post``, ``KIND_free``) and mirror message are named by it
MEMBER_KINDS = (RemoteHand.KIND, RemoteGait.KIND)
#: what a freed arm's calls and reports say (the worker's side says the same)
FREED = "this arm was freed (a reload of the page makes a new one)"
#: s between two mirrors of the arms' servo reports (the Servos panel shows them every s)
REPORTS_S = 0.5
#: s without a mirror message after which a worker's arms are told as not answering
STALE_S = 5.0
#: what a worker runs: the class's private arms on one clock, or arms on threads of their own
KINDS = ("class", "own")
#: s the worker may take to start (a spawned interpreter imports numpy and the lab)
START_TIMEOUT_S = 120.0


class RemoteLoop:
    """An arm's :class:`armlab.control.loop.ControlLoop`, running in a worker process,
    as a lesson uses it (see the module docstring).

    Attributes:
        model: the arm. lower, upper: (n,) rad, the loop's joint limits.
        recorder: the mirror of the loop's recorder (``snapshot``, ``to_csv``).
    """

    def __init__(self, owner: ArmProcess, arm_id: int, model: SerialChain, gains: GainCheck,
                 *, lower: np.ndarray, upper: np.ndarray, capacity: int,
                 status: LoopStatus, reports: tuple[ServoReport, ...] | None) -> None:
        self._owner = owner
        self.arm_id = arm_id
        self.model = model
        self.lower = lower
        self.upper = upper
        self.recorder = Recorder(model.n, capacity, joint_names=model.joint_names)
        self._gains = gains
        self._status = status
        self._spare = UseSpareJoints("off")
        self._gripper: GripperState | None = None
        self._reports = reports

    @property
    def params(self) -> Params:
        """The parameters in force (as set through this proxy)."""
        return self._gains.params

    @property
    def gains(self) -> GainCheck:
        """What the worker's loop said of the parameters in force (:meth:`ControlLoop.gains`)."""
        return self._gains

    def set_params(self, params: Params) -> GainCheck:
        """:meth:`ControlLoop.set_params` in the worker (refused gains raise ValueError)."""
        self._gains = self._owner.call("set_params", self.arm_id, params)
        return self._gains

    def post(self, command: Command) -> None:
        """:meth:`ControlLoop.post` in the worker (not a command: ValueError). An E-STOP
        waits at most :data:`ESTOP_TIMEOUT_S` s for its answer (then BackendError)."""
        timeout = ESTOP_TIMEOUT_S if isinstance(command, EStop) else CALL_TIMEOUT_S
        self._owner.call("post", self.arm_id, command, timeout=timeout)

    @property
    def status(self) -> LoopStatus:
        """The loop's newest status (about :data:`MIRROR_S` s old); a fault once the
        worker has ended, or while it has sent nothing for :data:`STALE_S` s (stopped,
        or starved of CPU: what the arm does then is not known here)."""
        why = self._owner.ended or self._owner.silent()
        st = self._status
        if why is not None:
            return dataclasses.replace(st, running=False, active=False, fault=why)
        return st

    @property
    def spare_joints(self) -> UseSpareJoints:
        return self._spare

    @property
    def gripper(self) -> GripperState | None:
        return self._gripper

    def start(self) -> None:
        """Nothing: the loop runs from the moment it was made."""

    def shutdown(self, *, torque_off: bool = False, timeout: float = 2.0) -> None:
        """Free the arm in the worker (its loop stops with torque off)."""
        self._owner.free_id(self.arm_id)

    def _mirror(self, status: LoopStatus, rows: np.ndarray, capacity: int,
                spare: UseSpareJoints, gripper: GripperState | None,
                reports: tuple[ServoReport, ...] | None) -> None:
        if capacity != self.recorder.capacity:
            self.recorder.resize(capacity)
        if len(rows):
            self.recorder.extend(rows)
        self._status = status
        self._spare = spare
        self._gripper = gripper
        if reports is not None:
            self._reports = reports


class RemotePlant:
    """The Servos panel's view of a private arm's simulated servos."""

    def __init__(self, loop: RemoteLoop) -> None:
        self._loop = loop

    def reports(self) -> tuple[ServoReport, ...]:
        """The arm's servo reports in joint order (raw words), as last mirrored (at most
        about :data:`REPORTS_S` s old).

        Raises:
            BackendError: the worker has ended or is silent, or the arm was freed.
        """
        owner = self._loop._owner
        why = owner.ended or owner.silent()
        if why is None and not owner.holds(self._loop.arm_id):
            why = FREED
        reports = self._loop._reports
        if why is None and reports is None:
            why = "these simulated servos give no reports"
        if why is not None:
            raise BackendError(why)
        assert reports is not None  # why is None: the loop has reports
        return reports


class RemoteBackend:
    """An arm's backend in a worker process: what a lesson calls on it.

    Implements ``armlab.control.backend.Pushable`` and ``Touchable`` (the wall in the
    worker's world, the arm's own); ``plant.reports()`` as a simulated backend's.
    """

    def __init__(self, owner: ArmProcess, loop: RemoteLoop) -> None:
        self._owner = owner
        self._loop = loop
        self.arm_id = loop.arm_id
        self.n = loop.model.n
        self.plant = RemotePlant(loop)
        self._peak_read = -np.inf  #: loop time of the newest row :meth:`wall_peak` read

    def read(self) -> JointState:
        """Every joint as its servo reports it (the worker's ``read()``)."""
        return self._owner.call("read", self.arm_id)

    def estop(self) -> bool:
        """Torque off on every servo of this arm now; never raises. False only when the
        worker did not answer (an ended worker holds no torque: True)."""
        try:
            return bool(self._owner.call("estop", self.arm_id, timeout=ESTOP_TIMEOUT_S))
        except BackendError:  # ended or freed: no arm holds torque; not answering: unsure
            return self._owner.ended is not None or not self._owner.holds(self.arm_id)
        except Exception:
            return False

    def close(self) -> None:
        """Nothing: the owner frees the arm (:meth:`ArmProcess.free`)."""

    def push(self, force: np.ndarray, *, link: int, point: np.ndarray, duration: float) -> None:
        """``Pushable.push`` in the worker."""
        self._owner.call("push", self.arm_id, force, link, point, duration)

    def set_spring(self, anchor: np.ndarray | None, *, stiffness: float, link: int,
                   point: np.ndarray) -> None:
        """``Pushable.set_spring`` in the worker."""
        self._owner.call("spring", self.arm_id, anchor, stiffness, link, point)

    def set_wall(self, origin: np.ndarray | None, normal: np.ndarray | None = None, *,
                 stiffness: float, damping: float, friction: float = 0.0,
                 size: tuple[float, float, float] | None = None) -> None:
        """``Touchable.set_wall`` in the worker (this arm's world only); a refused wall
        raises here (ValueError), as in process."""
        self._owner.call("wall", self.arm_id,
                         None if origin is None else np.asarray(origin, dtype=float),
                         None if normal is None else np.asarray(normal, dtype=float),
                         float(stiffness), float(damping), float(friction),
                         None if size is None else tuple(float(x) for x in size))

    def wall_setting(self) -> WallSetting | None:
        """The wall in the arm's world now (the worker's answer; None: none)."""
        wall = self._owner.call("wall_setting", self.arm_id)
        return wall if isinstance(wall, WallSetting) else None

    def wall_force(self) -> float:
        """N, the wall's force on the hand in the newest mirrored period (0: none). The
        worker's loop records it every period; this reads that record."""
        f = self._newest("f_contact", 0.05)
        return float(f[-1]) if f.size and np.isfinite(f[-1]) else 0.0

    def wall_peak(self) -> float:
        """N, the largest wall force at any plant step in the periods mirrored since the
        last call (the worker's record, ``f_contact_peak``; then the newest period's)."""
        snap = self._loop.recorder.snapshot(1.0)
        t, peak = snap["t"], snap["f_contact_peak"]
        if not t.size:
            return 0.0
        new = t > self._peak_read
        rows = peak[new] if new.any() else peak[-1:]
        self._peak_read = float(t[-1])
        rows = rows[np.isfinite(rows)]
        return float(rows.max()) if rows.size else 0.0

    def _newest(self, name: str, seconds: float) -> np.ndarray:
        return np.asarray(self._loop.recorder.snapshot(seconds)[name], dtype=float)

    def meet_wall(self, wall: WallSetting | None) -> None:
        """The next restart's fresh arm meets ``wall`` (None: none) in the worker
        (:meth:`armlab.control.restart.RestartableArm.meet_wall`)."""
        self._owner.call("meet_wall", self.arm_id, wall)

    def cancel(self) -> None:
        """Post nothing more of the last restart's plan (the run was cut short), in the
        worker (:meth:`armlab.control.restart.RestartableArm.cancel`)."""
        self._owner.call("cancel", self.arm_id)

    def restart(self, q: np.ndarray, plan: list[tuple[int, Command]]) -> int:
        """Start the arm again at ``q`` (n,) rad, at rest, its controller reset, then post
        ``plan``'s (periods, command) (:class:`armlab.control.restart.RestartableArm`, in
        the worker); the restart's number."""
        return int(self._owner.call("restart", self.arm_id, np.asarray(q, dtype=float),
                                    list(plan)))

    def restarted(self) -> tuple[int, float | None]:
        """(restarts done, loop time of the last one's period)."""
        done, at = self._owner.call("restarted", self.arm_id)
        return int(done), at


class _Call:
    def __init__(self) -> None:
        self.done = threading.Event()
        self.ok = False
        self.value: Any = None


class ArmProcess:
    """A worker process running simulated arms, and their proxies (module docstring).

    Args:
        kind: "class" (private arms on one clock) or "own" (each its own loop thread).
        realtime: step against the wall clock (False: as fast as possible, for tests).
        mirror_s: s between two mirror messages.
    """

    def __init__(self, *, kind: str = "class", realtime: bool = True,
                 mirror_s: float = MIRROR_S) -> None:
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
        ours, theirs = socket.socketpair()
        self._conn = Connection(ours.detach())
        fd = theirs.detach()
        env = dict(os.environ)  # the lab's package, wherever this copy of it is
        root = str(Path(armlab.__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        try:  # a fresh interpreter: never fork a server's threads, never rerun its script
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "armlab.app.workers.worker", str(fd), str(int(realtime)),
                 repr(float(mirror_s)), kind], pass_fds=(fd,), env=env, stdin=subprocess.DEVNULL)
        finally:
            os.close(fd)
        self._send_lock = threading.Lock()
        self._lock = threading.Lock()
        self._calls: dict[int, _Call] = {}
        self._loops: dict[int, RemoteLoop] = {}
        self._members: dict[int, RemoteHand | RemoteGait] = {}  #: hands and quadrupeds
        #: mirror items of arms and members being added (their rows from the first period
        #: on, which may come before the add's answer), by id
        self._early: dict[int, list[tuple]] = {}
        self._ids = itertools.count(1)
        self._ready = threading.Event()
        #: how the OS schedules the worker (:func:`armlab.app.workers.worker.prioritise`), once it
        #: started
        self.scheduling: str | None = None
        self._ended: str | None = None
        self._heard = time.monotonic()  #: when the worker last sent anything
        self._closing = False
        self._receiver = threading.Thread(target=self._receive, name="armlab-arm-mirror",
                                          daemon=True)
        self._receiver.start()

    @property
    def ended(self) -> str | None:
        """Why the worker is gone (None while it runs)."""
        return self._ended

    def silent(self) -> str | None:
        """Why the arms' state is not known now (the worker, holding arms, sent nothing
        for :data:`STALE_S` s), or None."""
        quiet = time.monotonic() - self._heard
        if quiet <= STALE_S or not self._ready.is_set():
            return None
        return (f"the arm's simulation has not answered for {quiet:.0f} s "
                "(the machine may be overloaded)")

    @property
    def pid(self) -> int | None:
        """The worker's process id."""
        return self._proc.pid

    def add(self, model: SerialChain, params: Params, *, preset: str, q0: np.ndarray,
            history_s: float) -> Arm:
        """A new arm in the worker (:meth:`ClassArms.add` or :meth:`OwnArms.add`), its loop
        running; its ``backend`` and ``loop`` are the server's proxies."""
        self._wait_ready()
        arm_id = next(self._ids)
        with self._adding(arm_id):
            lower, upper, capacity, status, gains, reports = self.call(
                "add", arm_id, model, params, preset, np.asarray(q0, dtype=float), history_s)
            loop = RemoteLoop(self, arm_id, model, gains, lower=lower, upper=upper,
                              capacity=capacity, status=status, reports=reports)
            self._register(self._loops, arm_id, loop)
        return Arm(preset, None, RemoteBackend(self, loop), loop)  # type: ignore[arg-type]  # a RemoteLoop quacks as the arm's ControlLoop

    def _wait_ready(self) -> None:
        """Wait for the worker to have started (BackendError when it did not in
        :data:`START_TIMEOUT_S` s)."""
        if not self._ready.wait(START_TIMEOUT_S) and self._ended is None:
            raise BackendError("the class's simulation did not start; restart the lab")

    def free(self, arm: Arm) -> None:
        """Stop ``arm``'s loop (torque off) and take it out of the worker (as
        :meth:`ClassArms.free`)."""
        self.free_id(arm.loop.arm_id)  # type: ignore[attr-defined]  # a RemoteLoop's

    def free_id(self, arm_id: int) -> None:
        """:meth:`free` by the arm's id; nothing when the worker has ended or the arm was
        freed."""
        with self._lock:
            if self._loops.pop(arm_id, None) is None:
                return
        if self._ended is None:
            self.call("free", arm_id)

    def add_hand(self, obj: GraspObject | None, params: GripParams, *,
                 history_s: float) -> RemoteHand:
        """A new hand in the worker's class of hands (:meth:`ClassHands.add`), open, around
        ``obj`` with grasp settings ``params``; its proxy."""
        return self._add_member(RemoteHand, obj, params, history_s)  # type: ignore[return-value]  # _add_member makes a RemoteHand here

    def add_quadruped(self, spec: GaitSpec, *, speed: float, history_s: float) -> RemoteGait:
        """A new robot in the worker's class of quadrupeds (:meth:`ClassQuadrupeds.add`),
        standing, its loop on the class's clock; its proxy."""
        return self._add_member(RemoteGait, spec, speed, history_s)  # type: ignore[return-value]  # _add_member makes a RemoteGait here

    def _add_member(self, kind: type[RemoteHand | RemoteGait], *args: object
                    ) -> RemoteHand | RemoteGait:
        self._wait_ready()
        member_id = next(self._ids)
        with self._adding(member_id):
            made = kind(self, member_id, **self.call(f"{kind.KIND}_add", member_id, *args))
            self._register(self._members, member_id, made)
        return made

    @contextlib.contextmanager
    def _adding(self, new_id: int) -> Iterator[None]:
        """While ``new_id`` is being added, keep the mirror items the worker sends for it
        (its loop runs, and is mirrored, before the add's answer arrives here)."""
        with self._lock:
            self._early[new_id] = []
        try:
            yield
        finally:
            with self._lock:
                self._early.pop(new_id, None)

    def _register(self, table: dict, new_id: int, proxy: RemoteLoop | RemoteHand | RemoteGait
                  ) -> None:
        """Put ``proxy`` in ``table`` after giving it the items mirrored while it was being
        added (so its record holds every row from its loop's first period)."""
        with self._lock:
            for state in self._early.pop(new_id, ()):
                proxy._mirror(*state)
            table[new_id] = proxy

    def free_member(self, member: RemoteHand | RemoteGait) -> None:
        """Take a hand or a quadruped out of the worker's class (its loop stops, torque
        off); nothing when the worker has ended or it was freed."""
        with self._lock:
            if self._members.pop(member.member_id, None) is None:
                return
        member.freed = True
        if self._ended is None:
            self.call(f"{member.KIND}_free", member.member_id)

    def holds(self, arm_id: int) -> bool:
        """Whether arm ``arm_id`` is held (added and not freed)."""
        with self._lock:
            return arm_id in self._loops

    def call(self, op: str, arm_id: int, *args: object,
             timeout: float = CALL_TIMEOUT_S) -> Any:
        """Run ``op`` on arm ``arm_id`` in the worker and return its answer (its exception
        raised here).

        Raises:
            BackendError: the worker has ended or did not answer in
                :data:`CALL_TIMEOUT_S` s.
            ValueError: an argument that cannot be sent (not picklable).
        """
        if self._ended is not None:
            raise BackendError(self._ended)
        call_id = next(self._ids)
        call = _Call()
        with self._lock:
            self._calls[call_id] = call
        try:
            try:
                data = pickle.dumps((op, call_id, arm_id, *args), pickle.HIGHEST_PROTOCOL)
            except Exception as exc:
                raise ValueError(f"{op}: cannot be sent to the arm's simulation: {exc}"
                                 ) from None
            try:
                with self._send_lock:
                    self._conn.send_bytes(data)
            except (OSError, ValueError) as exc:
                raise BackendError(self._ended or f"the arm's simulation is gone: {exc}"
                                   ) from None
            if not call.done.wait(timeout):
                raise BackendError(f"the arm's simulation did not answer {op!r} in "
                                   f"{timeout:g} s")
        finally:
            with self._lock:
                self._calls.pop(call_id, None)
        if not call.ok:
            raise call.value
        return call.value

    def close(self) -> None:
        """Stop the worker (every arm's loop with torque off) and wait for it."""
        self._closing = True
        try:
            with self._send_lock:
                self._conn.send(("close",))
        except (OSError, ValueError):
            pass
        try:
            self._proc.wait(10.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait(5.0)
        self._receiver.join(5.0)
        self._conn.close()

    def _receive(self) -> None:
        while True:
            try:
                msg = self._conn.recv()
            except (EOFError, OSError):
                break
            except Exception:  # noqa: S112 - a message that cannot be read: the next may
                continue
            self._heard = time.monotonic()
            if msg[0] == "mirror":
                with self._lock:
                    loops = self._loops
                    for arm_id, *state in msg[1]:
                        loop = loops.get(arm_id)
                        if loop is not None:
                            loop._mirror(*state)
                        elif arm_id in self._early:
                            self._early[arm_id].append(state)
            elif msg[0] in MEMBER_KINDS:
                with self._lock:
                    members = self._members
                    for member_id, *state in msg[1]:
                        member = members.get(member_id)
                        if member is not None:
                            member._mirror(*state)
                        elif member_id in self._early:
                            self._early[member_id].append(state)
            elif msg[0] == "reply":
                _, call_id, ok, value = msg
                with self._lock:
                    call = self._calls.get(call_id)
                if call is not None:
                    call.ok, call.value = ok, value
                    call.done.set()
            elif msg[0] == "ready":
                self.scheduling = msg[1]
                self._ready.set()
        try:
            code: int | None = self._proc.wait(1.0)
        except subprocess.TimeoutExpired:
            code = None
        self._ended = ("the arm's process was closed" if self._closing else
                       f"the arm's simulation stopped (exit code {code}); "
                       "reload the page for a new arm")
        self._ready.set()
        with self._lock:
            calls = list(self._calls.values())
        for call in calls:
            call.ok, call.value = False, BackendError(self._ended)
            call.done.set()
