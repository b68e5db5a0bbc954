"""The generated dynamics compiled to machine code (armlab.kinematics.compiled_dynamics):
the same numbers as the numpy and float code, bit for bit, and the numpy code without
numba."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from armlab.hardware.families.dynamixel1 import compiled_contact
from armlab.hardware.families.dynamixel1.batched_backend import add_sim_arm
from armlab.hardware.families.dynamixel1.batched_plant import BatchedPlant
from armlab.hardware.servos.servo_spec import RX24F
from armlab.kinematics import compiled_dynamics, load_robot, machine_code
from armlab.kinematics._rnea_codegen import dynamics_model
from armlab.kinematics.batched_dynamics import FLOAT_ARMS, batched_dynamics

#: the serial chains a class's plant can hold (the quadruped's legs have their own)
CHAINS = ("receptionist_arm", "so101", "planar_servo_arm", "redundant_planar",
          "open_manipulator_x")


def _numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(machine_code, "ENABLED", False)


@pytest.mark.slow
@pytest.mark.parametrize("name", CHAINS)
def test_compiled_fd_and_frames_equal_the_numpy_and_float_code_bit_for_bit(
        name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    model = load_robot(name)
    dyn = batched_dynamics(model)
    assert dyn.compile(), dyn.compile_error  # numba is one of armlab's dependencies
    n, arms = dyn.n, FLOAT_ARMS + 76
    rng = np.random.default_rng(7)
    q, qd, tau = (rng.uniform(-2.5, 2.5, (n, arms)) for _ in range(3))
    g, armature = [float(x) for x in model.gravity], list(rng.uniform(0.0, 0.01, n))
    fd, frames = dyn.fd(q, qd, tau, g, armature), dyn.frames(q)
    few = dyn.fd(q[:, :5], qd[:, :5], tau[:, :5], g, armature)  # compiled at any size
    strided = dyn.frames(q[:, ::3])  # a view of every third arm: copied, same numbers
    one = dynamics_model(model)
    float_fd = np.array([one.fd(list(q[:, k]), list(qd[:, k]), list(tau[:, k]), g, armature)
                         for k in range(arms)]).T
    _numpy(monkeypatch)
    assert np.array_equal(fd, dyn.fd(q, qd, tau, g, armature))
    assert np.array_equal(fd, float_fd) and np.array_equal(few, float_fd[:, :5])
    numpy_frames = dyn.frames(q)
    assert frames.shape == (12 * n, arms) and np.array_equal(frames, numpy_frames)
    assert np.array_equal(strided, numpy_frames[:, ::3])


def _class(arms: int, *, boxes: bool = False) -> BatchedPlant:
    """A class of ``arms`` thesis arms, each pushed, one on a spring, every other one at a
    wall its hand is pressed into (planes, some with friction; with ``boxes``, every
    fourth wall a box its links meet too: many touches an arm)."""
    model = load_robot("receptionist_arm")
    plant = BatchedPlant(model, RX24F, dt=1e-3)
    rng = np.random.default_rng(11)
    for a in range(arms):
        q = np.array([0.0, 0.3, 0.3]) + rng.uniform(-0.3, 0.3, 3)
        add_sim_arm(plant, q0=q)
        tip = model.fk(q)[:3, 3]
        if a % 2 == 0:
            normal = np.array([0.0, 0.0, 1.0]) if a % 4 == 0 else np.array([1.0, 0.0, 0.0])
            size = (0.2, 0.2, 0.1) if boxes and a % 8 == 0 else None
            plant.set_wall(a, tip + 0.002 * normal, normal, stiffness=2e4, damping=50.0,
                           friction=0.5 if a % 6 == 0 else 0.0, size=size)
        plant.push(a, rng.uniform(-3.0, 3.0, 3), link=2, point=np.array([0.1, 0.0, 0.0]),
                   duration=0.05)
    plant.set_spring(1, np.array([0.1, 0.1, 0.1]), stiffness=50.0, link=2,
                     point=np.array([0.05, 0.0, 0.0]))
    return plant


@pytest.mark.slow
@pytest.mark.parametrize("boxes", [False, True], ids=["planes", "boxes"])
def test_a_class_plant_steps_the_same_compiled_as_with_numpy(
        boxes: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """A class past FLOAT_ARMS arms, walls (planes, boxes), friction, pushes and a spring:
    300 steps with the compiled code (every part of it: BatchedPlant.compile) and with
    numpy give the same states, servo words and wall forces, bit for bit."""
    assert _class(2).compile()  # the dynamics, link points, walls' pushes, firmware tick
    # (planes only: the walls near their arms are found compiled too)
    assert compiled_contact.MACHINE.kernel("plane_touches") is not None
    runs = []
    for enabled in (True, False):
        monkeypatch.setattr(machine_code, "ENABLED", enabled)
        plant = _class(FLOAT_ARMS + 8, boxes=boxes)
        forces = []
        for _ in range(300):
            plant.step()
            forces.append(plant.wall_forces()[1].copy())
        runs.append((plant.q, plant.qd, plant.present_position(), plant.present_load(),
                     forces))
    (q, qd, pos, load, forces), (q2, qd2, pos2, load2, forces2) = runs
    assert np.array_equal(q, q2) and np.array_equal(qd, qd2)
    assert np.array_equal(pos, pos2) and np.array_equal(load, load2)
    assert all(np.array_equal(a, b) for a, b in zip(forces, forces2, strict=True))
    assert max(float(f.max(initial=0.0)) for f in forces) > 1.0  # the walls were pressed


def test_code_numba_cannot_compile_leaves_the_numpy_code_and_says_why() -> None:
    source = ("def fd(q, qd, tau, g, armature):\n    return undefined_name\n"
              "def frames(q):\n    return undefined_name\n")
    broken = machine_code.MachineCode(
        lambda: compiled_dynamics.compile_kernels(source, 1, "<broken>"), "<broken>")
    assert broken.wait(120.0) is False
    assert broken.kernel("fd") is None and broken.kernel("frames") is None
    assert broken.error is not None and "could not compile <broken>" in broken.error


@pytest.mark.slow
def test_without_numba_a_class_runs_on_the_numpy_code() -> None:
    """A Python where numba cannot be imported: compile() says so and a class's plant
    still steps, on numpy."""
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "import numpy as np\n"
        "from armlab.kinematics import load_robot\n"
        "from armlab.kinematics.batched_dynamics import batched_dynamics, FLOAT_ARMS\n"
        "m = load_robot('receptionist_arm'); d = batched_dynamics(m)\n"
        "print(d.compile(60.0), d.compile_error)\n"
        "q = np.zeros((3, FLOAT_ARMS + 10))\n"
        "print(d.fd(q, q, q, [0.0, 0.0, -9.81], [0.0] * 3).shape)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True).stdout.splitlines()
    assert out[0].startswith("False numba is not installed")
    assert out[1] == f"(3, {FLOAT_ARMS + 10})"
