"""The batched plant equals N single plants (issue 16 item 3): q, qd to 1e-9, raw words exactly."""

from __future__ import annotations

import sys
import threading

import numpy as np
import pytest

from armlab.control.params import Params
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.families.dynamixel1.firmware import ERROR_ANGLE_LIMIT, ERROR_OVERLOAD
from armlab.hardware.families.dynamixel1.sim_backend import thesis_registers
from armlab.hardware.servos.servo_spec import RX24F
from armlab.hardware.sim.plant import Plant
from armlab.hardware.sim.servo_motor import IDEAL, ServoParams
from armlab.kinematics import load_robot
from armlab.kinematics.batched_dynamics import FLOAT_ARMS, batched_dynamics
from armlab.kinematics.dynamics import dynamics_model

MODEL = load_robot("receptionist_arm")
N = 5
Q0 = [np.array([0.0, 0.3, 0.3]), np.array([0.2, -0.4, 1.0]), np.array([-0.5, 0.8, -0.6]),
      np.array([1.0, 0.1, 0.2]), np.array([0.0, 1.4, 2.5])]  # the last one driven into its stops
GOALS = [(0.5, 0.8, 1.0), (-0.3, 0.2, 0.4), (0.0, 0.0, 0.0), (1.2, -0.5, -1.0), (0.1, 2.0, 2.9)]
SPEEDS = [(1.5, 1.5, 1.5), (0.0, 0.0, 0.0), (3.0, 0.5, 8.0), (0.2, 2.0, 0.0), (1.0, 1.0, 1.0)]
#: per arm: (start step, force (3,) N, link, point (3,), duration s)
PUSHES = [(100, (0.0, 5.0, 0.0), 2, (0.2, 0.0, 0.0), 0.3),
          (250, (3.0, 0.0, -2.0), 1, (0.1, 0.0, 0.0), 0.2),
          (400, (0.0, -4.0, 1.0), 2, (0.0, 0.0, 0.05), 0.5),
          (50, (-2.0, 2.0, 2.0), 0, (0.0, 0.05, 0.0), 0.1),
          (600, (0.0, 3.0, 0.0), 2, (0.15, 0.0, 0.0), 0.2)]


def _registers(i: int) -> list:
    """Thesis registers with a different goal, speed, gains and torque per arm (arm 2 off)."""
    regs = []
    for j in range(3):
        r = thesis_registers(RX24F, goal=RX24F.position_to_raw(GOALS[i][j]), cw_limit=0,
                             ccw_limit=1023, torque_on=i != 2)
        r.moving_speed = RX24F.speed_to_raw(SPEEDS[i][j]) if SPEEDS[i][j] else 0
        r.cw_compliance_margin = r.ccw_compliance_margin = i % 3
        r.cw_compliance_slope, r.ccw_compliance_slope = 16 << (i % 3), 32 << (j % 2)
        r.punch = 32 + 20 * i
        r.torque_limit = 1023 - 150 * i
        regs.append(r)
    return regs


def _pair() -> tuple[list[Plant], BatchedPlant]:
    singles = [Plant(MODEL, RX24F, q0=Q0[i], registers=_registers(i)) for i in range(N)]
    batch = BatchedPlant(MODEL, RX24F)
    for i in range(N):
        assert batch.add_arm(q0=Q0[i], registers=_registers(i)) == i
    return singles, batch


def _words(plant: Plant) -> np.ndarray:
    return np.array([(r.position, r.speed, r.load, r.error, r.moving, r.torque_enable,
                      r.torque_limit) for r in plant.reports()])


def _batch_words(batch: BatchedPlant, arm: int) -> np.ndarray:
    return np.array([(r.position, r.speed, r.load, r.error, r.moving, r.torque_enable,
                      r.torque_limit) for r in batch.reports(arm)])


def _all_words(batch: BatchedPlant) -> np.ndarray:
    """(N, n, 7) the same words from the vectorised accessors (what a class step reads)."""
    return np.stack([batch.present_position(), batch.present_speed(), batch.present_load(),
                     batch.error(), batch.moving(), batch.register("torque_enable"),
                     batch.register("torque_limit")], axis=2)


