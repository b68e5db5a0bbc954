"""``armlab check FILE [--results PATH]``: run a student's exercise against its cases."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

NAME = "check"
HELP = ("check a student's exercise file (.py or .ipynb): one line per case; exit 0 only "
        "when every case passes")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", help="the student's file (from `armlab "
                        "exercise start`)")
    parser.add_argument("--exercise", metavar="NAME",
                        help="the exercise (default: the file's EXERCISE line, or its name)")
    parser.add_argument("--results", metavar="PATH", type=Path,
                        help="also write Gradescope's autograder results.json here "
                        "(one test per case, the total score)")


def run(args: argparse.Namespace) -> int:
    """Exit 0: every case passed; 1: a case failed or the file could not be run."""
    from armlab.exercises import check_file

    if not Path(args.file).is_file():
        raise ValueError(f"no such file: {args.file}")
    report = check_file(args.file, exercise=args.exercise,
                        echo=lambda text: print(text, flush=True))
    if report.error is not None:
        print(f"FAIL  {report.error}", flush=True)
    print(report.summary(), flush=True)
    if args.results is not None:
        args.results.parent.mkdir(parents=True, exist_ok=True)
        args.results.write_text(json.dumps(report.gradescope(), indent=2) + "\n",
                                encoding="utf-8")
    sys.stdout.flush()
    return 0 if report.passed else 1
