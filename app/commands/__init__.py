"""Subcommands of ``armlab``; one module each (see ``app.cli``)."""
