"""Headless experiments run by ``armlab experiment NAME``.

Each module named in :data:`MODULES` defines ``EXPERIMENTS``: a tuple of
:class:`Experiment`. An experiment's options are a frozen dataclass (one field
per option, declared with :func:`option`); the command line
(``armlab/app/commands/experiment.py``) turns its fields into command-line options and
calls ``run(options, keep=..., **needs)``. No argparse here: the experiments are plain
functions of typed options, callable from a test or a script.

Every experiment hands each run it records to ``keep`` (a
:class:`armlab.control.runs.Run`: its time series at the rate it was sampled), and
``armlab experiment NAME --save-run PATH`` saves the last one with the experiment's
figures (docs/runs.md says which series each experiment keeps).
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from armlab.control.runs import Run

if TYPE_CHECKING:
    from armlab.control.loop import ControlLoop

#: What an experiment's ``run`` is given as ``keep``: it calls it with every run it records
#: (None: nobody keeps them).
Keep = Callable[[Run], None]

#: The modules of this package that define experiments (adding one: add its name here).
MODULES: tuple[str, ...] = ("contact", "contact_sweep", "hand_grip", "observers", "seed002",
                            "seed003", "seed004", "thesis", "thesis_readings")


def option(default: Any, help: str, *, choices: Sequence[Any] | None = None,
           metavar: str | None = None, hidden: bool = False) -> Any:
    """A field of an experiment's options dataclass, with what ``--help`` says of it.

    Args:
        default: the value when the option is not given.
        help: one line for ``--help``.
        choices: the allowed values (a ``Literal`` type gives them too).
        metavar: the value's name in ``--help``.
        hidden: left out of ``--help`` (still accepted).
    """
    return field(default=default, metadata={"help": help, "choices": choices,
                                            "metavar": metavar, "hidden": hidden})


@dataclass(frozen=True)
class BackendOptions:
    """Options of an experiment that runs on a backend the command line opens for it
    (``needs=("backend_factory",)``; armlab/control/ never imports armlab/hardware/)."""

    backend: Literal["sim", "serial"] = option(
        "sim", "simulated arm (default) or Dynamixel servos on --port")
    port: str | None = option(None, "serial port for --backend serial, e.g. /dev/ttyUSB0")
    baud: int | None = option(None, "bit rate for --backend serial")


@dataclass(frozen=True)
class Experiment:
    """One headless experiment.

    Attributes:
        name: the CLI name, e.g. "seed004-table".
        help: one line for ``--help``.
        options: the frozen dataclass of its options (fields made with :func:`option`).
        run: ``run(options, *, keep=None, **needs)`` runs it, handing each run it
            records to ``keep`` (:data:`Keep`); returns a JSON-serialisable dict (what
            ``--json`` prints).
        rows: turns that dict into flat table rows for ``--csv`` and the
            human-readable table (None: print the dict's top-level items).
        needs: names of factories the caller passes to ``run`` as keyword arguments
            (armlab/control/ never imports armlab/hardware/), e.g. "hand_plant" =
            ``armlab.hardware.sim.hand_plant.make_hand``, "backend_factory" (with
            :class:`BackendOptions`).
    """

    name: str
    help: str
    options: type
    run: Callable[..., dict[str, Any]]
    rows: Callable[[dict[str, Any]], list[dict[str, Any]]] | None = None
    needs: tuple[str, ...] = ()


def advance(loop: ControlLoop, until: float) -> None:
    """Run ``loop`` until its time reaches ``until`` s: stepped headless, or waited for
    when its thread paces it (real servos live in real time)."""
    if loop.status.running:
        while loop.status.t + 1e-9 < until and loop.status.fault is None:
            time.sleep(0.005)
    else:
        loop.run_for(until - loop.status.t)


def all_experiments() -> dict[str, Experiment]:
    """Every experiment of the modules in :data:`MODULES`, by name."""
    found: dict[str, Experiment] = {}
    for name in MODULES:
        module = importlib.import_module(f"{__name__}.{name}")
        for exp in module.EXPERIMENTS:
            found[exp.name] = exp
    return dict(sorted(found.items()))
