"""``armlab exercise list|start``: the coursework's exercises and their starters."""

from __future__ import annotations

import argparse

NAME = "exercise"
HELP = "coursework: list the exercises, or write one's starter (.py or notebook) to fill in"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    sub.add_parser("list", help="one line per exercise: its name, then its title (seed, "
                   "equation)", description="one line per exercise: its name, then its title")
    start = sub.add_parser("start", help="write an exercise's starter and print its path",
                           description="write DIR/NAME.py (or DIR/NAME.ipynb with --notebook): "
                           "the function to fill in, raising NotImplementedError until it is")
    start.add_argument("name", metavar="NAME", help="the exercise (see `armlab exercise list`)")
    start.add_argument("--dir", default=".", metavar="DIR",
                       help="folder to write into (default: the current one)")
    start.add_argument("--notebook", action="store_true",
                       help="write a Jupyter notebook: the function's cell and a cell that "
                       "checks it")
    start.add_argument("--force", action="store_true",
                       help="overwrite an existing file (a student's work is kept otherwise)")


def run(args: argparse.Namespace) -> int:
    from armlab.exercises import EXERCISES, write_starter

    if args.action == "list":
        width = max(len(ex.name) for ex in EXERCISES)
        for ex in EXERCISES:
            print(f"{ex.name:<{width}}  {ex.title}")
        return 0
    try:
        path = write_starter(args.name, args.dir, notebook=args.notebook, force=args.force)
    except FileExistsError as exc:
        raise ValueError(str(exc)) from None
    print(path)
    return 0