@pytest.mark.parametrize("n_arms", [5, FLOAT_ARMS + 16])  # per arm, then numpy over arms
def test_generated_dynamics_over_arms_equal_the_float_path(n_arms: int) -> None:
    rng = np.random.default_rng(3)
    q, qd, tau = (rng.uniform(-2.5, 2.5, (3, n_arms)) for _ in range(3))
    g, arm = [float(x) for x in MODEL.gravity], [3e-3] * 3
    fd = batched_dynamics(MODEL).fd(q, qd, tau, g, arm)
    one = dynamics_model(MODEL)
    ref = np.array([one.fd(list(q[:, k]), list(qd[:, k]), list(tau[:, k]), g, arm)
                    for k in range(n_arms)]).T
    assert fd.shape == (3, n_arms) and np.array_equal(fd, ref)


def test_two_threads_running_the_generated_dynamics_each_get_their_own_results() -> None:
    """The numpy fd writes into buffers (armlab.kinematics.batched_dynamics): two classes' clocks
    stepping plants of the same model at once, switching threads every few operations,
    still each get their own arms' accelerations, bit for bit."""
    dyn = batched_dynamics(MODEL)
    g, arm = [float(x) for x in MODEL.gravity], [3e-3] * 3
    inputs = [[rng.uniform(-2.5, 2.5, (3, 50)) for _ in range(3)]  # as many arms: one size
              for rng in (np.random.default_rng(5), np.random.default_rng(6))]
    want = [dyn.fd(q, qd, tau, g, arm) for q, qd, tau in inputs]
    wrong: list[int] = []

    def run(i: int) -> None:
        q, qd, tau = inputs[i]
        for _ in range(200):
            if not np.array_equal(dyn.fd(q, qd, tau, g, arm), want[i]):
                wrong.append(i)

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as the interpreter can
    try:
        threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120.0)
    finally:
        sys.setswitchinterval(interval)
    assert not any(t.is_alive() for t in threads) and wrong == []


@pytest.mark.parametrize("float_arms", [FLOAT_ARMS, 0])  # the plant's path for a few arms; numpy's
@pytest.mark.slow
def test_batched_plant_equals_n_single_plants_over_one_second(float_arms: int,
                                                              monkeypatch) -> None:  # noqa: ANN001
    monkeypatch.setattr("armlab.kinematics.batched_dynamics.FLOAT_ARMS", float_arms)
    singles, batch = _pair()
    worst = 0.0
    for k in range(1000):
        for i, (start, f, link, point, duration) in enumerate(PUSHES):
            if k == start:
                singles[i].push(np.array(f), link=link, point=np.array(point),
                                duration=duration)
                batch.push(i, np.array(f), link=link, point=np.array(point), duration=duration)
        if k == 700:  # a goal write mid-run, arm 1 only, as SimBackend.write does
            singles[1].servos[0].regs.goal_position = 300
            batch.set_registers(1, 0, goal_position=300)
        for p in singles:
            p.step()
        batch.step()
        q, qd = batch.q, batch.qd
        worst = max(worst, float(np.max(np.abs(q - np.array([p.q for p in singles])))),
                    float(np.max(np.abs(qd - np.array([p.qd for p in singles])))))
        assert np.array_equal(_all_words(batch), np.array([_words(p) for p in singles])), k
    for i, p in enumerate(singles):
        assert np.array_equal(_batch_words(batch, i), _words(p))
    assert worst <= 1e-9
    assert batch.t == pytest.approx(singles[0].t)
    moved = np.abs(batch.q - np.array(Q0))
    assert np.all(moved.max(axis=1) > 0.05)  # every arm really moved (torque off: it fell)


def test_adding_and_removing_an_arm_leaves_the_others_unchanged() -> None:
    _, ref = _pair()
    _, batch = _pair()
    for k in range(300):
        if k == 100:
            extra = batch.add_arm(q0=np.array([0.3, 0.3, 0.3]), registers=_registers(4))
            batch.push(extra, np.array([0.0, 9.0, 0.0]), link=2, point=np.zeros(3),
                       duration=0.5)
            batch.remove_arm(1)
            ref.remove_arm(1)
        if k == 200:
            batch.remove_arm(extra)
        ref.step()
        batch.step()
    assert batch.arm_ids.tolist() == [0, 2, 3, 4]
    assert [batch.row(a) for a in (0, 2, 3, 4)] == [0, 1, 2, 3]  # ids -> rows kept right
    for gone in (1, extra):
        with pytest.raises(ValueError, match="not in this plant"):
            batch.row(gone)
    assert all(batch.reports(a) == ref.reports(a) for a in (0, 2, 3, 4))
    assert np.array_equal(batch.q, ref.q)
    assert np.array_equal(batch.qd, ref.qd)
    assert np.array_equal(batch.present_position(), ref.present_position())


