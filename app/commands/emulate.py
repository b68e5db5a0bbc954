"""``armlab emulate --robot NAME``: simulated Dynamixel servos behind a pseudo-terminal.

The first line printed is ``port: /dev/pts/N`` (flushed): point ``armlab scan``,
``armlab serve --backend serial`` or any protocol-1.0 client at it. Serves until
SIGINT or SIGTERM, then exits cleanly.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys

from app.commands.scan import _ids
from hardware.emulator import Faults, PtyEmulator, drop_link, emulated_network, point_link
from hardware.servo_spec import value_from_baud
from kinematics.model import load_robot

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
                        "(default 1,3,5 for receptionist_arm, else 1..n)")
    parser.add_argument("--servo", choices=("RX-24F", "AX-12A"),
                        help="servo model (default RX-24F for the thesis arm, else AX-12A)")
    parser.add_argument("--pace", action="store_true",
                        help="hold replies for their wire time at the set baud")
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
    parser.add_argument("--link", metavar="PATH",
                        help="also make PATH a symlink to the pseudo-terminal, replaced on "
                        "restart (a stable name, like a /dev/serial/by-id path)")
    parser.add_argument("--log", metavar="FILE",
                        help="write one line per received (rx) and sent (tx) packet")


def run(args: argparse.Namespace) -> int:
    value_from_baud(args.baud)  # ValueError for a rate no servo can take
    if not -20 <= args.nice <= 19:
        raise ValueError(f"--nice must be in -20..19, got {args.nice}")
    _raise_priority(args.nice)
    model = load_robot(args.robot, preset=args.preset)
    network = emulated_network(model, ids=args.ids, servo=args.servo, baud=args.baud)
    faults = Faults(drop=args.drop, corrupt=args.corrupt, delay=args.delay,
                    delay_time=args.delay_time, seed=args.seed)
    stop = {"now": False}

    def on_signal(signum: int, frame: object) -> None:
        stop["now"] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    log = open(args.log, "w") if args.log else None
    emu = PtyEmulator(network, pace=args.pace, faults=faults, echo=args.echo, log=log)
    try:
        if args.link:
            point_link(args.link, emu.path)
        print(f"port: {emu.path}", flush=True)
        s = network.servos
        print(f"emulating {len(s)} {s[0].table.name} servos (IDs "
              f"{', '.join(str(x.servo_id) for x in s)}) of {model.name} at {args.baud:.0f} bps"
              f"{', paced' if args.pace else ''}; Ctrl-C to stop", file=sys.stderr, flush=True)
        emu.serve(lambda: stop["now"])
    except ArithmeticError as exc:  # the simulated plant diverged: say so in one line
        print(f"armlab emulate: the simulated plant failed ({exc}); restart the emulator",
              file=sys.stderr)
        return 2
    finally:
        if args.link:
            drop_link(args.link, emu.path)
        emu.close()
        if log is not None:
            log.close()
    st = emu.stats
    print(f"emulator stopped: {st.packets} packets, {st.replies} replies "
          f"({st.dropped} dropped, {st.corrupted} corrupted, {st.delayed} delayed); "
          f"plant clock slipped {st.slipped:.3f} s",
          file=sys.stderr)
    return 0
