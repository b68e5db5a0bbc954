"""``armlab scan --port P``: list the servos (Dynamixel, Feetech STS) on a serial port."""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict

from armlab.hardware.families import FAMILIES, family
from armlab.hardware.wire.bus import BusError
from armlab.hardware.wire.scan import (
    ALL_IDS,
    COMMON_BAUDS,
    DEFAULT_BAUDS,
    ping_policy,
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
    parser.add_argument("--ids", type=_ids, default=list(ALL_IDS),
                        help="IDs to ping, e.g. 1,3,5 or 0-20 (default 0-253)")
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="s to wait beyond wire time for each reply (default 0.010; on a "
                        "pseudo-terminal, the emulator, 0.060 and a second ping)")
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


def run(args: argparse.Namespace) -> int:
    model = None
    if args.calibration is not None and (args.robot is None or args.write_map is None):
        raise ValueError("--calibration needs --robot and --write-map (it becomes the map)")
    if args.robot is not None:
        if args.write_map is None:
            raise ValueError("--robot is for --write-map (it names the map's joints)")
        from armlab.kinematics.model import SerialChain, load_robot

        model = load_robot(args.robot, tip_link=args.tip_link)
        if not isinstance(model, SerialChain):
            raise ValueError(f"--robot: {args.robot} is not a serial arm")
    bauds = list(COMMON_BAUDS) if args.all_bauds else (args.baud or list(DEFAULT_BAUDS))
    for b in bauds:
        if not b > 0:
            raise ValueError(f"--baud must be > 0, got {b:g}")
    if args.timeout is not None and not args.timeout > 0:
        raise ValueError(f"--timeout must be > 0 s, got {args.timeout}")
    bound = scan_time_bound(bauds, args.ids, *ping_policy(args.port, args.timeout))
    tty = sys.stderr.isatty()
    print(f"scanning {args.port}: {len(args.ids)} IDs at {len(bauds)} baud rate(s), "
          f"at most {bound:.1f} s", file=sys.stderr)
    state = {"baud": None, "t": 0.0}

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

    jmap = joint_map_from_lerobot(path, model)  # type: ignore[arg-type]
    by_id = {f.servo_id: f for f in found}
    for j in jmap.joints:
        f = by_id.get(j.servo_id)
        if f is None or f.model != jmap.servo:
            what = "did not answer" if f is None else f"answered as a {f.model}"
            raise ValueError(f"joint {j.name!r}: servo ID {j.servo_id} of {path} {what}; "
                             f"expected a {jmap.servo}")
    return joint_map_toml(jmap, baud=min(by_id[j.servo_id].baud for j in jmap.joints),
                          source=path)
