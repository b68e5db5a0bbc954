"""The worker side of :mod:`armlab.app.workers.worker_process`: ``python -m
armlab.app.workers.worker FD REALTIME
MIRROR_S KIND`` runs simulated arms for the server at the other end of socket FD, sends
their mirror every MIRROR_S s and answers the server's calls (the messages are listed in
:mod:`armlab.app.workers.worker_process`)."""

from __future__ import annotations

import itertools
import os
import pickle
import signal
import sys
import threading
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from armlab.app.workers.class_arms import Arm, ClassArms, OwnArms
from armlab.app.workers.class_hands import FREED as HAND_FREED
from armlab.app.workers.class_hands import ClassHand, ClassHands
from armlab.app.workers.class_quadrupeds import ClassQuadruped, ClassQuadrupeds
from armlab.app.workers.remote_gait import FREED as QUAD_FREED
from armlab.app.workers.worker_process import FREED, REPORTS_S
from armlab.control.backend import BackendError, Touchable, WallSetting
from armlab.control.commands import Reset
from armlab.control.gait_loop import Command as GaitCommand
from armlab.control.grip import GripParams
from armlab.control.grip_loop import Command as GripCommand
from armlab.control.loop import LoopStatus
from armlab.control.params import GainCheck, Params
from armlab.control.restart import RestartableArm
from armlab.control.walking import GaitSpec
from armlab.hardware.families.dynamixel1.firmware import ServoReport
from armlab.hardware.sim.hand_plant import GraspObject
from armlab.kinematics.model import SerialChain

#: real-time priority (SCHED_FIFO) a real-time "own" worker (the shared arm) asks for, where
#: the OS allows it (root, CAP_SYS_NICE or an rtprio limit): its loop then wakes on time
#: on a busy machine, as a robot's control loop does (ros2_control); refused, it runs as is
SHARED_RT_PRIORITY = 10
#: niceness the class's worker adds to its own: when the cores are busy, the shared arm's
#: loop and the pages come before the students' 1 kHz steps
CLASS_NICE = 5


def prioritise(kind: str, realtime: bool) -> str:
    """Set this worker's scheduling for ``kind`` (only when ``realtime``: a loop run as
    fast as possible must never hold a core at real-time priority) and say what it is."""
    if not realtime:
        return "normal"
    if kind == "class":
        return f"nice {os.nice(CLASS_NICE)}"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(SHARED_RT_PRIORITY))
    except (OSError, AttributeError):  # not allowed here (or not Linux): as any process
        return "normal (real-time priority not allowed)"
    return f"SCHED_FIFO {SHARED_RT_PRIORITY}"


def reports_of(arm: Arm) -> tuple[ServoReport, ...] | None:
    """The arm's servo reports (the Servos panel's), or None for servos that give none."""
    plant = getattr(arm.backend, "plant", None)
    return None if plant is None else plant.reports()


class HandKind:
    """The class's hands (:class:`ClassHands`) as the worker hosts them: the answers and
    mirror items :class:`armlab.app.workers.remote_hand.RemoteHand` expects."""

    name = "hand"
    freed = HAND_FREED  #: what a freed hand's calls say

    @staticmethod
    def host(realtime: bool) -> ClassHands:
        return ClassHands(realtime=realtime)

    @staticmethod
    def add(host: ClassHands, obj: GraspObject | None, params: GripParams,
            history_s: float) -> tuple[ClassHand, dict[str, object]]:
        hand = host.add(obj, params, history_s=history_s)
        return hand, {"model": hand.model, "dt": hand.dt, "capacity": hand.capacity,
                      "status": hand.status, "params": hand.params, "obj": hand.obj}

    @staticmethod
    def post(hand: ClassHand, command: GripCommand) -> None:
        hand.post(command)

    @staticmethod
    def free(host: ClassHands, hand: ClassHand) -> None:
        host.free(hand)

    @staticmethod
    def sent(hand: ClassHand) -> list:
        """[rows mirrored, settings and object last sent] (all of them sent with ``add``)."""
        return [0, hand.params, hand.obj]

    @staticmethod
    def item(member_id: int, hand: ClassHand, sent: list) -> tuple:
        status = hand.status  # first: the rows are at least as new as it says
        rows, sent[0] = hand.rows_since(sent[0])
        params = None if hand.params is sent[1] else hand.params
        obj = None if hand.obj is sent[2] else (hand.obj,)
        sent[1], sent[2] = hand.params, hand.obj
        return member_id, status, rows, params, obj