def test_vectorised_goal_writes_reach_the_servos() -> None:
    batch = BatchedPlant(MODEL, RX24F, 3, registers=_registers(0))
    goals = np.full((3, 3), 600, dtype=np.int64)
    batch.set_goals(goals, np.full((3, 3), 0, dtype=np.int64))
    batch.set_torque_enable(np.array([True, False, True]))
    batch.advance_to(0.3)
    assert batch.register("goal_position").tolist() == goals.tolist()
    pos = batch.present_position()
    assert np.all(np.abs(pos[[0, 2]] - 600) < 30) and np.all(np.abs(pos[1] - 600) > 30)


def test_bad_input_raises_naming_the_argument() -> None:
    batch = BatchedPlant(MODEL, RX24F, 2)
    with pytest.raises(ValueError, match="force_base"):
        batch.push(0, np.array([np.nan, 0.0, 0.0]), link=1, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="link"):
        batch.push(0, np.ones(3), link=3, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="arm"):
        batch.push(2, np.ones(3), link=0, point=np.zeros(3), duration=0.1)
    with pytest.raises(ValueError, match="arm"):
        batch.remove_arm(-1)
    with pytest.raises(ValueError, match="duration"):
        batch.push(0, np.ones(3), link=0, point=np.zeros(3), duration=-1.0)
    with pytest.raises(ValueError, match="values"):
        batch.set_goals(np.zeros((3, 3), dtype=np.int64))
    with pytest.raises(ValueError, match="n_arms"):
        BatchedPlant(MODEL, RX24F, -1)


# -- the batched controller and the class step -------------------------------------------

PARAMS = [Params(), Params(kp=40.0, kv=9.0, k_env=8.0, feedforward=False),
          Params(kp=10.0, kv=3.0, compliance=False), Params(kp=30.0, law="2.26", k_f=1.0),
          Params(kp=20.0, kv=6.0, alpha=0.2, m_env=0.5, d_env=3.0)]


@pytest.mark.slow
def test_overload_shutdown_wheel_mode_and_angle_limit_as_single_plants() -> None:
    """Firmware corners: an arm held in its stop at Torque Limit trips the overload alarm
    (Alarm Shutdown) and recovers when Torque Limit and Torque Enable are written again;
    an arm in wheel mode (CW = CCW angle limit 0); a goal outside the angle limits."""
    def regs(i: int) -> list:
        out = []
        for j in range(3):
            r = thesis_registers(RX24F, goal=1000 if j == 1 else 512, cw_limit=0,
                                 ccw_limit=1023)
            if i == 0:
                r.torque_limit = 400
            elif i == 1 and j == 0:
                r.cw_angle_limit = r.ccw_angle_limit = 0
                r.moving_speed = 300 | 1024
            elif i == 2:
                r.cw_angle_limit, r.ccw_angle_limit = 300, 700
            out.append(r)
        return out

    q0 = np.array([0.0, 1.4, 0.0])
    singles = [Plant(MODEL, RX24F, q0=q0, registers=regs(i)) for i in range(3)]
    batch = BatchedPlant(MODEL, RX24F)
    for i in range(3):
        batch.add_arm(q0=q0, registers=regs(i))
    tripped = False
    for k in range(2600):
        if k == 2400:  # the user recovers arm 0's servos
            for servo in singles[0].servos:
                servo.regs.torque_limit, servo.regs.torque_enable = 400, 1
            batch.set_registers(0, torque_limit=400, torque_enable=1)
        for p in singles:
            p.step()
        batch.step()
        assert np.array_equal(_all_words(batch), np.array([_words(p) for p in singles])), k
        tripped = tripped or bool(batch.reports(0)[1].error & ERROR_OVERLOAD)
    assert tripped
    assert np.max(np.abs(batch.q - np.array([p.q for p in singles]))) <= 1e-9
    assert np.max(np.abs(batch.qd - np.array([p.qd for p in singles]))) <= 1e-9
    assert batch.reports(2)[1].error & ERROR_ANGLE_LIMIT  # goal 1000 outside CCW limit 700


