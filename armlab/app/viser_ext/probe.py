"""Checks that a private name of viser is still there, without an instance to look at."""

from __future__ import annotations

import types
from typing import Any


def code_names(func: Any) -> set[str]:
    """Every global or attribute name ``func``'s code (and the code nested in it) uses."""
    names: set[str] = set()
    todo = [func.__code__] if hasattr(func, "__code__") else []
    while todo:
        code = todo.pop()
        names.update(code.co_names)
        todo.extend(c for c in code.co_consts if isinstance(c, types.CodeType))
    return names


def assigned_in(cls: type, name: str) -> bool:
    """Whether ``cls`` has attribute ``name``, is a dataclass with that field, or the code
    of one of its methods names it (an attribute its instances get)."""
    if hasattr(cls, name) or name in getattr(cls, "__dataclass_fields__", {}):
        return True
    return any(name in code_names(f) for k in cls.__mro__ for f in vars(k).values()
               if isinstance(f, types.FunctionType))
