"""Headless experiments run by ``armlab experiment NAME``.

Each module in this package defines ``EXPERIMENTS``: a tuple of
:class:`Experiment`. The CLI discovers them, so adding an experiment means
adding a module here and nothing else.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Experiment:
    """One headless experiment.

    Attributes:
        name: the CLI name, e.g. "seed004-table".
        help: one line for ``--help``.
        add_arguments: adds the experiment's own options to its argparse parser.
        run: runs it from the parsed options; returns a JSON-serialisable dict
            (what ``--json`` prints).
        rows: turns that dict into flat table rows for ``--csv`` and the
            human-readable table (None: print the dict's top-level items).
        needs: names of plant factories the CLI sets on the parsed options
            before ``run`` (control/ never imports hardware/), e.g.
            "hand_plant" = ``hardware.hand.make_hand``.
    """

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], dict[str, Any]]
    rows: Callable[[dict[str, Any]], list[dict[str, Any]]] | None = None
    needs: tuple[str, ...] = ()


def all_experiments() -> dict[str, Experiment]:
    """Every experiment defined in this package, by name."""
    found: dict[str, Experiment] = {}
    for info in pkgutil.iter_modules(__path__):
        module = importlib.import_module(f"{__name__}.{info.name}")
        for exp in getattr(module, "EXPERIMENTS", ()):
            found[exp.name] = exp
    return dict(sorted(found.items()))
