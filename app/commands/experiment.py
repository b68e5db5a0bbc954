"""``armlab experiment NAME``: run a headless experiment and print its figures."""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections.abc import Callable
from typing import Any

from control.experiments import all_experiments

NAME = "experiment"
HELP = "run a headless experiment (seed tables, thesis runs) and print its figures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="experiment", metavar="NAME", required=True)
    for exp in all_experiments().values():
        p = sub.add_parser(exp.name, help=exp.help, description=exp.help)
        p.add_argument("--json", action="store_true", help="print the result as JSON")
        p.add_argument("--csv", metavar="FILE", help="also write the result rows to FILE")
        exp.add_arguments(p)
        if "backend_factory" in exp.needs:
            p.add_argument("--backend", choices=("sim", "serial"), default="sim",
                           help="simulated arm (default) or Dynamixel servos on --port")
            p.add_argument("--port", help="serial port for --backend serial, e.g. /dev/ttyUSB0")
            p.add_argument("--baud", type=int, help="bit rate for --backend serial")
        p.set_defaults(_experiment=exp)


def _print_table(rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    keys = list(rows[0])
    cells = [[_fmt(r.get(k)) for k in keys] for r in rows]
    widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
    print("  ".join(k.rjust(w) for k, w in zip(keys, widths, strict=True)))
    for c in cells:
        print("  ".join(v.rjust(w) for v, w in zip(c, widths, strict=True)))


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def _backend_factory(args: argparse.Namespace) -> Any:
    """``factory(model, **sim_options)`` opening the backend chosen by --backend/--port/--baud
    (options such as ``q0`` only reach the simulator)."""
    from app.backends import make_backend

    def factory(model: Any, **kw: Any) -> Any:
        if args.backend != "sim":
            return make_backend(args.backend, model, port=args.port, baud=args.baud)
        if args.port is not None or args.baud is not None:
            raise ValueError("--port and --baud are for --backend serial")
        return make_backend("sim", model, **kw)

    return factory


def _hand_plant(args: argparse.Namespace) -> Any:
    """``hardware.hand.make_hand``: the simulated three-finger hand."""
    from hardware.hand import make_hand

    return make_hand


#: What an experiment can ask for in ``Experiment.needs``: name -> maker(parsed options).
FACTORIES: dict[str, Callable[[argparse.Namespace], Any]] = {
    "backend_factory": _backend_factory,
    "hand_plant": _hand_plant,
}


def run(args: argparse.Namespace) -> int:
    exp = args._experiment
    for name in exp.needs:
        if name not in FACTORIES:
            raise ValueError(f"experiment {exp.name} needs {name!r}, which the CLI cannot give")
        setattr(args, name, FACTORIES[name](args))
    result = exp.run(args)
    rows = exp.rows(result) if exp.rows else [
        {k: v for k, v in result.items() if not isinstance(v, list | dict)}
    ]
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else [])
            writer.writeheader()
            for r in rows:
                writer.writerow({k: _fmt(v) for k, v in r.items()})
    if args.json:
        json.dump(result, sys.stdout)
        sys.stdout.write("\n")
    else:
        _print_table(rows)
        for k, v in result.items():
            # With its own rows, an experiment's other keys are its summary.
            if isinstance(v, dict) or (k == "rows" and exp.rows):
                continue
            if exp.rows or isinstance(v, list | tuple):
                print(f"{k}: {_fmt(v)}")
    return 0