def test_per_arm_writes_and_an_empty_class() -> None:
    batch = BatchedPlant(MODEL, RX24F, 2, registers=_registers(0))
    batch.set_goal(1, [100, 200, 300], [5, 6, 7])
    assert batch.registers(1)[2].goal_position == 300 and batch.registers(1)[0].moving_speed == 5
    assert batch.registers(0)[2].goal_position != 300
    with pytest.raises(ValueError, match="rows"):
        batch.write_registers("goal_position", np.zeros((1, 3), dtype=np.int64), [2])
    with pytest.raises(ValueError, match="on"):
        batch.set_torque_enable(np.array([1, 0]))
    with pytest.raises(ValueError, match="name"):
        batch.register("goal")
    empty = BatchedPlant(MODEL, RX24F)
    empty.step()
    empty.step()
    assert empty.q.shape == (0, 3) and empty.t == pytest.approx(0.002)


def test_directions_and_servo_params_per_joint_as_single_plants() -> None:
    dirs = (-1.0, 1.0, -1.0)
    params = (IDEAL, ServoParams(coulomb_friction=0.1, viscous_friction=0.02),
              ServoParams(rotor_inertia=1e-3, friction_speed=0.05))
    singles = [Plant(MODEL, RX24F, q0=Q0[i], registers=_registers(i), directions=dirs,
                     params=params) for i in range(3)]
    batch = BatchedPlant(MODEL, RX24F, directions=dirs, params=params)
    for i in range(3):
        batch.add_arm(q0=Q0[i], registers=_registers(i))
    for _ in range(300):
        for p in singles:
            p.step()
        batch.step()
        assert np.array_equal(_all_words(batch), np.array([_words(p) for p in singles]))
    assert np.max(np.abs(batch.q - np.array([p.q for p in singles]))) <= 1e-9
    assert np.max(np.abs(batch.qd - np.array([p.qd for p in singles]))) <= 1e-9


@pytest.mark.slow
def test_walls_far_from_a_hand_are_left_out_without_changing_a_number() -> None:
    """Each arm's wall across its hand's way, halfway along where its servos take it in
    0.3 s (centimetres off at the start: beyond the margin, so the plant leaves it out of
    its steps until the joints' speeds could have brought the hand close): the batched
    plant's arms stay within 1e-9 of single plants' that hold every wall near enough to
    touch, and the hands meet their walls."""
    free, _ = _pair()
    start = [MODEL.fk(p.q)[:3, 3] for p in free]
    for _ in range(300):
        for p in free:
            p.step()
    way = [MODEL.fk(p.q)[:3, 3] - a for p, a in zip(free, start, strict=True)]
    singles, batch = _pair()
    for i, (a, d) in enumerate(zip(start, way, strict=True)):
        normal = -d / np.linalg.norm(d)
        singles[i].set_wall(a + 0.5 * d, normal)
        batch.set_wall(i, a + 0.5 * d, normal)
    assert min(0.5 * float(np.linalg.norm(d)) for d in way) > 0.005  # all off the margin
    assert batch._near_walls().rows.size == 0  # so left out at first
    worst, touched = 0.0, set()
    for _ in range(300):
        for i, p in enumerate(singles):
            p.step()
            if p.wall_force() > 0.0:
                touched.add(i)
        batch.step()
        worst = max(worst, float(np.max(np.abs(batch.q - np.array([p.q for p in singles])))),
                    float(np.max(np.abs(batch.qd - np.array([p.qd for p in singles])))))
    assert worst <= 1e-9
    assert touched == set(range(N)), touched


