"""``armlab scan --port P``: list the servos (Dynamixel, Feetech STS) on a serial port."""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, replace
from typing import Any

from armlab.hardware.servos.registry import FAMILIES, family
from armlab.hardware.wire.errors import BusError
from armlab.hardware.wire.scan import (
    COMMON_BAUDS,
    DEFAULT_BAUDS,
    all_ids,
    scan,
    scan_time_bound,
)

NAME = "scan"
HELP = ("ping servo IDs 0..253 at each baud (Dynamixel protocol 1.0 and 2.0, Feetech STS) "
        "and list ID, model, protocol, firmware, baud, angle limits")


def _ids(text: str) -> list[int]:
    """"1,3,5" or "0-20" or a mix -> IDs."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi or lo)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"not an ID list: {text!r} (e.g. 1,3,5 or 0-20)") from None
        if not 0 <= a <= b <= 253:
            raise argparse.ArgumentTypeError(f"IDs must lie in 0..253: {part!r}")
        out.extend(range(a, b + 1))
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True, help="serial device, e.g. /dev/ttyUSB0")
    parser.add_argument("--baud", type=float, action="append", metavar="B",
                        help="bit/s to try (repeatable; default "
                        f"{', '.join(map(str, DEFAULT_BAUDS))})")
    parser.add_argument("--all-bauds", action="store_true",
                        help=f"try every usual rate ({', '.join(map(str, COMMON_BAUDS))})")
    parser.add_argument("--ids", type=_ids, default=list(all_ids()),
                        help="IDs to ping, e.g. 1,3,5 or 0-20 (default 0-253)")
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="s to wait beyond wire time for each ping (default 0.010; on a "
                        "pseudo-terminal, the emulator, 0.005; a late answer is asked "
                        "again)")
    parser.add_argument("--json", action="store_true", help="print the servos as JSON")
    parser.add_argument("--write-map", metavar="MAP.toml",
                        help="draft a joint map from the servos that answered (IDs in chain "
                        "order, model, protocol, baud, their angle limits) and write it here")
    parser.add_argument("--robot", metavar="PATH.urdf",
                        help="with --write-map: the arm's URDF (robot name or file); the map "
                        "takes its joint names and must match its joint count")
    parser.add_argument("--tip-link", metavar="LINK", help="with --robot: the end-effector link")
    parser.add_argument("--calibration", metavar="FILE.json",
                        help="with --write-map and --robot: LeRobot's calibration file of the "
                        "arm (per motor id, drive_mode, homing_offset, range_min, range_max): "
                        "the map takes its directions, zeros and ranges")
    parser.add_argument("--calibrate", action="store_true",
                        help="with --write-map and --robot, without a LeRobot file: switch "
                        "the servos' torque off and guide each joint by hand to the middle "
                        "of its range and its two ends (press Enter at each), the gripper "
                        "closed and open; the map takes the zeros and ranges read")


def run(args: argparse.Namespace) -> int:
    model = None
    if args.calibration is not None and (args.robot is None or args.write_map is None):
        raise ValueError("--calibration needs --robot and --write-map (it becomes the map)")
    if args.calibrate and (args.robot is None or args.write_map is None):
        raise ValueError("--calibrate needs --robot and --write-map (it becomes the map)")
    if args.calibrate and args.calibration is not None:
        raise ValueError("--calibrate or --calibration: the lab's own calibration, or "
                         "LeRobot's file, not both")
    if args.robot is not None:
        if args.write_map is None:
            raise ValueError("--robot is for --write-map (it names the map's joints)")
        from armlab.kinematics.catalog import load_robot
        from armlab.kinematics.model import SerialChain

        model = load_robot(args.robot, tip_link=args.tip_link)
        if not isinstance(model, SerialChain):
            raise ValueError(f"--robot: {args.robot} is not a serial arm")
    bauds = list(COMMON_BAUDS) if args.all_bauds else (args.baud or list(DEFAULT_BAUDS))
    for b in bauds:
        if not b > 0:
            raise ValueError(f"--baud must be > 0, got {b:g}")
    if args.timeout is not None and not args.timeout > 0:
        raise ValueError(f"--timeout must be > 0 s, got {args.timeout}")
    bound = scan_time_bound(args.port, bauds, args.ids, args.timeout)
    tty = sys.stderr.isatty()
    print(f"scanning {args.port}: {len(args.ids)} IDs at {len(bauds)} baud rate(s), "
          f"at most {bound:.1f} s", file=sys.stderr)
    state: dict[str, Any] = {"baud": None, "t": 0.0}

    def progress(baud: float, servo_id: int, n_found: int) -> None:
        now = time.monotonic()
        if tty and now - state["t"] > 0.1:
            state["t"] = now
            print(f"\r  {baud:>9.0f} bps  ID {servo_id:3d}  found {n_found}", end="",
                  file=sys.stderr, flush=True)
        elif not tty and baud != state["baud"]:
            print(f"  {baud:.0f} bps ...", file=sys.stderr, flush=True)
        state["baud"] = baud

    try:
        found = scan(args.port, bauds, ids=args.ids, margin=args.timeout, progress=progress)
    except BusError as exc:
        if tty:
            print(file=sys.stderr)
        print(f"armlab scan: {exc}", file=sys.stderr)
        return 2
    if tty:
        print("\r" + " " * 40 + "\r", end="", file=sys.stderr)
    if args.write_map is not None:
        from armlab.hardware.backends.joint_map import draft_joint_map

        if args.calibration is not None:
            text = _calibrated_map(args.calibration, model, found)
        elif args.calibrate:
            text = _guided_map(args.port, model, found)
        else:
            text = draft_joint_map(found, model)  # ValueError names the joint and the servo
        with open(args.write_map, "w") as out:
            out.write(text)
        print(f"wrote {args.write_map}: {len(found)} servo(s); check signs and offsets "
              "with the arm held safe before serving", file=sys.stderr)
    if args.json:
        json.dump([asdict(f) for f in found], sys.stdout)
        sys.stdout.write("\n")
        return 0
    if not found:
        print(f"no servo answered on {args.port}: check power, cabling and the baud "
              "(try --all-bauds); the lab speaks "
              + ", ".join(f.title for f in FAMILIES))
        return 1
    print(f"{'ID':>3}  {'model':10} {'protocol':>11} {'fw':>3} {'baud':>9}  "
          f"{'angle limits (deg from centre)':>30}")
    for f in found:
        limits = ("wheel mode" if f.cw_limit == f.ccw_limit == 0 else
                  f"{f.cw_limit_deg:+7.1f} .. {f.ccw_limit_deg:+7.1f} "
                  f"({f.cw_limit}..{f.ccw_limit})")
        label = family(f.protocol).label
        print(f"{f.servo_id:3d}  {f.model:10} {label:>11} {f.firmware:3d} {f.baud:9.0f}  "
              f"{limits:>30}")
    return 0


def _calibrated_map(path: str, model: object, found: list) -> str:
    """TOML of the joint map LeRobot's calibration file gives, once every servo it names
    answered the scan as that model; ValueError naming the servo that did not."""
    from armlab.hardware.backends.lerobot_calibration import (
        joint_map_from_lerobot,
        joint_map_toml,
    )

    jmap = joint_map_from_lerobot(path, model)  # type: ignore[arg-type]  # an arm: the LeRobot calibration is a serial arm's
    by_id = {f.servo_id: f for f in found}
    named = [(j.name, j.servo_id) for j in jmap.joints]
    if jmap.gripper is not None:
        named.append((jmap.gripper.joint, jmap.gripper.servo_id))
    for name, servo_id in named:
        f = by_id.get(servo_id)
        if f is None or f.model != jmap.servo:
            what = "did not answer" if f is None else f"answered as a {f.model}"
            raise ValueError(f"joint {name!r}: servo ID {servo_id} of {path} {what}; "
                             f"expected a {jmap.servo}")
    return joint_map_toml(jmap, baud=min(by_id[j.servo_id].baud for j in jmap.joints),
                          source=path)


def _guided_map(port: str, model: object, found: list) -> str:
    """TOML of the joint map the guided calibration reads from the servos that answered
    (:mod:`armlab.hardware.backends.guided_calibration`): each instruction on stdout, the
    person's Enter on stdin; ValueError when stdin ends first, or as the calibration
    refuses a range (naming the joint)."""
    from armlab.hardware.backends.guided_calibration import calibrate
    from armlab.hardware.backends.joint_map import default_joint_map, draft_joint_map
    from armlab.hardware.backends.lerobot_calibration import joint_map_toml
    from armlab.hardware.wire.bus import Bus

    draft_joint_map(found, model)  # type: ignore[arg-type]  # ValueError: a joint without a servo
    servos = sorted(found, key=lambda f: f.servo_id)
    n = model.n  # type: ignore[attr-defined]  # an arm: scan drafts a serial arm's map
    jmap = default_joint_map(model, servo=servos[0].model,  # type: ignore[arg-type]  # an arm: scan drafts a serial arm's map
                             ids=tuple(f.servo_id for f in servos[:n]))
    # the gripper's servo is the one past the joints' (the draft's rule), or none answered
    grip = None if jmap.gripper is None or len(servos) == n else \
        replace(jmap.gripper, servo_id=servos[n].servo_id)
    jmap = replace(jmap, gripper=grip)
    baud = min(f.baud for f in servos)

    def ask(text: str) -> None:
        print(text, flush=True)
        if not sys.stdin.readline():
            raise ValueError("calibration stopped: stdin ended before the arm was placed")

    def say(text: str) -> None:
        print(f"  {text}", file=sys.stderr, flush=True)

    with Bus(port, baud, protocol=jmap.family) as bus:
        calibrated = calibrate(bus, model, ask=ask, say=say, jmap=jmap)  # type: ignore[arg-type]  # an arm: scan calibrates a serial arm
    return joint_map_toml(calibrated, baud=baud, source="armlab scan --calibrate")
