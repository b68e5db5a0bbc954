"""Subcommands of ``armlab``; one module each (see ``armlab.app.commands.cli``)."""

#: The subcommand modules of this package, in ``--help`` order (adding one: add its name).
COMMANDS: tuple[str, ...] = ("bench", "check", "emulate", "exercise", "experiment", "export",
                             "scan", "serve")
