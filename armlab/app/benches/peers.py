"""armlab beside its peers (``armlab bench --peers``): MuJoCo and Pinocchio on the same URDF,
the official Dynamixel SDK and Feetech's on the same emulated servos.

Everything runs in this process, on ``armlab/kinematics/robots/receptionist_arm.urdf`` (the
thesis arm, three joints), armlab's figure measured in the same run as the peer's:

- ``peer_rnea_us`` / ``armlab_rnea_us``: one inverse-dynamics call (``pinocchio.rnea``
  / ``armlab.kinematics.dynamics.rnea``) at the same q, q̇, q̈; their torques agree to 1e-9.
- ``peer_ik_us`` / ``armlab_rmrc_us``: one position IK solve to 0.1 mm from q = 0 to
  the same 16 targets (``armlab.app.benches.kinematics.rmrc_targets``): Pinocchio's damped
  least-squares loop (forwardKinematics, frame Jacobian, ``(J Jᵀ + λI)⁻¹``, integrate;
  λ = 1e-6, full steps, at most 200 iterations, no joint limits) against armlab's RMRC
  (thesis eq. 3.16–3.22, which keeps the joint limits). ``peer_ik_solved`` is the share
  of targets the Pinocchio loop reached. The ``_us`` figures are medians over single
  solves; ``peer_ik_set_us`` / ``armlab_rmrc_set_us`` are the time per target of a pass
  over all 16 (median over passes): a loop that needs 70 iterations for one target in 16
  pays for it there, not in the median.
- ``peer_plant_steps_per_s`` / ``armlab_plant_steps_per_s``: 1 ms steps per CPU second
  of a simulated arm whose servos hold a goal: MuJoCo's RK4 with a Python position-servo
  law (PD on the joint, clipped at the RX-24F's stall torque) written into
  ``qfrc_applied`` before each ``mj_step``, against armlab's plant (its own RK4 and the
  RX-24F servo model, ``armlab.hardware.sim.plant``).
- ``peer_plant_wall_steps_per_s`` / ``armlab_plant_wall_steps_per_s``: the same step with
  the hand held 1 cm into a table (a plane facing up): armlab's wall (2·10⁴ N/m,
  50 N·s/m, its normal force worked out at every RK4 stage) against MuJoCo's box and a
  sphere on the hand under its own soft contact; both timed in contact.
- ``peer_bus2_cycle_ms`` / ``armlab_bus2_cycle_ms``: one SYNC_READ of present current,
  velocity and position (126..135) of the OpenManipulator-X's five XM430-W350 (IDs
  11..15, the gripper's included) plus one SYNC_WRITE of profile velocity and goal
  (112..119), protocol 2.0 at 1 Mbps on the same paced emulator (``armlab emulate
  --pace --robot open_manipulator_x``, return delay 0 as the X-series backend configures
  it): the SDK's ``GroupSyncRead.txRxPacket`` + ``GroupSyncWrite.txPacket`` against
  ``armlab.hardware.wire.bus.Bus.sync_read`` + ``sync_write``; medians over cycles, taken in
  alternating blocks (200 of armlab's, 200 of the SDK's, ten rounds) on the one port.
- ``peer_bus_sts_cycle_ms`` / ``armlab_bus_sts_cycle_ms``: the same for the SO-101's six
  STS3215 (IDs 1..6, ``armlab emulate --pace --robot so101``): one SYNC_READ of present
  position to temperature (56..70) and one SYNC_WRITE of goal position, time and speed
  (42..47), Feetech's SDK (``scservo_sdk``, as LeRobot drives it) against armlab's bus;
  ``ratio_bus_sts_wire`` is armlab's cycle over the bytes' wire time
  (``bus_sts_wire_bound_ms``).
- ``ratio_*``: armlab's time over the peer's (below 1: armlab is faster); ``ratio_bus2``
  and ``ratio_bus_sts`` are the medians of the rounds' ratios.

The peers are an optional extra (``pip install -e '.[bench]'``: ``mujoco``, ``pin``,
``dynamixel-sdk`` and ``feetech-servo-sdk``), never a dependency of the lab.
"""

from __future__ import annotations

