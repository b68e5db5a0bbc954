"""Starters on disk: ``DIR/NAME.py``, or a Jupyter notebook ``DIR/NAME.ipynb`` whose cells
hold the same function and a cell that checks it (nbformat 4, written as plain JSON)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from armlab.exercises.catalog import get, starter_text


def notebook_json(name: str) -> dict[str, Any]:
    """The starter of exercise ``name`` as an nbformat 4 notebook: a title cell, the
    starter's code (the function to fill in), and ``armlab.check(function)``."""
    ex = get(name)
    code = starter_text(name)
    doc_end = code.index('"""', 3) + 3  # the module docstring becomes the title cell
    body = code[doc_end:].lstrip("\n")
    title = (f"# {ex.name}: {ex.title}\n\nFill in `{ex.function}` below, run its cell, then "
             f"run the check under it. Every case prints one line; a failed one shows its "
             f"input, what was expected, what came back and, for a common mistake, a hint.")

    def cell(kind: str, text: str) -> dict[str, object]:
        c: dict[str, object] = {"cell_type": kind, "metadata": {},
                                "source": text.splitlines(keepends=True)}
        if kind == "code":
            c.update(execution_count=None, outputs=[])
        return c

    return {
        "cells": [cell("markdown", title), cell("code", body),
                  cell("code", f"import armlab\n\narmlab.check({ex.function})")],
        "metadata": {
            "kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"},
            "language_info": {"name": "python"},
        },
        "nbformat": 4,
        "nbformat_minor": 5,
    }


def write_starter(name: str, directory: str | Path = ".", *, notebook: bool = False,
                  force: bool = False) -> Path:
    """Write exercise ``name``'s starter into ``directory`` (created if missing).

    Returns:
        the path written: ``directory/NAME.py`` or ``directory/NAME.ipynb``.

    Raises:
        ValueError: unknown exercise.
        FileExistsError: the file exists and ``force`` is False (a student's work is
            never overwritten by accident).
    """
    get(name)
    path = Path(directory) / f"{name}{'.ipynb' if notebook else '.py'}"
    if path.exists() and not force:
        raise FileExistsError(f"{path} exists; not overwritten (use --force to start over)")
    path.parent.mkdir(parents=True, exist_ok=True)
    if notebook:
        nb = notebook_json(name)
        for k, c in enumerate(nb["cells"]):
            c["id"] = f"{name[:20]}-{k}"  # nbformat 4.5 wants cell ids
        path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    else:
        path.write_text(starter_text(name), encoding="utf-8")
    return path
