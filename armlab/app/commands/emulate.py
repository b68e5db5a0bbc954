"""``armlab emulate --robot NAME``: simulated Dynamixel servos behind a pseudo-terminal.

The first line printed is ``port: /dev/pts/N`` (flushed): point ``armlab scan``,
``armlab serve --backend serial`` or any Dynamixel client at it. The servos speak
protocol 1.0 (RX-24F, AX-12A) or, for X-series servos (``--servo XM430-W350``, and by
default for ``open_manipulator_x``: XM430-W350, IDs 11..14 and its gripper's servo 15,
moving the fingers), protocol 2.0; for ``so101`` Feetech STS (STS3215, IDs 1..5 and the
jaw's servo 6, at the arm's 5 V supply). Serves until SIGINT or SIGTERM, then exits
cleanly.

``--disturb JOINT:NM@S`` applies a known torque to a joint of the simulated arm (a
weight hung at the joint) from S s of the emulator's plant clock on: what
``armlab experiment observers --backend serial --applied NM`` estimates from the
servos' current. Repeat it for several.

``--fault JOINT:FLAG@S`` makes the X-series servo of a joint raise a Hardware Error
Status flag (``input_voltage``, ``overheating``, ``motor_encoder``, ``electrical_shock``,
``overload``) once its torque has been on for S s: its replies carry the alert bit, and
a flag in its Shutdown register (the XM430's factory value: overheating, electrical
shock, overload) switches its torque off until a REBOOT, as the servo's firmware does.
On Feetech STS servos (``--robot so101``) the flag is a status error bit (``voltage``,
``angle``, ``overheat``, ``overcurrent``, ``overload``) carried by every reply until the
torque is switched off and on (an overload also holds the output back, as the
firmware's own), or ``silent``: the servo stops answering for good (a cut cable).
Repeatable.

``--wall X,Y,Z@NX,NY,NZ`` puts a wall in the emulated arm's world: a plane through the
point (X, Y, Z) cm, base frame, facing the free side along (NX, NY, NZ), that the hand
presses into with ``--wall-stiffness`` N/m (default 2·10⁴, a wooden table top) and
``--wall-damping`` N·s/m (default 50), as the simulated arm's (``armlab experiment
contact``): the lab over the real serial path feels it in its servos' loads only, as an
arm touching a real table does. ``--wall-size W,H,T`` makes it a box instead (a table top,
a block: W × H cm across its face, T cm thick behind it, centred on the point), which the
arm's links meet with their collision shapes too.

``--control FIFO`` makes FIFO a named pipe the emulator reads lines from, as a person's
hand on an arm whose torque is off: ``hold JOINT DEG`` holds a joint (name or index, or
``gripper`` for the gripper's servo) at DEG degrees of the joint until ``release JOINT``
lets it go. The guided calibration (``armlab scan --calibrate``) is tested this way.

``--pose JOINT=DEG,...`` starts the arm there (joint name or index, degrees of the joint;
joints not named start at zero): each joint rests where it was put, as an
unpowered arm rests on its gears where it was left, until its servo's torque comes on.
So the lab can be tried on an arm that is not at zero when it is switched on, as a real
one never is (every family, the quadruped's legs too).

``--link PATH`` also makes PATH a symlink to that pseudo-terminal (replacing one an
earlier emulator left), so the emulator keeps its name across restarts, as a
``/dev/serial/by-id/...`` path does across re-plugs; the link goes when it exits.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import stat
import sys
from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np

from armlab.app.commands.scan import _ids
from armlab.control.experiments.contact import box_size_cm, check_wall_numbers
from armlab.hardware import family_parts
from armlab.hardware.backends.joint_map import default_joint_map, robot_joints
from armlab.hardware.emulator.pty import Faults, PtyEmulator
from armlab.hardware.servos.registry import FAMILIES, family
from armlab.hardware.sim.plant import Plant
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain
from armlab.kinematics.validate import joint_index

NAME = "emulate"
HELP = "serve simulated servos of a robot on a pseudo-terminal (prints 'port: /dev/pts/N')"


def _fraction(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"a fraction of replies in [0, 1], got {v}")
    return v


T = TypeVar("T")

#: what ``--disturb`` takes
DISTURB_FORMAT = ("JOINT:NM@S (joint index or name, torque in N·m along the joint's axis, "
                  "seconds after the emulator starts), e.g. 1:0.3@1.5")


def parse_disturbance(text: str, names: Sequence[str]) -> tuple[int, float, float]:
    """``--disturb JOINT:NM@S`` -> (joint index, torque N·m, start s).

    Raises:
        ValueError: one line naming the option, the value, what is wrong and the format.
    """
    return _joint_event("--disturb", text, names, DISTURB_FORMAT,
                        lambda middle: _number(middle, "the torque"), "the start")


def fault_format(which: int | str = 2) -> str:
    """What ``--fault`` takes for servos of the family ``which`` names (its protocol)."""
    return (f"JOINT:FLAG@S (joint index or name; FLAG one of "
            f"{', '.join(family(which).fault_flags)}; S seconds of torque on before it), "
            "e.g. 1:overload@3")


def parse_fault(text: str, names: Sequence[str], *, protocol: int | str = 2
                ) -> tuple[int, int, float]:
    """``--fault JOINT:FLAG@S`` -> (joint index, the flag: one of the ``fault_flags`` of
    the family of ``protocol``, a Hardware Error Status bit on the X-series, a status
    error bit on an STS; s of torque on).

    Raises:
        ValueError: one line naming the option, the value, what is wrong and the format.
    """
    def flag(middle: str) -> int:
        found = family(protocol).fault_flags.get(middle.strip().lower())
        if found is None:
            raise ValueError(f"no flag {middle.strip()!r}")
        return found

    return _joint_event("--fault", text, names, fault_format(protocol), flag, "the time")


def _joint_event(option: str, text: str, names: Sequence[str], fmt: str,
                 middle: Callable[[str], T], when: str) -> tuple[int, T, float]:
    """``JOINT:X@S`` -> (joint index, ``middle(X)``, S >= 0 s); ValueError naming
    ``option``, the value, what is wrong and ``fmt``."""
    m = re.fullmatch(r"\s*([^:@]+):([^:@]+)@([^:@]+)\s*", text)
    try:
        if m is None:
            raise ValueError(f"not {fmt.split(' ')[0]}")
        joint = joint_index(m[1], names)
        value = middle(m[2])
        at = _number(m[3], when)
        if at < 0:
            raise ValueError(f"{when} must be >= 0 s, got {at:g}")
    except ValueError as exc:
        raise ValueError(f"{option} {_quoted(text, 60)}: {exc}; expected {fmt}") from None
    return joint, value, at


def _quoted(text: str, limit: int = 40) -> str:
    """``text`` quoted for a message, at most ``limit`` characters of it (a pasted page is
    not echoed whole)."""
    text = text.strip()
    return repr(text[:limit]) + ("…" if len(text) > limit else "")


def _number(text: str, name: str) -> float:
    """``text`` as a finite float; ValueError naming ``name`` and quoting it
    (:func:`_quoted`)."""
    shown = _quoted(text)
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{name} is not a number: {shown}") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError(f"{name} must be finite, got {shown}")
    return v


#: what ``--wall`` takes
WALL_FORMAT = ("X,Y,Z@NX,NY,NZ (a point of the plane in cm and its normal towards the "
               "free side, base frame), e.g. --wall=-11.3,15.7,0@0,-1,0")


def parse_wall(text: str) -> tuple[list[float], list[float]]:
    """``--wall X,Y,Z@NX,NY,NZ`` -> (origin (3,) m, unit normal (3,)), base frame.

    Raises:
        ValueError: one line naming the option, the value, what is wrong and the format.
    """
    try:
        point, sep, normal = text.partition("@")
        xyz = [_number(v, "a coordinate") / 100.0 for v in point.split(",")]
        n = [_number(v, "a normal's component") for v in normal.split(",")]
        if not sep or len(xyz) != 3 or len(n) != 3:
            raise ValueError(f"not {WALL_FORMAT.split(' ')[0]}")
        length = math.sqrt(sum(c * c for c in n))
        if length < 1e-9:
            raise ValueError("the normal must not be zero")
    except ValueError as exc:
        raise ValueError(f"--wall {_quoted(text, 60)}: {exc}; expected {WALL_FORMAT}") from None
    return xyz, [c / length for c in n]


def parse_pose(text: str, names: Sequence[str]) -> dict[int, float]:
    """``--pose JOINT=DEG,...`` -> {joint index: angle rad}.

    Raises:
        ValueError: one line naming the option, the part that is wrong and the format.
    """
    fmt = "JOINT=DEG,... (joint name or index, degrees), e.g. shoulder_lift=60,elbow_flex=-45"
    pose: dict[int, float] = {}
    for part in text.split(","):
        joint, sep, deg = part.partition("=")
        try:
            if not sep:
                raise ValueError(f"{part.strip()!r} is not JOINT=DEG")
            k = joint_index(joint.strip(), names)
            if k in pose:
                raise ValueError(f"joint {names[k]} named twice")
            pose[k] = math.radians(_number(deg, f"the angle of {names[k]}"))
        except ValueError as exc:
            raise ValueError(f"--pose {_quoted(text, 60)}: {exc}; expected {fmt}") from None
    return pose


def _raise_priority(nice: int) -> None:
    """Servos never stall: ask the OS to schedule the emulator ahead of ordinary programs
    (``nice`` < 0 needs root or CAP_SYS_NICE; without them nothing changes)."""
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except OSError:
        pass


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="receptionist_arm",
                        help="robot name or URDF (default receptionist_arm)")
    parser.add_argument("--preset", help="link-length preset of the receptionist arm")
    parser.add_argument("--baud", type=float, default=1_000_000,
                        help="the servos' baud, bit/s (default 1000000)")
    parser.add_argument("--ids", type=_ids, help="servo IDs in joint order "
                        "(default 1,3,5 for receptionist_arm, 11..14 for open_manipulator_x, "
                        "1..5 for so101, else 1..n); the gripper's servo (open_manipulator_x, "
                        "so101) takes the ID after "
                        "the highest (15 by default)")
    emulated = [f for f in FAMILIES if family_parts.has(f, "emulator")]
    parser.add_argument("--servo", choices=tuple(t.name for f in emulated
                                                 for t in f.tables.values()),
                        help="servo model (default RX-24F for the thesis arm, XM430-W350 for "
                        "open_manipulator_x, STS3215 for so101, else AX-12A); X-series servos "
                        "speak protocol 2.0, STS Feetech's")
    parser.add_argument("--pace", action="store_true",
                        help="hold replies for their wire time at the set baud")
    parser.add_argument("--dt", type=_plant_step, default=1e-3, metavar="S",
                        help="the plant's step, s (default 0.001; up to 0.005 where a slow "
                        "machine cannot step many servos' physics on the wall clock: the "
                        "quadruped's 12 servos at 0.004)")
    parser.add_argument("--drop", type=_fraction, default=0.0, metavar="F",
                        help="fraction of replies never sent")
    parser.add_argument("--corrupt", type=_fraction, default=0.0, metavar="F",
                        help="fraction of replies with one byte flipped")
    parser.add_argument("--delay", type=_fraction, default=0.0, metavar="F",
                        help="fraction of replies held back --delay-time s")
    parser.add_argument("--delay-time", type=float, default=0.05, metavar="S",
                        help="s a delayed reply is held (default 0.05)")
    parser.add_argument("--seed", type=int, help="random seed of the fault injection")
    parser.add_argument("--echo", action="store_true",
                        help="echo received bytes first, like a half-duplex TTL adapter")
    parser.add_argument("--nice", type=int, default=-10,
                        help="scheduling priority to ask for (default -10: ahead of ordinary "
                        "programs, like a device; needs root, else ignored)")
    parser.add_argument("--log", metavar="FILE",
                        help="write one line per received (rx) and sent (tx) packet")
    parser.add_argument("--disturb", action="append", default=[], metavar="JOINT:NM@S",
                        help="apply a known torque to a joint of the simulated arm: "
                        + DISTURB_FORMAT.replace("%", "%%") + " (repeatable)")
    parser.add_argument("--fault", action="append", default=[], metavar="JOINT:FLAG@S",
                        help="the joint's servo raises an alarm after S s of torque on: "
                        "JOINT:FLAG@S (joint index or name), FLAG one of "
                        + "; ".join(f"{f.title}'s {', '.join(f.fault_flags)}"
                                    for f in FAMILIES if f.fault_flags)
                        + " (silent: it stops answering; repeatable)")
    parser.add_argument("--control", metavar="FIFO",
                        help="a serial arm: read 'hold JOINT DEG' and 'release JOINT' lines "
                        "from this named pipe (made if missing), a hand moving the arm")
    parser.add_argument("--wall", metavar="X,Y,Z@NX,NY,NZ",
                        help="a wall the emulated arm's hand presses into: "
                        + WALL_FORMAT.replace("%", "%%"))
    parser.add_argument("--wall-stiffness", type=float, default=2e4, metavar="N_PER_M",
                        help="the wall's stiffness, N/m of penetration (default 2e4)")
    parser.add_argument("--wall-damping", type=float, default=50.0, metavar="NS_PER_M",
                        help="the wall's damping, N·s/m (default 50)")
    parser.add_argument("--wall-friction", type=float, default=0.0, metavar="MU",
                        help="the wall's Coulomb friction coefficient (default 0)")
    parser.add_argument("--wall-size", metavar="W,H,T",
                        help="make the wall a box: W x H cm across its face, T cm thick "
                             "(a table top, a block), met by the arm's links too")
    parser.add_argument("--pose", type=str, metavar="JOINT=DEG,...",
                        help="start these joints at these angles (joint name or index, "
                        "degrees), each resting there until its servo's torque comes on, "
                        "e.g. shoulder_lift=60,elbow_flex=-45")
    parser.add_argument("--link", metavar="PATH",
                        help="also make PATH a symlink to the pseudo-terminal (replaced on "
                             "restart, like a /dev/serial/by-id name)")


def _arm_plant(network: object) -> Plant:
    """The plant of a serial arm's emulated servos (any family's), for ``--disturb``,
    ``--fault`` and ``--wall``."""
    physics = network.physics  # type: ignore[attr-defined]  # every family's network has a physics
    return physics.plant if hasattr(physics, "plant") else physics.plants[0]


def open_control(path: str) -> int:
    """The named pipe ``--control`` reads (made when missing), open for reading without
    blocking; also open for writing, so the emulator never sees it end between writers.

    Raises:
        ValueError: ``path`` exists and is not a named pipe.
    """
    if not os.path.exists(path):
        os.mkfifo(path)
    elif not stat.S_ISFIFO(os.stat(path).st_mode):
        raise ValueError(f"--control {path}: exists and is not a named pipe")
    return os.open(path, os.O_RDWR | os.O_NONBLOCK)


def control_handler(network: object, model: SerialChain, gripper: object | None
                    ) -> Callable[[str], None]:
    """What ``--control`` does with a line: ``hold JOINT DEG`` / ``release JOINT`` on the
    network's physics (the gripper's horn follows its jaw or finger, ``gripper.to_servo``);
    a line it cannot take is said on stderr, in one line, and changes nothing."""
    physics = network.physics  # type: ignore[attr-defined]  # every family's network has a physics

    def handle(line: str) -> None:
        words = line.split()
        try:
            if len(words) not in (2, 3) or words[0] not in ("hold", "release") or \
                    (words[0] == "hold") != (len(words) == 3):
                raise ValueError("expected 'hold JOINT DEG' or 'release JOINT'")
            if words[1] == "gripper":
                if gripper is None:
                    raise ValueError("this arm has no gripper servo")
                joint = model.n
                angle = None if len(words) == 2 else \
                    gripper.to_servo(math.radians(_number(words[2], "DEG")))  # type: ignore[attr-defined]  # a gripper servo here: it has to_servo
            else:
                joint = joint_index(words[1], model.joint_names)
                angle = None if len(words) == 2 else math.radians(_number(words[2], "DEG"))
            physics.hold(joint, angle)
        except ValueError as exc:
            print(f"armlab emulate --control: {line!r}: {exc}", file=sys.stderr, flush=True)

    return handle


def make_link(link: str, target: str) -> None:
    """Point the symlink ``link`` at ``target``, replacing a symlink already there
    (atomically: a reader sees the old or the new device, never none).

    Raises:
        ValueError: ``link`` exists and is not a symlink (never overwrite a file).
    """
    if os.path.lexists(link) and not os.path.islink(link):
        raise ValueError(f"--link {link}: exists and is not a symlink; choose another path")
    tmp = f"{link}.{os.getpid()}.tmp"
    os.symlink(target, tmp)
    os.replace(tmp, link)


def remove_link(link: str, target: str) -> None:
    """Remove the symlink ``link`` if it still points at ``target`` (a newer emulator's
    link is left alone)."""
    try:
        if os.path.islink(link) and os.readlink(link) == target:
            os.unlink(link)
    except OSError:
        pass


def _plant_step(text: str) -> float:
    """``--dt``: a plant step of 0.1 to 5 ms (coarser steps misstate a servo's own loop)."""
    value = float(text)
    if not 1e-4 <= value <= 5e-3:
        raise argparse.ArgumentTypeError(f"must be 0.0001..0.005 s, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    if not -20 <= args.nice <= 19:
        raise ValueError(f"--nice must be in -20..19, got {args.nice}")
    model = load_robot(args.robot, preset=args.preset)
    jmap = default_joint_map(model, servo=args.servo,
                             ids=tuple(args.ids) if args.ids is not None else None)
    # the servo family's own emulator (armlab.hardware.families); ValueError for a baud
    # its servos cannot take
    network = family_parts.load(jmap.family, "emulator")(model, jmap, baud=args.baud, dt=args.dt)
    if args.pose:
        names = [j.name for j in robot_joints(model)]
        pose = dict.fromkeys(range(len(names)), 0.0) | parse_pose(args.pose, names)
        for k, angle in pose.items():  # the joints not named rest at zero
            lo, hi = jmap.joints[k].lower, jmap.joints[k].upper
            if not lo <= angle <= hi:
                raise ValueError(f"--pose: {names[k]} at {math.degrees(angle):+.1f}° is "
                                 f"outside its limits {math.degrees(lo):+.1f}..."
                                 f"{math.degrees(hi):+.1f}°")
            network.physics.rest(k, angle)
        for s in network.servos:
            network.physics.report(s)
    disturbances = []
    if args.disturb:
        if not isinstance(model, SerialChain):
            raise ValueError(f"--disturb: a joint torque on a serial arm, not the {model.name}")
        disturbances = [parse_disturbance(d, model.joint_names) for d in args.disturb]
        plant = _arm_plant(network)
        for joint, torque, start in disturbances:
            plant.apply_joint_torque(joint, torque, start=start)
    wall = None
    if args.wall_size and not args.wall:
        raise ValueError("--wall-size: place the box with --wall X,Y,Z@NX,NY,NZ (the centre "
                         "of its face, and the face's normal)")
    if args.wall:
        if not isinstance(model, SerialChain):
            raise ValueError(f"--wall: a serial arm's hand touches it, not the {model.name}'s")
        wall = parse_wall(args.wall)
        check_wall_numbers(stiffness=args.wall_stiffness, damping=args.wall_damping,
                           friction=args.wall_friction,
                           names=("--wall-stiffness", "--wall-damping", "--wall-friction"))
        size = None if args.wall_size is None else box_size_cm(
            args.wall_size, option="--wall-size", example="60,40,3")
        _arm_plant(network).set_wall(np.array(wall[0]), np.array(wall[1]),
                                     stiffness=args.wall_stiffness, damping=args.wall_damping,
                                     friction=args.wall_friction, size=size)
    if args.fault and not jmap.family.fault_flags:
        raise ValueError(f"--fault: the flags are an X-series servo's Hardware Error Status "
                         f"or a Feetech STS's status error bits; the {jmap.servo} has none "
                         "(emulate --servo XM430-W350)")
    alerts = [parse_fault(f, model.joint_names, protocol=jmap.protocol) for f in args.fault]
    for joint, flag, after in alerts:
        servo = _arm_plant(network).servos[joint]
        servo.inject_error(flag, after=after)
    _raise_priority(args.nice)
    faults = Faults(drop=args.drop, corrupt=args.corrupt, delay=args.delay,
                    delay_time=args.delay_time, seed=args.seed)
    stop = {"now": False}

    def on_signal(signum: int, frame: object) -> None:
        stop["now"] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    control = None
    if args.control:
        if not hasattr(network.physics, "hold") or not isinstance(model, SerialChain):
            raise ValueError(f"--control: a serial arm's servos (X-series or Feetech STS), "
                             f"not the {jmap.servo} of {model.name}")
        control = (open_control(args.control), control_handler(network, model, jmap.gripper))
    log = open(args.log, "w") if args.log else None
    emu = PtyEmulator(network, pace=args.pace, faults=faults, echo=args.echo, log=log,
                      control=control)
    try:
        if args.link:
            make_link(args.link, emu.path)
        print(f"port: {emu.path}", flush=True)
        s = network.servos
        flag_names = {v: k for k, v in jmap.family.fault_flags.items()}
        gripper = f" and the gripper's {jmap.gripper.servo_id}" if jmap.gripper else ""
        print(f"emulating {len(s)} {s[0].table.name} servos (IDs "
              f"{', '.join(str(i) for i in jmap.ids)}{gripper}, protocol "
              f"{jmap.family.label}) of {model.name} at {args.baud:.0f} bps"
              f"{', paced' if args.pace else ''}"
              + "".join(f"; {nm:g} N·m on {model.joint_names[j]} from {t0:g} s"
                        for j, nm, t0 in disturbances)
              + "".join(f"; {flag_names[flag]} on {model.joint_names[j]} after {t:g} s "
                        "of torque on" for j, flag, t in alerts)
              + (f"; resting at {args.pose} until torque on" if args.pose else "")
              + (f"; a {'box ' + args.wall_size + ' cm' if args.wall_size else 'wall'} "
                 f"through {args.wall} cm, {args.wall_stiffness:g} N/m"
                 if wall is not None else "")
              + "; Ctrl-C to stop", file=sys.stderr, flush=True)
        emu.serve(lambda: stop["now"])
    except ArithmeticError as exc:  # the simulated plant diverged: say so in one line
        print(f"armlab emulate: the simulated plant failed ({exc}); restart the emulator",
              file=sys.stderr)
        return 2
    finally:
        if args.link:
            remove_link(args.link, emu.path)
        emu.close()
        if log is not None:
            log.close()
        if control is not None:
            os.close(control[0])
    st = emu.stats
    print(f"emulator stopped: {st.packets} packets, {st.replies} replies "
          f"({st.dropped} dropped, {st.corrupted} corrupted, {st.delayed} delayed); "
          f"{st.wrong_baud} packets at another baud than the servos'; "
          f"{st.lost_bytes} reply bytes lost (nobody read the line); "
          f"plant clock slipped {st.slipped:.3f} s",
          file=sys.stderr)
    return 0
