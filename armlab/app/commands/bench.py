"""``armlab bench``: median timings of the hot paths (see ``armlab.app.benches``)."""

from __future__ import annotations

import argparse
import json
import platform
import sys

from armlab.app.benches import run_all

NAME = "bench"
HELP = "measure the hot paths (FK, IK, dynamics, bus, UI) and print median figures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one flat JSON object")
    parser.add_argument("--quick", action="store_true", help="fewer repeats (rougher figures)")
    parser.add_argument("--only", metavar="GROUP",
                        help="run one group (a module of armlab.app.benches)")
    parser.add_argument("--peers", action="store_true",
                        help="also run MuJoCo and Pinocchio on the same URDF and print armlab's "
                             "figures beside theirs (needs the optional bench extra)")


def run(args: argparse.Namespace) -> int:
    if args.peers or args.only == "peers":
        from armlab.app.benches.peers import INSTALL, missing

        if missing():
            print(f"armlab bench --peers needs {', '.join(missing())}: {INSTALL}",
                  file=sys.stderr)
            return 2
    try:
        figures = run_all(quick=args.quick, only=args.only, peers=args.peers)
    except ValueError as exc:
        print(f"armlab bench: {exc}", file=sys.stderr)
        return 2
    if args.json:
        json.dump(figures, sys.stdout)
        sys.stdout.write("\n")
        return 0
    print(f"armlab bench on {platform.node()} ({platform.processor() or platform.machine()}); "
          "a shared machine: figures are medians and vary run to run")
    for k, v in figures.items():
        print(f"  {k:32s} {v:12.3f}")
    return 0