class QuadKind:
    """The class's quadrupeds (:class:`ClassQuadrupeds`) as the worker hosts them, for
    :class:`armlab.app.workers.remote_gait.RemoteGait`."""

    name = "quad"
    freed = QUAD_FREED

    @staticmethod
    def host(realtime: bool) -> ClassQuadrupeds:
        return ClassQuadrupeds(realtime=realtime)

    @staticmethod
    def add(host: ClassQuadrupeds, spec: GaitSpec, speed: float, history_s: float
            ) -> tuple[ClassQuadruped, dict[str, object]]:
        made = host.add(spec, speed=speed, history_s=history_s)
        loop = made.loop
        return made, {"capacity": loop.capacity, "status": loop.status,
                      "state": loop.state, "spec": loop.walker.plan.spec}

    @staticmethod
    def post(made: ClassQuadruped, command: GaitCommand) -> None:
        made.loop.post(command)

    @staticmethod
    def free(host: ClassQuadrupeds, made: ClassQuadruped) -> None:
        host.free(made)

    @staticmethod
    def sent(made: ClassQuadruped) -> list:
        """[rows mirrored, gait spec last sent]."""
        return [0, made.loop.walker.plan.spec]

    @staticmethod
    def item(member_id: int, made: ClassQuadruped, sent: list) -> tuple:
        loop = made.loop
        status = loop.status
        rows, sent[0] = loop.rows_since(sent[0])
        spec = loop.walker.plan.spec
        changed, sent[1] = (None if spec is sent[1] else spec), spec
        return member_id, status, rows, loop.state, changed


#: what a class's worker hosts besides arms, by the name its messages carry
MEMBER_KINDS = {kind.name: kind for kind in (HandKind, QuadKind)}


def restart(arm: Arm, q: np.ndarray, plan: list) -> int:
    """Start ``arm`` again at ``q`` at rest (:meth:`RestartableArm.restart`, then a Reset
    posted), ``plan``'s commands posted after; the restart's number."""
    backend = arm.backend
    if not isinstance(backend, RestartableArm):
        raise ValueError("this arm cannot be started again from a pose")
    number = backend.restart(q, plan, arm.loop.post)
    arm.loop.post(Reset())
    return number


def set_wall(arm: Arm, origin: np.ndarray | None, normal: np.ndarray | None,
             stiffness: float, damping: float, friction: float,
             size: tuple[float, float, float] | None = None) -> None:
    """``arm``'s wall (``Touchable.set_wall``: its own world's, no other arm's)."""
    backend = arm.backend
    if not isinstance(backend, Touchable):
        raise ValueError("this simulated arm takes no wall")
    backend.set_wall(origin, normal, stiffness=float(stiffness), damping=float(damping),
                     friction=float(friction), size=size)


def wall_setting(arm: Arm) -> WallSetting | None:
    """``arm``'s wall now (None: none, or an arm that takes none)."""
    backend = arm.backend
    return backend.wall_setting() if isinstance(backend, Touchable) else None


def meet_wall(arm: Arm, wall: WallSetting | None) -> None:
    """The next restart's fresh arm meets ``wall`` (:meth:`RestartableArm.meet_wall`)."""
    backend = arm.backend
    if not isinstance(backend, RestartableArm) or not isinstance(backend, Touchable):
        raise ValueError("this arm cannot be started again against a wall")
    if wall is not None and not isinstance(wall, WallSetting):
        raise ValueError(f"a wall must be a WallSetting, got {type(wall).__name__}")
    backend.meet_wall(wall)


def cancel(arm: Arm) -> None:
    """Post nothing more of ``arm``'s last restart's plan (:meth:`RestartableArm.cancel`)."""
    if isinstance(arm.backend, RestartableArm):
        arm.backend.cancel()


def restarted(arm: Arm) -> tuple[int, float | None]:
    """(restarts done, loop time of the last) of ``arm`` (:class:`RestartableArm`)."""
    backend = arm.backend
    if not isinstance(backend, RestartableArm):
        return 0, None
    return backend.restarts, backend.restarted_at


