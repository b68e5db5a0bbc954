"""The ``armlab`` command line (also ``python -m armlab.app``).

Subcommands live in ``armlab/app/commands/``, listed in ``commands.COMMANDS``: each module
defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from armlab.app import commands
from armlab.control.backend import BackendError


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The top-level parser with one subparser per module of ``armlab.app.commands.COMMANDS``.

    Only the subcommand named in ``argv`` gets its options built (some of them
    import the experiments, scipy or viser), so ``armlab emulate`` starts fast;
    without one, every subcommand is built for ``--help``.
    """
    parser = argparse.ArgumentParser(
        prog="armlab",
        description="A browser lab for teaching robot-arm kinematics and compliance control.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    names = commands.COMMANDS
    chosen = next((a for a in (argv or []) if not a.startswith("-")), None)
    if chosen not in names:
        chosen = None
    for name in names:
        module = importlib.import_module(f"{commands.__name__}.{name}")
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        if chosen is None or module.NAME == chosen:
            module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the chosen subcommand; returns the exit status."""
    if argv is None:
        argv = sys.argv[1:]
    args = build_parser(argv).parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (ValueError, OSError, BackendError) as exc:  # a user's mistake: one clear line
        print(f"armlab {args.command}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