import contextlib
import itertools
import re
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from armlab.app.benches import median_us
from armlab.app.benches.kinematics import rmrc_targets
from armlab.hardware.families.dynamixel1.sim_backend import SimBackend
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics import load_robot
from armlab.kinematics.dynamics import rnea
from armlab.kinematics.ik import rmrc

INSTALL = ("pip install -e '.[bench]'  (MuJoCo, Pinocchio, the Dynamixel SDK and Feetech's, "
           "for armlab bench --peers)")
TOL = 1e-4  #: m, the IK tolerance of both solvers


def missing() -> list[str]:
    """The peer packages that cannot be imported here."""
    out = []
    for module, package in (("mujoco", "mujoco"), ("pinocchio", "pin"),
                            ("dynamixel_sdk", "dynamixel-sdk"),
                            ("scservo_sdk", "feetech-servo-sdk")):
        try:
            __import__(module)
        except ImportError:
            out.append(package)
    return out


def _mujoco_urdf(urdf_path: str) -> str:
    """The URDF's text for MuJoCo: visuals and collisions dropped, massless links (joint
    frames) given a negligible mass (MuJoCo needs one)."""
    text = open(urdf_path).read()
    text = re.sub(r"<(visual|collision)>.*?</\1>", "", text, flags=re.S)
    compiler = ('<mujoco><compiler discardvisual="true" fusestatic="false" '
                'boundmass="1e-9" boundinertia="1e-12"/></mujoco>')
    return re.sub(r"(<robot[^>]*>)", r"\1" + compiler, text, count=1)


def _rk4_1ms(model: Any) -> Any:
    import mujoco

    model.opt.timestep = 1e-3
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    return model


def mujoco_model(urdf_path: str) -> Any:
    """The URDF as a MuJoCo model, RK4 at 1 ms; gravity -z in the URDF's world."""
    import mujoco

    return _rk4_1ms(mujoco.MjModel.from_xml_string(_mujoco_urdf(urdf_path)))


def mujoco_table_model(urdf_path: str, hand_body: str, top: np.ndarray) -> Any:
    """:func:`mujoco_model` with a table: a box in the world whose top face (facing +z)
    passes through ``top`` (3,) m, world frame, and a 5 mm sphere on the body
    ``hand_body`` (the arm's hand) that touches it (MuJoCo's own soft contact)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(_mujoco_urdf(urdf_path))
    hand = next(b for b in spec.bodies if b.name == hand_body)
    hand.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.005, 0.0, 0.0])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5, 0.5, 0.05],
                            pos=(np.asarray(top, dtype=float) - [0.0, 0.0, 0.05]).tolist())
    return _rk4_1ms(spec.compile())


def pinocchio_ik(model: Any, data: Any, frame: int, target: np.ndarray, q0: np.ndarray
                 ) -> tuple[np.ndarray, bool]:
    """Pinocchio's damped least-squares position IK: (q, reached within ``TOL``)."""
    import pinocchio as pin

    q = q0.copy()
    for _ in range(200):
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacement(model, data, frame)
        err = data.oMf[frame].translation - target
        if np.linalg.norm(err) < TOL:
            return q, True
        J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        v = -J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), err)
        q = pin.integrate(model, q, v)
    return q, False


def _cpu_rate(step: Any, steps: int, batches: int) -> float:
    """Median calls of ``step`` per second of this thread's CPU time."""
    rates = []
    for _ in range(batches):
        t0 = time.thread_time()
        for _ in range(steps):
            step()
        rates.append(steps / (time.thread_time() - t0))
    return float(np.median(rates))


