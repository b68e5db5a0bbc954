"""The emulator's arm touches a wall over the real serial path (``armlab emulate --wall``):
the thesis line run by the lab's compliance loop through ``DynamixelBackend`` and a
pseudo-terminal, into a wall 18 cm ahead of the line's start, stops at the wall (within
the 2 mm its impact presses into a 2·10⁴ N/m wall) instead of running its
20 cm, and the loop's sensorless estimate τ_ext (eq. 2.21-2.23, the servos' loads) reads
the press; without the wall the same run goes the whole line. And a wall given badly is
one line naming the option."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _emulator import emulator

from armlab.app.arm.backends import make_backend
from armlab.app.commands.cli import main
from armlab.control.experiments.contact import wall_across_line
from armlab.control.experiments.thesis import run_line
from armlab.control.params import DEFAULT
from armlab.control.trajectory import thesis_line
from armlab.kinematics.catalog import load_robot

ARM = load_robot("receptionist_arm")
#: m of the wall ahead of the line's start: the 20 cm line ends 2 cm behind its surface
#: (the Contact tab's default; the compliance law presses that far without its lag check
#: stopping it, where a line run 16 cm into a wall is blocked and switched off)
WALL_M = 0.18


def _run(*emulate: str) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The thesis line over the emulated servos started at its first pose: the wall's
    (origin, normal) and the run's record."""
    line = thesis_line(ARM)
    _, _, origin, normal = wall_across_line(ARM, line.q[0], line.q[-1], WALL_M)
    pose = ",".join(f"{n}={math.degrees(a):.2f}" for n, a in zip(ARM.joint_names, line.q[0],
                                                                 strict=True))
    with emulator("--pose", pose, *emulate) as emu:
        run = run_line(ARM, lambda model, **kw: make_backend("serial", model, port=emu.port),
                       DEFAULT, controller="compliance", realtime=True)
    return origin, normal, run.snapshot


def _depth(snap: dict[str, np.ndarray], origin: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """m of the hand on the free side of the wall's plane, each recorded period."""
    hand = np.array([ARM.fk(q)[:3, 3] for q in snap["q"] if np.all(np.isfinite(q))])
    return (hand - origin) @ normal


@pytest.mark.realtime
@pytest.mark.slow
def test_the_emulated_arm_stops_at_the_wall_over_the_serial_path():
    line = thesis_line(ARM)
    _, _, origin, normal = wall_across_line(ARM, line.q[0], line.q[-1], WALL_M)
    wall = (",".join(f"{100 * c:.4f}" for c in origin) + "@"
            + ",".join(f"{c:.6f}" for c in normal))
    origin, normal, snap = _run(f"--wall={wall}")  # (= : its first number may be negative)
    depth = _depth(snap, origin, normal)
    assert depth.min() > -0.005, depth.min()  # pressed, never through (measured 2.1 mm in)
    assert depth.min() < 0.003, depth.min()  # and it got there
    # the servos' loads read the press: the estimate at the end, against the wall
    tail = snap["tau_ext"][-30:]
    assert np.max(np.abs(np.nanmean(tail, axis=0))) > 0.05, np.nanmean(tail, axis=0)
    # servos measure no wall: the loop records no contact force for them, even pressing
    assert np.all(np.isnan(snap["f_contact"])) and np.all(np.isnan(snap["f_contact_peak"]))
    # the same run without the wall goes the whole line, 2 cm past where the wall stood
    _, _, free = _run()
    assert _depth(free, origin, normal).min() < -0.015


@pytest.mark.parametrize("wall, said", [
    ("1,2@0,1,0", "expected X,Y,Z@NX,NY,NZ"),
    ("1,2,3@0,0,0", "the normal must not be zero"),
    ("1,2,x@0,1,0", "a coordinate is not a number"),
])
def test_a_wall_given_badly_is_one_line(wall, said, capsys):
    assert main(["emulate", f"--wall={wall}"]) != 0
    err = capsys.readouterr().err
    assert said in err and "--wall" in err and "Traceback" not in err


@pytest.mark.parametrize(("option", "value", "said"), [
    ("--wall-friction", "5", "--wall-friction must be in 0..2, got 5"),
    ("--wall-friction", "nan", "--wall-friction must be in 0..2, got nan"),
    ("--wall-stiffness", "1", "--wall-stiffness must be in 100..1e+06, got 1"),
])
def test_a_wall_s_number_out_of_range_is_one_line_naming_its_option(option, value, said,
                                                                    capsys):
    assert main(["emulate", "--wall=1,2,3@0,1,0", option, value]) != 0
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err and err.count("\n") == 1, err


@pytest.mark.realtime
@pytest.mark.slow
def test_a_block_across_the_line_stops_the_emulated_arm_as_the_wall_does():
    """``--wall-size``: a 20 × 20 cm block, 5 cm thick, its face where the wall stood:
    the hand stops at its face over the serial path."""
    line = thesis_line(ARM)
    _, _, origin, normal = wall_across_line(ARM, line.q[0], line.q[-1], WALL_M)
    wall = (",".join(f"{100 * c:.4f}" for c in origin) + "@"
            + ",".join(f"{c:.6f}" for c in normal))
    origin, normal, snap = _run(f"--wall={wall}", "--wall-size=20,20,5")
    depth = _depth(snap, origin, normal)
    assert -0.005 < depth.min() < 0.003, depth.min()


@pytest.mark.parametrize(("size", "said"), [
    ("20,0,5", "three sizes above 0 and at most 1000 cm"),
    ("20,x,5", "not numbers"),
    ("20,20", "three sizes above 0 and at most 1000 cm"),
])
def test_a_box_given_badly_is_one_line(size, said, capsys):
    assert main(["emulate", "--wall=1,2,3@0,1,0", f"--wall-size={size}"]) != 0
    err = capsys.readouterr().err
    assert said in err and "--wall-size" in err and "Traceback" not in err
    assert err.count("\n") == 1, err