def serve(conn: Connection, realtime: bool, mirror_s: float, kind: str = "class") -> None:
    """The worker process: a :class:`ClassArms` (``kind`` "class") or :class:`OwnArms`
    ("own") run by the server's calls, mirrored every ``mirror_s`` s, until the server
    says close or its end of the pipe closes; and the class's hands and quadrupeds
    (:data:`MEMBER_KINDS`, each kind's host made at its first member)."""
    scheduling = prioritise(kind, realtime)  # before any thread: they inherit it
    arms = ClassArms(realtime=realtime) if kind == "class" else OwnArms(realtime=realtime)
    held: dict[int, tuple[Arm, list[int]]] = {}  # arm id -> (arm, [rows mirrored])
    fresh: dict[int, Arm] = {}  # added, mirrored once the server has its answer
    held_lock = threading.Lock()
    # Any: each kind's own host and members (MEMBER_KINDS[name] takes them)
    hosts: dict[str, Any] = {}  # kind name -> its host, made at its first member
    #: member id -> (kind name, the member, what its mirror last sent)
    members: dict[int, tuple[str, Any, list]] = {}
    fresh_members: dict[int, tuple[str, Any]] = {}  # mirrored once the server has them
    send_lock = threading.Lock()
    stop = threading.Event()

    def send(msg: object) -> None:
        with send_lock:
            conn.send(msg)

    def mirror() -> None:
        """Every ``mirror_s`` s, one mirror; a cycle that fails unexpectedly is told once
        on stderr and the next goes on (a dead mirror would leave the server calling a
        running worker silent for good)."""
        told: set[str] = set()
        for n in itertools.count(1):
            if stop.wait(mirror_s):
                return
            try:
                if not mirror_once(n):  # the server's end is gone
                    return
            except Exception as exc:  # noqa: BLE001 - any other: say it, keep mirroring
                said = f"{type(exc).__name__}: {exc}"
                if said not in told:
                    told.add(said)
                    print(f"armlab worker: a mirror failed ({said}); going on",
                          file=sys.stderr, flush=True)

    def mirror_once(n: int) -> bool:
        """Send the held arms' and members' news (the servos' reports every
        :data:`REPORTS_S` s); False when the server's end of the pipe is gone."""
        reports_every = max(1, round(REPORTS_S / mirror_s))
        with held_lock:
            items = list(held.items())
        batch = []
        for arm_id, (arm, bookmark) in items:
            loop = arm.loop
            status = loop.status  # first: the rows are at least as new as it says
            rows, bookmark[0] = loop.recorder.since(bookmark[0])
            try:
                reports = reports_of(arm) if n % reports_every == 0 else None
            except ValueError:  # freed since the list was taken (its mirror is dropped)
                reports = None
            batch.append((arm_id, status, rows, loop.recorder.capacity,
                          loop.spare_joints, loop.gripper, reports))
        with held_lock:
            member_items = list(members.items())
        by_kind: dict[str, list] = {}
        for member_id, (name, member, sent) in member_items:
            by_kind.setdefault(name, []).append(
                MEMBER_KINDS[name].item(member_id, member, sent))
        try:
            if batch:
                send(("mirror", batch))
            for name, member_batch in by_kind.items():
                send((name, member_batch))
        except (OSError, ValueError):
            return False
        return True

    def arm_of(arm_id: int) -> Arm:
        with held_lock:
            found = held.get(arm_id)
        if found is None:
            raise BackendError(FREED)
        return found[0]

    def add(arm_id: int, model: SerialChain, params: Params, preset: str, q0: np.ndarray,
            history_s: float) -> tuple[np.ndarray, np.ndarray, int, LoopStatus, GainCheck,
                                       tuple[ServoReport, ...] | None]:
        arm = fresh[arm_id] = arms.add(model, params, preset=preset, q0=q0,
                                       history_s=history_s)
        loop = arm.loop
        return (loop.lower, loop.upper, loop.recorder.capacity, loop.status, loop.gains,
                reports_of(arm))

    def member_of(name: str, member_id: int) -> Any:
        with held_lock:
            found = members.get(member_id)
        if found is None or found[0] != name:
            raise ValueError(MEMBER_KINDS[name].freed)
        return found[1]

    def member_add(name: str, member_id: int, *args: Any) -> dict[str, object]:
        kind_of = MEMBER_KINDS[name]
        if name not in hosts:
            hosts[name] = kind_of.host(realtime)
        member, reply = kind_of.add(hosts[name], *args)
        fresh_members[member_id] = (name, member)
        return reply

    def member_free(name: str, member_id: int) -> None:
        with held_lock:
            found = members.pop(member_id, None)
        if found is not None:
            MEMBER_KINDS[name].free(hosts[name], found[1])

    def member_ops(name: str) -> dict[str, Callable[..., object]]:
        kind_of = MEMBER_KINDS[name]
        return {f"{name}_add": lambda i, *args: member_add(name, i, *args),
                f"{name}_post": lambda i, cmd: kind_of.post(member_of(name, i), cmd),
                f"{name}_free": lambda i: member_free(name, i)}

    def free(arm_id: int) -> None:
        with held_lock:
            found = held.pop(arm_id, None)
        if found is not None:
            arms.free(found[0])

    ops: dict[str, Callable[..., object]] = {
        "add": add,
        "free": free,
        "post": lambda i, cmd: arm_of(i).loop.post(cmd),
        "set_params": lambda i, p: arm_of(i).loop.set_params(p),
        "estop": lambda i: arm_of(i).backend.estop(),
        "read": lambda i: arm_of(i).backend.read(),
        "push": lambda i, f, link, point, d: arm_of(i).backend.push(  # type: ignore[attr-defined]  # the worker's arms are simulated (a push, a spring)
            f, link=link, point=point, duration=d),
        "spring": lambda i, anchor, k, link, point: arm_of(i).backend.set_spring(  # type: ignore[attr-defined]  # the worker's arms are simulated (a push, a spring)
            anchor, stiffness=k, link=link, point=point),
        "restart": lambda i, q, plan: restart(arm_of(i), q, plan),
        "restarted": lambda i: restarted(arm_of(i)),
        "cancel": lambda i: cancel(arm_of(i)),
        "wall": lambda i, origin, normal, k, c, mu, size=None: set_wall(
            arm_of(i), origin, normal, k, c, mu, size),
        "wall_setting": lambda i: wall_setting(arm_of(i)),
        "meet_wall": lambda i, wall: meet_wall(arm_of(i), wall),
        **member_ops("hand"),
        **member_ops("quad"),
        "quad_estop": lambda i: member_of("quad", i).loop.estop(),
        "quad_restart": lambda i, q, plan, timed: hosts["quad"].restart(
            member_of("quad", i), np.asarray(q, dtype=float), plan, timed),
        "quad_cancel": lambda i: member_of("quad", i).backend.cancel(),
    }
    mirror_thread = threading.Thread(target=mirror, name="armlab-arm-mirror", daemon=True)
    mirror_thread.start()
    send(("ready", scheduling))
    try:
        while True:
            try:
                msg = pickle.loads(conn.recv_bytes())
            except (EOFError, OSError):
                break
            if msg[0] == "close":
                break
            op, call_id, *args = msg
            try:
                value, ok = ops[op](*args), True
            except Exception as exc:
                value, ok = exc, False
            try:
                send(("reply", call_id, ok, value))
            except (pickle.PicklingError, TypeError, AttributeError) as exc:
                send(("reply", call_id, False, RuntimeError(f"{op}: {exc}")))
            except (OSError, ValueError):
                break
            if fresh:  # (a mirror before the answer would name an arm the server lacks)
                with held_lock:
                    held.update((i, (arm, [0])) for i, arm in fresh.items())
                fresh.clear()
            if fresh_members:  # (likewise)
                with held_lock:
                    members.update((i, (name, member, MEMBER_KINDS[name].sent(member)))
                                   for i, (name, member) in fresh_members.items())
                fresh_members.clear()
    finally:
        stop.set()
        mirror_thread.join(2.0)
        with held_lock:
            left = [arm for arm, _ in held.values()] + list(fresh.values())
            held.clear()
        arms.close(left)
        for host in hosts.values():
            host.close()
        conn.close()


if __name__ == "__main__":  # started by armlab.app.workers.worker_process.ArmProcess
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the server's: it closes us
    serve(Connection(int(sys.argv[1])), bool(int(sys.argv[2])), float(sys.argv[3]),
          sys.argv[4])