def run(quick: bool) -> dict[str, float]:
    """The peer figures beside armlab's (see the module's docstring)."""
    import mujoco
    import pinocchio as pin

    arm = load_robot("receptionist_arm")
    path = str(arm.urdf_path)
    repeat = 500 if quick else 5000
    q, qd, qdd = np.array([0.3, 0.5, 0.8]), np.array([0.4, -0.2, 0.6]), np.array([1.0, 2, 3])

    pm = pin.buildModelFromUrdf(path)
    pd = pm.createData()
    tau_pin = pin.rnea(pm, pd, q, qd, qdd)
    if not np.allclose(tau_pin, rnea(arm, q, qd, qdd), atol=1e-9):
        raise RuntimeError("Pinocchio and armlab disagree on the same URDF's torques")
    out: dict[str, float] = {
        "peer_rnea_us": median_us(lambda: pin.rnea(pm, pd, q, qd, qdd), repeat=repeat),
        "armlab_rnea_us": median_us(lambda: rnea(arm, q, qd, qdd), repeat=repeat),
    }

    targets = rmrc_targets(arm)
    world = [(arm.base_pose @ np.append(p, 1.0))[:3] for p in targets]  # Pinocchio's frame
    frame = pm.getFrameId("hand")
    q0 = arm.neutral()
    solved = [pinocchio_ik(pm, pd, frame, w, q0)[1] for w in world]
    cycle_w, cycle_t = itertools.cycle(world), itertools.cycle(targets)
    out["peer_ik_us"] = median_us(lambda: pinocchio_ik(pm, pd, frame, next(cycle_w), q0),
                                  repeat=repeat // 10)
    out["armlab_rmrc_us"] = median_us(lambda: rmrc(arm, next(cycle_t), q0),
                                      repeat=repeat // 10)
    out["peer_ik_solved"] = float(np.mean(solved))
    passes = 5 if quick else 25
    out["peer_ik_set_us"] = median_us(lambda: [pinocchio_ik(pm, pd, frame, w, q0)
                                               for w in world], repeat=passes) / len(world)
    out["armlab_rmrc_set_us"] = median_us(lambda: [rmrc(arm, t, q0) for t in targets],
                                          repeat=passes) / len(targets)

    mm = mujoco_model(path)
    md = mujoco.MjData(mm)
    goal, stall = np.array([0.5, 0.8, 1.0]), RX24F.stall_torque

    def mujoco_step() -> None:  # a position servo per joint, then one RK4 step
        md.qfrc_applied[:] = np.clip(8.0 * (goal - md.qpos) - 0.2 * md.qvel, -stall, stall)
        mujoco.mj_step(mm, md)

    backend = SimBackend(arm, q0=[0.0, 0.3, 0.3])
    backend.write(goal, np.full(3, 1.5))
    steps, batches = (1000, 3) if quick else (5000, 7)
    out["peer_plant_steps_per_s"] = _cpu_rate(mujoco_step, steps, batches)
    out["armlab_plant_steps_per_s"] = _cpu_rate(backend.plant.step, steps, batches)
    out.update(_plant_on_a_table(arm, path, goal, steps, batches))

    out.update(bus2_cycles(quick))
    out.update(bus_sts_cycles(quick))
    out["ratio_rnea"] = out["armlab_rnea_us"] / out["peer_rnea_us"]
    out["ratio_ik"] = out["armlab_rmrc_us"] / out["peer_ik_us"]
    out["ratio_ik_set"] = out["armlab_rmrc_set_us"] / out["peer_ik_set_us"]
    out["ratio_plant"] = out["peer_plant_steps_per_s"] / out["armlab_plant_steps_per_s"]
    out["ratio_plant_wall"] = (out["peer_plant_wall_steps_per_s"]
                               / out["armlab_plant_wall_steps_per_s"])
    return out


def _plant_on_a_table(arm: Any, path: str, goal: np.ndarray, steps: int, batches: int
                      ) -> dict[str, float]:
    """The 1 ms step of the arm holding ``goal`` with its hand pressed 1 cm into a table
    (a plane facing up in the URDF's world): armlab's plant and its wall (2·10⁴ N/m,
    50 N·s/m) against MuJoCo's step with a box and its own contact. Each is timed in
    contact (checked before and after)."""
    import mujoco

    hand = arm.fk(goal)[:3, 3]
    up = arm.base_pose[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # the world's +z, base frame
    top = hand + 0.01 * up  # the goal holds the hand 1 cm below the table's top
    mm = mujoco_table_model(path, "hand", (arm.base_pose @ np.append(top, 1.0))[:3])
    md = mujoco.MjData(mm)
    md.qpos[:] = goal
    stall = RX24F.stall_torque

    def mujoco_step() -> None:
        md.qfrc_applied[:] = np.clip(8.0 * (goal - md.qpos) - 0.2 * md.qvel, -stall, stall)
        mujoco.mj_step(mm, md)

    backend = SimBackend(arm, q0=goal)
    backend.set_wall(top, up, stiffness=2e4, damping=50.0)
    backend.set_torque(True)
    backend.write(goal, np.full(3, 1.5))
    for _ in range(300):  # into contact, both
        mujoco_step()
        backend.plant.step()
    touching = (md.ncon > 0, backend.plant.wall_force() > 0.0)
    rates = {"peer_plant_wall_steps_per_s": _cpu_rate(mujoco_step, steps, batches),
             "armlab_plant_wall_steps_per_s": _cpu_rate(backend.plant.step, steps, batches)}
    if not (all(touching) and md.ncon > 0 and backend.plant.wall_force() > 0.0):
        raise RuntimeError(f"the hand left the table while timed (MuJoCo contacts "
                           f"{md.ncon}, armlab's wall {backend.plant.wall_force():.3g} N)")
    return rates


def _alternating(ours_cycle: Callable[[], None], peer_cycle: Callable[[], None], quick: bool
                 ) -> tuple[list[float], list[float], list[float]]:
    """Both cycles timed on one port in alternating blocks (each cycle's times in s, and
    each round's ratio of armlab's median over the peer's): a minute of load on the
    shared machine falls on both rather than on whichever ran then."""
    rounds, block = (4, 75) if quick else (10, 200)

    def block_s(cycle: Callable[[], None]) -> list[float]:
        for _ in range(10):  # back on the port: settle before timing
            cycle()
        samples = []
        for _ in range(block):
            t0 = time.perf_counter()
            cycle()
            samples.append(time.perf_counter() - t0)
        return samples

    for _ in range(50):  # warm-up of both
        ours_cycle()
        peer_cycle()
    ours: list[float] = []
    theirs: list[float] = []
    ratios = []
    for _ in range(rounds):
        a, b = block_s(ours_cycle), block_s(peer_cycle)
        ours += a
        theirs += b
        ratios.append(float(np.median(a) / np.median(b)))
    return ours, theirs, ratios


@contextlib.contextmanager
def _sdk_timeout(handler: Any) -> Iterator[None]:
    """An SDK's port handler waiting 2 × LATENCY_TIMER + 2 ms past the wire time (34 ms
    for the Dynamixel SDK's 16), which a busy machine's emulator overruns several times
    running: armlab's 0.1 s margin for the time it is open, its own afterwards."""
    ports: Any = sys.modules[type(handler).__module__]  # the SDK's port module
    latency_ms = ports.LATENCY_TIMER
    ports.LATENCY_TIMER = 49.0
    try:
        yield
    finally:
        ports.LATENCY_TIMER = latency_ms


def _sdk_cycle(reader: Any, writer: Any, success: int) -> Callable[[], None]:
    """An SDK's group read + write, up to 5 retries of the read, as armlab's bus here."""
    def cycle() -> None:
        for _ in range(6):
            if reader.txRxPacket() == success:
                break
        else:
            raise RuntimeError("the SDK's SYNC_READ failed 6 times")
        writer.txPacket()
    return cycle


def _versus_sdk(sdk: Any, name: str, *, robot: str, protocol: int | str, version: float,
                ids: list[int], present: tuple[int, int], goal: tuple[int, int],
                goal_bytes: dict[int, bytes], quick: bool
                ) -> tuple[list[float], list[float], list[float]]:
    """One group read (``present``: address, length) + one group write (``goal``) of the
    servos ``ids`` of ``armlab emulate --pace --robot robot``, armlab's bus (``protocol``)
    against an SDK's (``sdk``: the Dynamixel SDK or Feetech's, the same API;
    ``PacketHandler(version)``), in alternating blocks on one port (:func:`_alternating`)."""
    from armlab.app.benches.bus import BAUD, paced_emulator
    from armlab.hardware.wire.bus import Bus

    with paced_emulator("--robot", robot, "--baud", str(BAUD)) as port, \
            Bus(port, BAUD, protocol=protocol, timeout_margin=0.1, retries=5,
                exclusive=False) as bus:
        for i in ids:  # as a configured arm: no factory return delay
            bus.write(i, "return_delay_time", 0)

        def armlab_cycle() -> None:
            bus.sync_read(*present, ids)
            bus.sync_write(*goal, goal_bytes)

        handler = sdk.PortHandler(port)
        if not handler.openPort() or not handler.setBaudRate(BAUD):
            raise RuntimeError(f"{name} could not open {port}")
        try:
            with _sdk_timeout(handler):
                packets = sdk.PacketHandler(version)
                reader = sdk.GroupSyncRead(handler, packets, *present)
                writer = sdk.GroupSyncWrite(handler, packets, *goal)
                for i in ids:
                    reader.addParam(i)
                    writer.addParam(i, list(goal_bytes[i]))
                return _alternating(armlab_cycle,
                                    _sdk_cycle(reader, writer, sdk.COMM_SUCCESS), quick)
        finally:
            handler.closePort()


def bus2_cycles(quick: bool) -> dict[str, float]:
    """The protocol-2.0 group read + write cycle, armlab's bus and the Dynamixel SDK's, on
    one paced emulator (see the module's docstring), in alternating blocks: both keep the
    port open and take turns (each empties the input before it sends).

    Returns:
        ``armlab_bus2_cycle_ms`` and ``peer_bus2_cycle_ms`` (medians over every cycle)
        and ``ratio_bus2`` (the median over rounds of armlab's median over the SDK's).
    """
    import dynamixel_sdk as sdk

    from armlab.app.benches.bus import OMX_IDS
    from armlab.hardware.families.xseries.backend import GOAL_AT, GOAL_LEN, PRESENT_AT, PRESENT_LEN

    ids = list(OMX_IDS)  # the arm's and the gripper's, as the X-series backend's
    ours, theirs, ratios = _versus_sdk(
        sdk, "the Dynamixel SDK", robot="open_manipulator_x", protocol=2, version=2.0,
        ids=ids, present=(PRESENT_AT, PRESENT_LEN), goal=(GOAL_AT, GOAL_LEN),
        goal_bytes={i: bytes(4) + (2048).to_bytes(4, "little") for i in ids}, quick=quick)
    return {"armlab_bus2_cycle_ms": float(np.median(ours) * 1e3),
            "peer_bus2_cycle_ms": float(np.median(theirs) * 1e3),
            "ratio_bus2": float(np.median(ratios))}


def bus_sts_cycles(quick: bool) -> dict[str, float]:
    """The Feetech STS group read + write cycle, armlab's bus and Feetech's own SDK's
    (``scservo_sdk``, the FTServo SDK LeRobot drives its SO-101 with), on one paced
    emulator (``armlab emulate --pace --robot so101``), in alternating blocks as
    :func:`bus2_cycles`: one SYNC_READ of present position, speed, load, voltage,
    temperature (56..70, 15 bytes) of the SO-101's six STS3215 (IDs 1..6) plus one
    SYNC_WRITE of goal position, time and speed (42..47), the packets of one cycle of
    the STS backend.

    Returns:
        ``armlab_bus_sts_cycle_ms`` and ``peer_bus_sts_cycle_ms`` (medians over every
        cycle), ``ratio_bus_sts`` (the median over rounds of armlab's median over the
        SDK's), ``bus_sts_wire_bound_ms`` (the cycle's bytes at 10 bits a byte) and
        ``ratio_bus_sts_wire`` (armlab's median over that bound).
    """
    import scservo_sdk as scs

    from armlab.app.benches.bus import BAUD, SO101_SERVOS, sts_cycle_bytes
    from armlab.hardware.families.feetech.backend import GOAL_AT, GOAL_LEN, PRESENT_AT, PRESENT_LEN
    from armlab.hardware.servos.servo_spec import wire_time

    ids = list(range(1, SO101_SERVOS + 1))
    ours, theirs, ratios = _versus_sdk(
        scs, "Feetech's SDK", robot="so101", protocol="sts", version=0,  # STS: little-endian
        ids=ids, present=(PRESENT_AT, PRESENT_LEN), goal=(GOAL_AT, GOAL_LEN),
        goal_bytes={i: (2048).to_bytes(2, "little") + bytes(GOAL_LEN - 2) for i in ids},
        quick=quick)
    bound = wire_time(sts_cycle_bytes(SO101_SERVOS), BAUD)
    return {"armlab_bus_sts_cycle_ms": float(np.median(ours) * 1e3),
            "peer_bus_sts_cycle_ms": float(np.median(theirs) * 1e3),
            "ratio_bus_sts": float(np.median(ratios)),
            "bus_sts_wire_bound_ms": bound * 1e3,
            "ratio_bus_sts_wire": float(np.median(ours)) / bound}
