"""``armlab check FILE [--results PATH]``: run a student's exercise against its cases."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
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


class Stopped(BaseException):  # noqa: N818 -- a signal, as KeyboardInterrupt is
    """SIGINT, SIGTERM or SIGHUP arrived during the check."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def run(args: argparse.Namespace) -> int:
    """Exit 0: every case passed; 1: a case failed or the file could not be run; 128 + N:
    signal N stopped the check.

    The student's file runs in a child process; this one alone prints, writes the
    results file and sets the exit status. With ``--results`` the file is written before
    the first case (every case failed, "not run yet") and again after each, so a check
    that is stopped part-way leaves the score its cases had earned; a check stopped by
    SIGINT, SIGTERM or SIGHUP (from a terminal, a timeout, or the student's code) kills
    the student's processes first, then writes it once more (whatever they wrote is
    replaced).
    """
    from armlab.exercises import Report, check_file

    if not Path(args.file).is_file():
        raise ValueError(f"no such file: {args.file}")
    last: list[Report] = []

    def write(report: Report) -> None:
        last[:] = [report]
        if args.results is not None:
            write_results(args.results, report.gradescope())

    def stop(signum: int, frame: object) -> None:
        for s in handled:  # the first one stops the check; more (a flood) are let be
            signal.signal(s, let_be)  # (not SIG_IGN: one already caught would then raise)
        raise Stopped(signum)

    def let_be(signum: int, frame: object) -> None:
        """A signal after the first: the check is stopping already."""

    handled = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    main = threading.current_thread() is threading.main_thread()
    previous = {s: signal.signal(s, stop) for s in handled} if main else {}
    try:
        report = check_file(args.file, exercise=args.exercise,
                            echo=lambda text: print(text, flush=True), progress=write)
    except (Stopped, KeyboardInterrupt) as exc:
        signum = exc.signum if isinstance(exc, Stopped) else signal.SIGINT
        if last:
            write(last[0])
            print(last[0].summary().replace(" cases pass", " cases pass before the check "
                                            "was stopped"), flush=True)
        print(f"the check was stopped by {signal.Signals(signum).name}", flush=True)
        return 128 + int(signum)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    if report.error is not None:
        print(f"FAIL  {report.error}", flush=True)
    print(report.summary(), flush=True)
    write(report)
    sys.stdout.flush()
    return 0 if report.passed else 1


def write_results(path: Path, results: dict[str, object]) -> None:
    """Write Gradescope's ``results.json`` whole or not at all (a temporary file, then
    renamed over ``path``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, path)
