"""Classroom figures: private compliance-lesson arms per core, and rooms of 30 pages.

Figures:
    sandboxes_realtime_per_core: arms (``receptionist_arm``, three RX-24F each) that one
        core keeps at 1 kHz in real time as "My arm" runs them: every arm its own
        :class:`~armlab.control.loop.ControlLoop` (compliance, 16 ms: commands, trajectory,
        recorder, run-time checks) over a
        :class:`~armlab.hardware.families.dynamixel1.batched_backend.BatchedArmBackend`,
        all on one :class:`~armlab.control.periodic.SharedClock` over one BatchedPlant at 1 ms
        (headless: ``SharedClock.run_for`` of 2 s of class time, the median of 3 classes of
        different gains; one of 0.5 s quick):
        N · 1e-3 s / (wall time per simulated ms) for the largest N of (50, 100); a tenth
        of the arms play a step trajectory, a tenth are pushed; the arms joined a tick
        apart, as students join (each loop's first period then waits for the next whole
        number of its periods: their law is computed as one).
    class_loops_step_us_n50 / _n100: wall µs per simulated ms of that class.
    sandboxes_walls_realtime_per_core: the same for the largest class with a wall per arm
        (the contact lesson's, 2·10⁴ N/m, 3 mm behind each hand: within the plant's margin,
        its force computed at every step), set through each arm's backend so that its loop
        records the force and its peak (:class:`BatchedWalls`, stepped in the plant's
        place); ``sandboxes_walls_over_free``: its cost over
        the wall-free class's, same run.
    plant_compiled: 1 when the plant ran compiled to machine code (numba:
        ``BatchedPlant.compile``, the dynamics, link points, walls' pushes and firmware
        tick; :mod:`armlab.kinematics.machine_code`), 0 when numpy ran it (numba missing:
        every figure then is numpy's); ``plant_compile_s``: how long compiling the
        thesis arm's plant took, before any class was timed.
    sandboxes_numpy_realtime_per_core: the free class's figure with the numpy code in
        the compiled code's place, same run; ``sandboxes_compiled_over_numpy``: the
        compiled figure over it.
    sandboxes_single_plants_realtime_per_core: the same figure, measured in the same run, of
        the design the batched plant replaced: 50 such loops, each over a plant of its own
        stepped in Python (:class:`~armlab.hardware.families.dynamixel1.sim_backend.SimBackend`);
        ``sandboxes_batched_over_single``: the batched figure over it (the machine's speed
        cancels out; the issue asks for about three times a per-arm design).
    classroom_30_pose_hz: a lab served with ``--classroom`` and 30 pages (headless
        clients in another process), each showing "My arm" and its arm playing the thesis
        line again and again while the shared arm does too: the lowest rate of frames of
        its own lesson any page receives (a probe node in each frame, as ``ui_pose_hz``);
        ``classroom_30_arm_moved_hz``: the lowest rate of those in which its arm turned
        (a resting arm sends no pose).
    classroom_30_bytes_per_client_per_s: websocket bytes per page per second (mean;
        ``_max``: the most any page received).
    classroom_30_loop_jitter_p99_ms: the shared arm's loop lateness p99 meanwhile (its loop
        runs in a worker process of its own, :mod:`armlab.app.workers.worker_process`);
        ``classroom_30_shared_loop_realtime_priority``: 1 when that worker got the
        real-time priority it asks for (SCHED_FIFO: root or CAP_SYS_NICE), 0 otherwise.
    classroom_30_rss_growth_pct: the server's memory growth over the run (its process and
        its two workers), from the moment all 30 private arms exist.
    classroom_30_frames_skipped_behind_pct: of the private pages' frames due, those not
        made because the page had not yet been sent the one before (``Publisher`` stats,
        the whole run); ``classroom_30_pose_hz_median``: the median page's rate;
        ``classroom_30_pages_dropped``: pages whose connection ended before the count did.
    classroom_30_frames_made_hz_min: the lowest rate of pose frames any page's publisher
        made (from the moment all 30 private arms exist to the end of the count): beside
        ``classroom_30_pose_hz``, it tells a frame not made from one not delivered.
    classroom_30_client_cpu_share: CPU seconds per second of the process running the 30
        fake pages (one thread): near 1, they, not the server, may limit the rates (in a
        classroom each browser has a device of its own).
    (120 s of the room, 20 s with ``--quick``.)
    quadrupeds_class_s_per_s_n1 / _n30: wall seconds per simulated second of a class of N
        private quadrupeds walking the trot (:mod:`armlab.app.workers.class_quadrupeds`: one
        ``BatchedQuadrupeds`` at ``CLASS_DT``, every robot's ``GaitLoop`` on its
        ``SharedClock``; headless ``run_for``, after standing up);
        ``quadrupeds_realtime_per_core``: robots one core keeps walking in real time that
        way (N = 30); ``quadrupeds_batched_over_single_n30``: 30 robots each on a
        ``QuadrupedSimBackend`` of its own at the same step, over the batch, measured in
        the same run.
    classroom_30_hand_pose_hz, classroom_30_quadruped_pose_hz: the same room on the hand
        and the quadruped lessons: 30 pages each showing its own hand (one row of the
        class's batched hands, :mod:`armlab.app.workers.class_hands`, in the class's worker),
        every hand
        closing and opening again and again; or its own quadruped (one robot of the
        class's, :mod:`armlab.app.workers.class_quadrupeds`, in a worker of their own), walking
        and
        stopping: the lowest rate of frames of its own lesson any page receives
        (``_median``: the median page's); ``..._bytes_per_client_per_s``: bytes per page
        per second (mean). (60 s each, 20 s with ``--quick``.)

Median of repeats, ``time.perf_counter``; the machine is shared, so these are figures,
never asserted by a test.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from armlab.control.backend import Backend
from armlab.control.commands import Push, RunTrajectory
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.periodic import SharedClock
from armlab.control.trajectory import minimum_jerk
from armlab.hardware.families.dynamixel1.batched_backend import BatchedArmBackend, add_sim_arm
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.families.dynamixel1.batched_walls import BatchedWalls
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics import load_robot, machine_code

LOOP_SIZES = (50, 100)
#: runs of each class whose median is quoted (one with ``--quick``)
REPEATS = 3


def loops_ms_cost(n_arms: int, *, seconds: float, seed: int = 0,
                  batched: bool = True, walls: bool = False) -> float:
    """Wall seconds per simulated ms of ``n_arms`` ControlLoops (compliance, 16 ms, gains
    of their own) on one SharedClock, run headless for ``seconds`` of class time after
    0.1 s of warm-up: over one BatchedPlant at 1 ms (``batched``, as "My arm" runs them),
    or each over a plant of its own
    (:class:`~armlab.hardware.families.dynamixel1.sim_backend.SimBackend`, stepped
    per arm in Python at its loop's periods: the design the batched plant replaced).
    The arms join one tick apart, as students join a class at moments of their own (each
    loop's first period then waits for the next whole number of its periods of class
    time, so their periods share ticks and their law is computed as one:
    :func:`~armlab.control.periodic.aligned_step`, :mod:`armlab.control.law_batch`).
    ``walls``: each arm has a wall of its own 3 mm behind its hand (the contact lesson's
    2·10⁴ N/m; within the plant's margin, so computed at every step, touched or not), set
    through its backend as the Contact tab sets it, so its loop records the wall's force
    and its peak at every plant step (``f_contact``, ``f_contact_peak``)."""
    model = load_robot("receptionist_arm")
    rng = np.random.default_rng(seed)
    dt = 1e-3
    plant = BatchedPlant(model, RX24F, dt=dt) if batched else None
    walled = BatchedWalls(plant) if plant is not None else None  # (as ClassArms steps it)
    if plant is not None:  # timed compiled, never while it compiles (when numba is here)
        plant.compile()
    clock = SharedClock(walled.step if walled is not None else (lambda: None), dt=dt,
                        realtime=False)
    lock = clock.lock
    q0 = np.array([0.0, 0.3, 0.3])
    loops = []
    for _ in range(n_arms):
        q = q0 + rng.uniform(-0.2, 0.2, 3)
        arm = add_sim_arm(plant, q0=q) if plant is not None else -1
        backend: Backend = (BatchedArmBackend(plant, arm, lock=lock, walls=walled)
                            if plant is not None else SimBackend(model, specs=RX24F, dt=dt, q0=q))
        if walls:  # 3 mm behind the hand, facing the way its step would take it (pressed
            # by its weight and the pushes, never blocking a move: a blocked arm faults)
            way = model.fk(q + 0.3)[:3, 3] - model.fk(q)[:3, 3]
            normal = way / np.linalg.norm(way)
            origin = model.fk(q)[:3, 3] - 0.003 * normal
            backend.set_wall(origin, normal, stiffness=2e4, damping=50.0)  # type: ignore[attr-defined]  # both are Touchable
        params = Params(kp=float(rng.uniform(10.0, 25.0)), kv=float(rng.uniform(3.0, 7.0)),
                        k_env=float(rng.uniform(8.0, 30.0)), period=0.016)
        loop = ControlLoop(model, backend, params, realtime=False, clock=clock)
        loop.start()
        loops.append((loop, q))
        clock.run_for(dt)  # the next student joins a tick later
    clock.run_for(0.1)
    for i, (loop, q) in enumerate(loops):
        if i % 10 == 0:
            loop.post(RunTrajectory(minimum_jerk(q, q + 0.3, 0.5)))
        elif i % 10 == 5:
            loop.post(Push(np.array([0.0, 3.0, 0.0]), 2, np.array([0.1, 0.0, 0.0]), 0.3))
    t0 = time.perf_counter()
    clock.run_for(seconds)
    wall = time.perf_counter() - t0
    faults = sum(loop.status.fault is not None for loop, _ in loops)
    if faults:
        raise RuntimeError(f"bench class: {faults} of {n_arms} arms faulted")
    return wall / (seconds / dt)


def _rss_bytes(pid: int | str = "self") -> int:
    """Resident memory of process ``pid`` (Linux /proc), bytes."""
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise OSError(f"no VmRSS in /proc/{pid}/status")


def _server_rss(room: Any) -> int:
    """The server's resident memory, bytes: its own process and its workers
    (:class:`armlab.app.workers.worker_process.ArmProcess`: the private arms', the shared
    arm's)."""
    shared = room.lab.arm_process
    return (_rss_bytes() + _rss_bytes(room.sandboxes.process.pid)
            + (0 if shared is None else _rss_bytes(shared.pid)))


def _probe(lesson: Any) -> list[int]:  # a class's compliance lesson
    """A hidden node of ``lesson``'s page that each of its frames moves (the bench counts
    them as the page receives them); the count of frames that moved it, kept updated."""
    from armlab.app.benches.ui import OWN_PROBE

    node = lesson.server.scene.add_frame(OWN_PROBE, show_axes=False,
                                         visible=False)
    seq = [0]

    def hook() -> None:
        seq[0] += 1
        node.position = (float(seq[0]), 0.0, 0.0)

    lesson.publisher.add_frame_hook(hook)
    return seq


def room_of_30(*, seconds: float, pages: int = 30, settle: float = 30.0) -> dict[str, float]:
    """The classroom_30 figures (see the module docstring), counted for ``seconds`` from
    ``settle`` s after every page drew its own arm."""
    from armlab.app.benches.ui import _clients, _Instrumented

    lab = _Instrumented(classroom=True)
    room = lab.lab.room
    assert room is not None
    stop = threading.Event()
    rss: dict[str, int] = {}
    # lesson id -> the lesson, and (time, pose frames made) when all 30 arms existed and
    # when last seen open (the pages close when the count ends, and their lessons with them)
    seen: dict[int, Any] = {}
    made_from: dict[int, tuple[float, int]] = {}
    made_to: dict[int, tuple[float, int]] = {}
    faults: list[str] = []
    probed: dict[int, list[int]] = {}  # lesson id -> [probe frames made]

    def students_play() -> None:
        while not stop.wait(0.5):
            # Any: the class's compliance lessons (their rig, publisher and run_line)
            lessons: dict[int, Any] = room.private_lessons()
            now = time.monotonic()
            if len(lessons) >= pages and "start" not in rss:
                rss["start"] = _server_rss(room)
                made_from.update((id(lesson), (now, lesson.publisher.stats.pose_frames))
                                 for lesson in lessons.values())
            for lesson in lessons.values():
                if id(lesson) not in seen:  # a probe node in each of its frames
                    seen[id(lesson)] = lesson
                    probed[id(lesson)] = _probe(lesson)
                made_to[id(lesson)] = (now, lesson.publisher.stats.pose_frames)
                rig = lesson.rig
                st = None if rig is None else rig.loop.status
                if st is not None and st.fault:
                    faults.append(st.fault)
                if st is not None and st.trajectory is None and st.active:
                    try:
                        lesson.run_line()
                    except (ValueError, RuntimeError):  # the arm being rebuilt, or a page
                        pass  # closing its lesson meanwhile (its scene's handles removed)

    player = threading.Thread(target=students_play, name="bench-students", daemon=True)
    try:
        lab.keep_running_the_line()
        player.start()
        res = _clients(lab.ws_url, pages, seconds, settle=settle, my_arm=True)
        rss["end"] = _server_rss(room)
        jitter = lab.loop.status.jitter_p99_ms
        shared = lab.lab.arm_process
        fifo = shared is not None and (shared.scheduling or "").startswith("SCHED_FIFO")
        lab.check()
    finally:
        stop.set()
        player.join(2.0)
        lab.close()
    if faults:
        raise RuntimeError(f"classroom bench: private arms faulted: {sorted(set(faults))[:3]}")
    if res["own_pose_hz_min"] <= 0.0:  # a page got none: were its frames made, and sent?
        print("a page received no frame of its own arm; each private lesson's publisher "
              "(frames made over the count, probe frames, frames given up and waits with "
              "its page behind, errors):",
              sorted((made_to[i][1] - made_from[i][1] if i in made_from else -1,
                      probed[i], lesson.publisher.stats.skipped_behind,
                      lesson.publisher.stats.waited_behind, lesson.publisher.stats.errors)
                     for i, lesson in seen.items())[:5], file=sys.stderr, flush=True)
    made = sum(lesson.publisher.stats.pose_frames for lesson in seen.values())
    behind = sum(lesson.publisher.stats.skipped_behind for lesson in seen.values())
    made_hz = [(made_to[i][1] - made_from[i][1]) / (made_to[i][0] - made_from[i][0])
               for i in made_from if made_to[i][0] > made_from[i][0]]
    start = rss.get("start", rss["end"])
    return {
        "classroom_30_pose_hz": res["own_pose_hz_min"],
        "classroom_30_pose_hz_median": res["own_pose_hz_median"],
        "classroom_30_arm_moved_hz": res["own_arm_moved_hz_min"],
        "classroom_30_bytes_per_client_per_s": res["bytes_per_client_per_s"],
        "classroom_30_bytes_per_client_per_s_max": res["bytes_per_client_per_s_max"],
        "classroom_30_loop_jitter_p99_ms": float("nan") if jitter is None else float(jitter),
        "classroom_30_shared_loop_realtime_priority": float(fifo),
        "classroom_30_rss_growth_pct": 100.0 * (rss["end"] - start) / start,
        "classroom_30_client_cpu_share": res["client_cpu_share"],
        "classroom_30_frames_skipped_behind_pct": 100.0 * behind / max(1, made + behind),
        "classroom_30_pages_dropped": res["pages_dropped"],
        "classroom_30_frames_made_hz_min": min(made_hz, default=float("nan")),
    }


def quadrupeds_cost(n: int, *, seconds: float, batched: bool = True) -> float:
    """Wall s per simulated s of ``n`` quadrupeds walking the trot at the class's step:
    batched on one clock (as :class:`armlab.app.workers.class_quadrupeds.ClassQuadrupeds`), or
    (the
    reference) each a ``GaitLoop`` on a ``QuadrupedSimBackend`` of its own."""
    from armlab.app.workers.class_quadrupeds import CLASS_DT, PERIOD
    from armlab.control.gait_loop import STAND_UP_S, GaitLoop
    from armlab.control.walking import GaitSpec, Walker, plan_gait
    from armlab.hardware.families.dynamixel1.batched_quadruped import (
        BatchedQuadrupedBackend,
        BatchedQuadrupeds,
    )
    from armlab.hardware.families.dynamixel1.quadruped import QuadrupedSimBackend

    model = load_robot("quadruped")
    plan = plan_gait(GaitSpec())
    q0 = Walker(plan).state().q
    loops: list[GaitLoop] = []
    backend: Backend
    if batched:
        batch = BatchedQuadrupeds(model, dt=CLASS_DT)
        clock = SharedClock(batch.step, dt=CLASS_DT, realtime=False)
        for _ in range(n):
            backend = BatchedQuadrupedBackend(batch, batch.add(q0), lock=clock.lock)
            loops.append(GaitLoop(Walker(plan), backend, period=PERIOD, realtime=False,
                                  clock=clock))
        for loop in loops:
            loop.go(plan)
            loop.start()

        def run(s: float) -> None:
            clock.run_for(s)
    else:
        for _ in range(n):
            backend = QuadrupedSimBackend(model, q0=q0, dt=CLASS_DT)
            loops.append(GaitLoop(Walker(plan), backend, period=PERIOD, realtime=False))
        for loop in loops:
            loop.go(plan)

        def run(s: float) -> None:
            for loop in loops:
                loop.run_for(s)
    run(STAND_UP_S)  # up on its feet, then count the walking
    t0 = time.perf_counter()
    run(seconds)
    cost = (time.perf_counter() - t0) / seconds
    faults = [loop.status.fault for loop in loops if loop.status.fault]
    if faults or not all(loop.status.walking for loop in loops):
        raise RuntimeError(f"classroom bench: quadrupeds stopped: {faults[:2]}")
    return cost


#: per lesson of :func:`private_room`: the node name a page's own robot turns (the clients
#: wait until every page drew its own), and what every student does every 0.5 s tick k
ROOMS: dict[str, tuple[str, Callable[[Any, int], object]]] = {
    # close every 3 s, open 2 s later
    "hand": ("/hand/finger", lambda lesson, k: lesson.close_hand() if k % 6 == 0 else
             lesson.open_hand() if k % 6 == 4 else None),
    # walk forward for 7 s, stop, walk again 3 s later
    "quadruped": ("/quadruped/", lambda lesson, k: lesson.walk("forward") if k % 20 == 1 else
                  lesson.stop() if k % 20 == 15 else None),
}


def private_room(lesson: str, *, seconds: float, pages: int = 30,
                 settle: float = 15.0) -> dict[str, float]:
    """The classroom_30_<lesson> figures (see the module docstring): ``pages`` pages each
    with its own copy of ``lesson`` (a key of :data:`ROOMS`), counted for ``seconds`` from
    ``settle`` s after every page drew its own robot."""
    from armlab.app.benches.ui import _clients
    from armlab.app.lab.server import Lab, ServeOptions

    prefix, play = ROOMS[lesson]
    lab = Lab(ServeOptions(http_port=0, classroom=True, lesson=lesson))
    room = lab.room
    assert room is not None
    stop = threading.Event()
    seen: set[int] = set()
    faults: list[str] = []

    def students_play() -> None:
        for k in range(1, 1 << 30):
            if stop.wait(0.5):
                return
            own: Any  # a student's compliance lesson (its loop)
            for own in room.private_lessons().values():
                if id(own) not in seen:
                    seen.add(id(own))
                    _probe(own)
                if own.loop.status.fault:
                    faults.append(own.loop.status.fault)
                try:
                    play(own, k)
                except (ValueError, RuntimeError):  # a page closing its lesson meanwhile
                    pass

    player = threading.Thread(target=students_play, name="bench-students", daemon=True)
    try:
        player.start()
        res = _clients(lab.url.replace("http://", "ws://"), pages, seconds, settle=settle,
                       my_arm=True, arm_prefix=prefix)
    finally:
        stop.set()
        player.join(2.0)
        lab.close()
    if faults:
        raise RuntimeError(f"classroom bench: private {lesson} copies faulted: "
                           f"{sorted(set(faults))[:3]}")
    return {f"classroom_30_{lesson}_pose_hz": res["own_pose_hz_min"],
            f"classroom_30_{lesson}_pose_hz_median": res["own_pose_hz_median"],
            f"classroom_30_{lesson}_bytes_per_client_per_s": res["bytes_per_client_per_s"]}


def run(quick: bool) -> dict[str, float]:
    """The figures above (about 1 min quick, 3 min otherwise)."""
    out: dict[str, float] = {}
    t0 = time.perf_counter()
    out["plant_compiled"] = float(BatchedPlant(load_robot("receptionist_arm"), RX24F,
                                                  dt=1e-3).compile())
    out["plant_compile_s"] = time.perf_counter() - t0
    cost = 0.0
    seconds = 0.5 if quick else 2.0
    repeats = 1 if quick else REPEATS
    for n in LOOP_SIZES:
        cost = float(np.median([loops_ms_cost(n, seconds=seconds, seed=k)
                                for k in range(repeats)]))
        out[f"class_loops_step_us_n{n}"] = cost * 1e6
    out["sandboxes_realtime_per_core"] = LOOP_SIZES[-1] * 1e-3 / cost
    walled = float(np.median([loops_ms_cost(LOOP_SIZES[-1], seconds=seconds, seed=k,
                                            walls=True) for k in range(repeats)]))
    out["sandboxes_walls_realtime_per_core"] = LOOP_SIZES[-1] * 1e-3 / walled
    out["sandboxes_walls_over_free"] = walled / cost  # the cost of contact, same run
    machine_code.ENABLED = False
    try:
        numpy_cost = float(np.median([loops_ms_cost(LOOP_SIZES[-1], seconds=seconds, seed=k)
                                      for k in range(repeats)]))
    finally:
        machine_code.ENABLED = True
    out["sandboxes_numpy_realtime_per_core"] = LOOP_SIZES[-1] * 1e-3 / numpy_cost
    out["sandboxes_compiled_over_numpy"] = numpy_cost / cost
    n = LOOP_SIZES[0]
    single = float(np.median([loops_ms_cost(n, seconds=seconds, seed=k, batched=False)
                              for k in range(repeats)]))
    out["sandboxes_single_plants_realtime_per_core"] = n * 1e-3 / single
    out["sandboxes_batched_over_single"] = (out["sandboxes_realtime_per_core"]
                                            / out["sandboxes_single_plants_realtime_per_core"])
    walk_s = 1.0 if quick else 4.0
    for n in (1, 30):
        out[f"quadrupeds_class_s_per_s_n{n}"] = quadrupeds_cost(n, seconds=walk_s)
    out["quadrupeds_realtime_per_core"] = 30.0 / out["quadrupeds_class_s_per_s_n30"]
    out["quadrupeds_batched_over_single_n30"] = quadrupeds_cost(
        30, seconds=walk_s / 2, batched=False) / out["quadrupeds_class_s_per_s_n30"]
    out.update(room_of_30(seconds=20.0 if quick else 120.0))
    for lesson in ROOMS:
        out.update(private_room(lesson, seconds=20.0 if quick else 60.0))
    return out
