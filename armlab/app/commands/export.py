"""``armlab export RUN --html OUT.html``: one run file as one self-contained page to hand in."""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "export"
HELP = ("write a run file (Save run, --save-run) as one HTML page that opens offline: the "
        "arm in 3D, the charts, the gains and the figures")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_file", metavar="RUN", type=Path,
                        help="the run file (*.armlab-run.zip)")
    parser.add_argument("--html", metavar="OUT", type=Path, required=True,
                        help="the page to write (e.g. run.html); replaced if it exists")
    parser.add_argument("--robot", metavar="NAME_OR_URDF",
                        help="the robot to draw (default: the one the run names; needed "
                        "for a run of a URDF of one's own)")


def run(args: argparse.Namespace) -> int:
    """Exit 0: the page was written; 2 (through ``armlab.app.commands.cli``): the run file was
    refused (read_run's message, or a value no page can draw), the robot is unknown or
    the page cannot be written."""
    from armlab.app.export.html import write_html
    from armlab.control.runs import check_drawable, read_run
    from armlab.kinematics import load_robot

    run_ = read_run(args.run_file)
    check_drawable(run_, str(args.run_file))  # named by its file, before any page work
    model = load_robot(args.robot) if args.robot else None
    out = write_html(run_, args.html, model=model)
    print(f"wrote {out} ({out.stat().st_size / 1024:.0f} kB): open it in any browser")
    return 0
