"""``armlab experiment NAME``: run a headless experiment, print its figures and, with
``--save-run PATH``, save its run file (docs/runs.md)."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import sys
import types
import typing
from collections.abc import Callable
from typing import Any

from armlab.control.experiments import BackendOptions, Experiment, all_experiments
from armlab.control.runs import SUFFIX, Run, writable_path, write_run

NAME = "experiment"
HELP = "run a headless experiment (seed tables, thesis runs) and print its figures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="experiment", metavar="NAME", required=True)
    for exp in all_experiments().values():
        p = sub.add_parser(exp.name, help=exp.help, description=exp.help)
        p.add_argument("--json", action="store_true", help="print the result as JSON")
        p.add_argument("--csv", metavar="FILE", help="also write the result rows to FILE")
        p.add_argument("--save-run", metavar="PATH", dest="save_run",
                       help=f"also save the run file (its recorded series, figures and "
                            f"rows; a zip of run.json and signals.csv, e.g. run{SUFFIX}) "
                            "to PATH")
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
    from armlab.app.arm.backends import make_backend

    def factory(model: Any, **kw: Any) -> Any:
        if options.backend != "sim":
            return make_backend(options.backend, model, port=options.port, baud=options.baud)
        if options.port is not None or options.baud is not None:
            raise ValueError("--port and --baud are for --backend serial")
        return make_backend("sim", model, **kw)

    return factory


def _hand_plant(options: Any) -> Any:
    """``armlab.hardware.sim.hand_plant.make_hand``: the simulated three-finger hand."""
    from armlab.hardware.sim.hand_plant import make_hand

    return make_hand


#: What an experiment can ask for in ``Experiment.needs``: name -> maker(options).
FACTORIES: dict[str, Callable[[Any], Any]] = {
    "backend_factory": _backend_factory,
    "hand_plant": _hand_plant,
}


def _json_safe(value: Any) -> Any:
    """``value`` as strict JSON holds it: NaN and infinities become None, tuples lists."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


#: A list longer than this in a result is a series, not a figure.
_MAX_FIGURE_LIST = 64


def result_figures(result: dict[str, Any], joint_names: tuple[str, ...]
                   ) -> dict[str, float | None]:
    """The numbers of an experiment's result as a run file's figures: a number under its
    key, a list of numbers per joint as "key.<joint>" (other lists "key.<i>"), a dict of
    numbers as "key.<name>" (two levels deep); NaN/inf and None as None; text, booleans,
    series and tables left to ``extra``."""
    out: dict[str, float | None] = {}

    def add(key: str, v: Any, depth: int) -> None:
        if isinstance(v, bool | str):
            return
        if v is None or isinstance(v, int | float):
            out[key] = None if v is None or not math.isfinite(v) else float(v)
        elif isinstance(v, list | tuple) and depth < 2 and len(v) <= _MAX_FIGURE_LIST and all(
                x is None or (isinstance(x, int | float) and not isinstance(x, bool))
                for x in v):
            names = joint_names if len(v) == len(joint_names) else range(len(v))
            for name, x in zip(names, v, strict=True):
                add(f"{key}.{name}", x, depth + 1)
        elif isinstance(v, dict) and depth < 2:
            for k, x in v.items():
                add(f"{key}.{k}", x, depth + 1)

    for key, value in result.items():
        add(key, value, 0)
    return out


def experiment_run(exp: Experiment, options: Any, result: dict[str, Any],
                   rows: list[dict[str, Any]], kept: list[Run]) -> Run:
    """The run file of one experiment: the last run it recorded, with the result's numbers
    as figures and, in ``extra``, the options, the table rows and the whole result (what
    ``--json`` prints, NaN/inf as null)."""
    if not kept:
        raise ValueError(f"experiment {exp.name} recorded no run to save")
    base = kept[-1]
    return dataclasses.replace(
        base, source=f"experiment:{exp.name}",
        figures={**result_figures(result, base.joint_names), **base.figures},
        extra={**base.extra, "options": _json_safe(dataclasses.asdict(options)),
               "rows": _json_safe(rows), "result": _json_safe(result),
               "runs_recorded": len(kept)})


def run(args: argparse.Namespace) -> int:
    exp = args._experiment
    options = options_of(exp, args)
    if args.save_run:
        writable_path(args.save_run)  # refused before a long run, not after it
    needs = {}
    for name in exp.needs:
        if name not in FACTORIES:
            raise ValueError(f"experiment {exp.name} needs {name!r}, which the CLI cannot give")
        needs[name] = FACTORIES[name](options)
    kept: list[Run] = []
    result = exp.run(options, keep=kept.append, **needs)
    rows = exp.rows(result) if exp.rows else [
        {k: v for k, v in result.items() if not isinstance(v, list | dict)}
    ]
    if args.save_run:
        path = write_run(experiment_run(exp, options, result, rows, kept), args.save_run)
        print(f"saved the run to {path}", file=sys.stderr)
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
