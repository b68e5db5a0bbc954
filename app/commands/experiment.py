"""``armlab experiment NAME``: run a headless experiment and print its figures."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import sys
import types
import typing
from collections.abc import Callable
from typing import Any

from armlab.control.experiments import BackendOptions, Experiment, all_experiments

NAME = "experiment"
HELP = "run a headless experiment (seed tables, thesis runs) and print its figures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="experiment", metavar="NAME", required=True)
    for exp in all_experiments().values():
        p = sub.add_parser(exp.name, help=exp.help, description=exp.help)
        p.add_argument("--json", action="store_true", help="print the result as JSON")
        p.add_argument("--csv", metavar="FILE", help="also write the result rows to FILE")
        add_options(p, exp.options)
        p.set_defaults(_experiment=exp)


def add_options(parser: argparse.ArgumentParser, options: type) -> None:
    """One option ``--field-name`` per field of an experiment's options dataclass
    (``armlab.control.experiments.option``): its type, default, choices and help."""
    hints = typing.get_type_hints(options)
    for f in dataclasses.fields(options):
        kind, choices = _value_type(hints[f.name])
        meta = f.metadata
        kw: dict[str, Any] = {"dest": f.name, "default": f.default,
                              "help": argparse.SUPPRESS if meta.get("hidden") else meta["help"]}
        if kind is not str:
            kw["type"] = kind
        if meta.get("choices") or choices:
            kw["choices"] = list(meta.get("choices") or choices)
        if meta.get("metavar"):
            kw["metavar"] = meta["metavar"]
        parser.add_argument("--" + f.name.replace("_", "-"), **kw)


def _value_type(hint: Any) -> tuple[type, tuple[Any, ...]]:
    """(what argparse converts a value to, the allowed values of a ``Literal`` or ()) of
    a field's annotation; ``X | None`` is read as X (None is the default)."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        (hint,) = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) is typing.Literal:
        values = typing.get_args(hint)
        return type(values[0]), values
    return hint, ()


def options_of(exp: Experiment, args: argparse.Namespace) -> Any:
    """The experiment's typed options from the parsed command line."""
    return exp.options(**{f.name: getattr(args, f.name) for f in dataclasses.fields(exp.options)})


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


def _backend_factory(options: BackendOptions) -> Any:
    """``factory(model, **sim_options)`` opening the backend chosen by --backend/--port/--baud
    (options such as ``q0`` only reach the simulator)."""
    from armlab.app.backends import make_backend

    def factory(model: Any, **kw: Any) -> Any:
        if options.backend != "sim":
            return make_backend(options.backend, model, port=options.port, baud=options.baud)
        if options.port is not None or options.baud is not None:
            raise ValueError("--port and --baud are for --backend serial")
        return make_backend("sim", model, **kw)

    return factory


def _hand_plant(options: Any) -> Any:
    """``armlab.hardware.sim.hand.make_hand``: the simulated three-finger hand."""
    from armlab.hardware.sim.hand import make_hand

    return make_hand


#: What an experiment can ask for in ``Experiment.needs``: name -> maker(options).
FACTORIES: dict[str, Callable[[Any], Any]] = {
    "backend_factory": _backend_factory,
    "hand_plant": _hand_plant,
}


def run(args: argparse.Namespace) -> int:
    exp = args._experiment
    options = options_of(exp, args)
    needs = {}
    for name in exp.needs:
        if name not in FACTORIES:
            raise ValueError(f"experiment {exp.name} needs {name!r}, which the CLI cannot give")
        needs[name] = FACTORIES[name](options)
    result = exp.run(options, **needs)
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
