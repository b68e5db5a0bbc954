"""``armlab bench``: median timings of the hot paths (see ``app.benches``)."""

from __future__ import annotations

import argparse
import json
import platform
import sys

from app.benches import run_all

NAME = "bench"
HELP = "measure the hot paths (FK, IK, dynamics, bus, UI) and print median figures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one flat JSON object")
    parser.add_argument("--quick", action="store_true", help="fewer repeats (rougher figures)")
    parser.add_argument("--only", metavar="GROUP", help="run one group (a module of app.benches)")


def run(args: argparse.Namespace) -> int:
    figures = run_all(quick=args.quick, only=args.only)
    if args.json:
        json.dump(figures, sys.stdout)
        sys.stdout.write("\n")
        return 0
    print(f"armlab bench on {platform.node()} ({platform.processor() or platform.machine()}); "
          "a shared machine: figures are medians and vary run to run")
    for k, v in figures.items():
        print(f"  {k:32s} {v:12.3f}")
    return 0
