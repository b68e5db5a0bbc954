"""``armlab serve``: the browser lab (``make run`` runs it with the defaults)."""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
from types import FrameType

NAME = "serve"
HELP = ("serve the browser lab: the arm in 3D, gain sliders, live plots "
        "(simulated arm by default; loopback only unless --host is given)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="receptionist_arm",
                        help="robot to load: a name (default receptionist_arm) or an arm's "
                        "URDF file (any serial chain of 1-7 revolute joints)")
    parser.add_argument("--tip-link", metavar="LINK",
                        help="with a URDF: the end-effector link (default: the leaf below the "
                        "most revolute joints)")
    parser.add_argument("--package-path", action="append", default=[], metavar="DIR",
                        help="with a URDF: a folder holding its package:// meshes (repeatable)")
    parser.add_argument("--joint-map", metavar="MAP.toml",
                        help="with --backend serial: which servo drives which joint "
                        "(armlab scan --write-map drafts one)")
    parser.add_argument("--backend", choices=("sim", "serial"), default="sim",
                        help="sim: simulated arm and servos (default); serial: Dynamixel bus")
    parser.add_argument("--port", metavar="DEV",
                        help="serial device for --backend serial, e.g. /dev/ttyUSB0")
    parser.add_argument("--baud", type=int, help="serial baud rate (default 1000000)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="interface to listen on (default 127.0.0.1: this computer only; "
                             "0.0.0.0 lets the whole network command the robot)")
    parser.add_argument("--http-port", type=int, default=8080,
                        help="first port to try (default 8080; the next free one if taken)")
    parser.add_argument("--lesson", help="lesson to open first (default: the robot's first)")
    parser.add_argument("--token", default=os.environ.get("ARMLAB_TOKEN") or None,
                        help="access token the page's URL carries (default: $ARMLAB_TOKEN, or "
                        "a new random one at each start)")
    parser.add_argument("--classroom", action="store_true",
                        help="roles for a class: only a page that types the passcode printed "
                        "after the url changes the shared arm; every page may press E-STOP")
    parser.add_argument("--exercise", metavar="FILE",
                        help="run your own law (an `armlab exercise start` file: pd_reference, "
                        "environment_impedance or compliance_law) in place of the lab's, in "
                        "the compliance and arm lessons, the lab's own as a ghost beside it; "
                        "saving the file reloads it (not with --classroom)")
    parser.add_argument("--i-am-next-to-the-robot", dest="next_to_robot", action="store_true",
                        help="with --exercise and --backend serial: your law drives the real "
                        "arm (every goal still within the lab's limits; an error in your law "
                        "turns the torque off)")
    parser.add_argument("--projector", action="store_true",
                        help="large text on every browser that has not chosen (each page has its "
                             "own Projector switch)")


def log_to_terminal() -> None:
    """The lab's own log lines (the servos' set-up, E-STOP, a lost link, an uncalibrated
    arm) on stderr, one line each from INFO up; the libraries' stay at their defaults."""
    logger = logging.getLogger("armlab")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)


def run(args: argparse.Namespace) -> int:
    from armlab.app.classroom.roles import loopback_warning
    from armlab.app.lab.server import Lab, ServeOptions
    from armlab.app.viser_ext import HooksMissing

    options = ServeOptions(robot=args.robot, backend=args.backend, port=args.port,
                           baud=args.baud, host=args.host, http_port=args.http_port,
                           lesson=args.lesson, token=args.token,
                           projector=args.projector, classroom=args.classroom,
                           tip_link=args.tip_link,
                           package_paths=tuple(args.package_path), joint_map=args.joint_map,
                           exercise=args.exercise, next_to_robot=args.next_to_robot)
    log_to_terminal()
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        try:
            lab = Lab(options)
        except HooksMissing as exc:  # the gate fails closed: one clear line
            print(f"armlab serve: {exc}", file=sys.stderr, flush=True)
            return 3
        try:
            lab.wait_until_loadable()
            alone = loopback_warning(options.host)
            if lab.roles is not None and alone is not None:
                print(f"warning: {alone}", file=sys.stderr, flush=True)
            if alone is None and lab.roles is None:
                print(f"warning: listening on {options.host} without --classroom: every "
                      "browser with the URL then controls the arm", file=sys.stderr, flush=True)
            print(f"url: {lab.url}", flush=True)
            if lab.roles is not None:
                print(f"passcode: {lab.roles.passcode}", flush=True)
                print(f"presenter: {lab.presenter_url}", flush=True)
            while not stop.wait(0.5):
                pass
            print("stopping: control loop shut down, torque off", flush=True)
        finally:
            lab.close()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return 0