@pytest.mark.slow
def test_spring_and_wall_per_arm_as_single_plants() -> None:
    """Arm 0 dragged by a spring (damped), arm 1 pressing a wall, arm 3 both, the rest free;
    the spring moved, the wall removed and put back mid-run, as Plant.set_spring/set_wall."""
    singles, batch = _pair()
    tip = MODEL.fk(Q0[1])[:3, 3]
    normal = np.array([0.0, 0.3, 1.0])
    wall_origin = tip + 0.01 * normal / np.linalg.norm(normal)  # the tip starts 1 cm inside
    worst = 0.0
    for k in range(600):
        if k == 0:
            for who, obj in ((0, singles[0]), (3, singles[3])):
                args = (np.array([0.2, 0.1, -0.1]),)
                kw = {"stiffness": 80.0, "link": 2, "point": np.array([0.25, 0.0, 0.0]),
                      "damping": 2.0}
                obj.set_spring(*args, **kw)
                batch.set_spring(who, *args, **kw)
            for who in (1, 3):
                singles[who].set_wall(wall_origin, normal)
                batch.set_wall(who, wall_origin, normal)
            singles[4].set_wall(np.zeros(3), np.array([1.0, 0.0, 0.0]), link=1,
                                stiffness=800.0, damping=5.0)
            batch.set_wall(4, np.zeros(3), np.array([1.0, 0.0, 0.0]), link=1,
                           stiffness=800.0, damping=5.0)
        if k == 200:
            singles[0].set_spring(np.array([0.0, -0.2, 0.1]), stiffness=50.0, link=1,
                                  point=np.array([0.1, 0.0, 0.0]))
            batch.set_spring(0, np.array([0.0, -0.2, 0.1]), stiffness=50.0, link=1,
                             point=np.array([0.1, 0.0, 0.0]))
            singles[1].set_wall(None)
            batch.set_wall(1, None)
        if k == 300:
            singles[1].set_wall(wall_origin, normal, stiffness=2000.0)
            batch.set_wall(1, wall_origin, normal, stiffness=2000.0)
        if k == 400:
            singles[3].clear_forces()
            batch.clear_forces(3)
            singles[0].set_spring(None, stiffness=0.0, link=0, point=np.zeros(3))
            batch.set_spring(0, None, stiffness=0.0, link=0, point=np.zeros(3))
        for p in singles:
            p.step()
        batch.step()
        worst = max(worst,
                    float(np.max(np.abs(batch.q - np.array([p.q for p in singles])))),
                    float(np.max(np.abs(batch.qd - np.array([p.qd for p in singles])))))
        assert np.array_equal(_all_words(batch), np.array([_words(p) for p in singles])), k
    assert worst <= 1e-9
    # the fields did something: the same arms without them end elsewhere
    _, free = _pair()
    for _ in range(600):
        free.step()
    moved = np.max(np.abs(batch.q - free.q), axis=1)
    assert np.all(moved[[0, 1, 3]] > 1e-3) and moved[2] == 0.0


def test_spring_and_wall_go_with_their_arm() -> None:
    batch = BatchedPlant(MODEL, RX24F, 3)
    batch.set_spring(1, np.array([0.1, 0.1, 0.1]), stiffness=50.0, link=2, point=np.zeros(3))
    batch.set_wall(2, np.zeros(3), np.array([0.0, 0.0, 1.0]))
    batch.remove_arm(0)
    single = Plant(MODEL, RX24F)
    single.set_spring(np.array([0.1, 0.1, 0.1]), stiffness=50.0, link=2, point=np.zeros(3))
    for _ in range(50):
        batch.step()
        single.step()
    assert np.max(np.abs(batch.q[0] - single.q)) <= 1e-9
    with pytest.raises(ValueError, match="normal_base"):
        batch.set_wall(1, np.zeros(3))
    with pytest.raises(ValueError, match="stiffness"):
        batch.set_spring(1, np.zeros(3), stiffness=-1.0, link=0, point=np.zeros(3))
    with pytest.raises(ValueError, match="arm 0"):
        batch.set_wall(0, None)


def test_pushes_on_many_rows_at_once_equal_one_push_per_arm() -> None:
    """``push_rows`` (the floor on many feet) as the same pushes one by one; bad input adds
    none."""
    _, one = _pair()
    _, many = _pair()
    forces = np.array([[0.0, 2.0, -1.0], [1.0, 0.0, 3.0], [-2.0, 1.0, 0.5]])
    for k in range(300):
        if k in (20, 150):
            for arm, f in zip((4, 0, 2), forces * (1 + k / 100), strict=True):
                one.push(arm, f, link=2, point=np.array([0.1, 0.0, 0.02]), duration=0.1)
            many.push_rows([4, 0, 2], forces * (1 + k / 100), link=2,
                           point=np.array([0.1, 0.0, 0.02]), duration=0.1)
        one.step()
        many.step()
    assert np.array_equal(one.q, many.q) and np.array_equal(one.qd, many.qd)
    _, ref = _pair()
    for _ in range(300):
        ref.step()
    assert np.max(np.abs(ref.q - many.q)[[0, 2, 4]]) > 1e-4  # the pushes did something
    for rows, f, link in (([0, 5], np.ones((2, 3)), 1), ([0, 1], np.ones((3, 3)), 1),
                          ([0], np.array([[np.nan, 0.0, 0.0]]), 1), ([0], np.ones((1, 3)), 3),
                          (None, np.ones((5, 3)), 1)):
        with pytest.raises(ValueError, match="rows|force_base|link"):
            many.push_rows(rows, f, link=link, point=np.zeros(3), duration=0.1)  # type: ignore[arg-type]
    for _ in range(10):
        one.step()
        many.step()
    assert np.array_equal(one.q, many.q)  # the bad pushes never were
