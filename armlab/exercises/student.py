"""Running a student's code: loading their file, calling their function, and saying where
it went wrong as *their* file and line, never the checker's traceback.

:func:`load_module` executes a student's ``.py`` file (or the code cells of a ``.ipynb``
notebook) as a fresh module; :func:`guarded_call` calls one of its functions with a time
limit. Both turn whatever goes wrong in the student's code (an exception, a syntax error,
a hang) into one :class:`StudentError` carrying the student's file, line and the error.
``armlab serve --exercise`` and the notebook's ``armlab.check(fn)`` use them in their own
process; ``armlab check`` runs the student's file in a child process instead
(:mod:`armlab.exercises.boundary`, :mod:`armlab.exercises.harness`).
"""

from __future__ import annotations

import importlib.util
import linecache
import sys
import sysconfig
import traceback
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from armlab.exercises.harness import CHECK_CALLS, LOAD_S, Hang, outside, sources, time_limit

__all__ = ["CHECK_CALLS", "LOAD_S", "CheckedLaw", "Hang", "StudentError", "guarded_call",
           "is_student_file", "load_module", "locate", "time_limit"]


class StudentError(Exception):
    """Something wrong in the student's code, located in their file.

    Attributes:
        path: the student's file (or notebook cell), as Python names it.
        line: the line in it (0 when unknown).
        error: what went wrong, one line ("ZeroDivisionError: division by zero").
        source: the text of that line, stripped ("" when unknown).
    """

    def __init__(self, path: str, line: int, error: str, source: str = "") -> None:
        self.path, self.line, self.error, self.source = path, line, error, source
        where = f"{path}:{line}" if line else path
        message = error.partition(": ")[2]
        shown = source and not (message and message in source)  # not the raise of it again
        super().__init__(f"{where}: {error}" + (f"  [{source}]" if shown else ""))


def _library_dirs() -> tuple[str, ...]:
    """Folders whose frames are not the student's: Python's own, site-packages, armlab."""
    paths = sysconfig.get_paths()
    dirs = {paths[k] for k in ("stdlib", "platstdlib", "purelib", "platlib") if k in paths}
    for name in ("armlab", "armlab.app", "armlab.control", "armlab.exercises",
                 "armlab.hardware", "armlab.kinematics"):
        spec = importlib.util.find_spec(name)
        for loc in (spec.submodule_search_locations or []) if spec else []:
            dirs.add(str(Path(loc)))
    return tuple(sorted(str(Path(d).resolve()) for d in dirs))


_LIBRARY: tuple[str, ...] | None = None


def is_student_file(filename: str) -> bool:
    """True for a frame of the student's code: not Python's, not a library's, not armlab's."""
    global _LIBRARY
    if _LIBRARY is None:
        _LIBRARY = _library_dirs()
    return outside(filename, _LIBRARY)


def locate(exc: BaseException, *, fallback: Callable[..., Any] | None = None) -> StudentError:
    """The :class:`StudentError` for ``exc`` raised in a student's code: the innermost frame
    of its traceback in the student's files, or ``fallback``'s definition line."""
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if is_student_file(f.filename)]
    error = _one_line(exc)
    if frames:
        f = frames[-1]
        return StudentError(f.filename, f.lineno or 0, error, (f.line or "").strip())
    if fallback is not None and hasattr(fallback, "__code__"):
        code = fallback.__code__
        return StudentError(code.co_filename, code.co_firstlineno, error,
                            linecache.getline(code.co_filename, code.co_firstlineno).strip())
    return StudentError("your code", 0, error)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def guarded_call(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any], *,
                 seconds: float, user: bool = True) -> Any:
    """``fn(*args, **kwargs)`` within ``seconds``; the student's failures as StudentError.

    Args:
        user: ``fn`` is the student's function itself (an error not located in their files
            is still theirs, at its definition); False: ``fn`` is the checker's harness
            around it, whose own errors (no student frame) propagate unchanged.

    Raises:
        StudentError: an exception raised in the student's code, or a hang (located at
            the line that was running).
    """
    try:
        with time_limit(seconds):
            return fn(*args, **kwargs)
    except StudentError:
        raise
    except (Hang, SystemExit) as exc:  # a student's sys.exit() ends their case, not the check
        raise locate(exc, fallback=fn if user else None) from None
    except Exception as exc:
        err = locate(exc, fallback=fn if user else None)
        if not user and err.line == 0:
            raise
        raise err from None


def load_module(path: str | Path) -> types.ModuleType:
    """Execute a student's ``.py`` file, or the code cells of a ``.ipynb`` notebook, as a
    new module (cells that call the check are left out; IPython's ``%``/``!`` lines too).

    Raises:
        StudentError: the file is missing or unreadable, has a syntax error, or its
            top-level code raises or hangs.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise StudentError(str(p), 0, f"cannot read the file ({exc})") from None
    module = types.ModuleType(f"armlab_student_{abs(hash(str(p.resolve())))}")
    module.__file__ = str(p)
    sys.modules[module.__name__] = module  # what dataclasses and pickle look a module up in
    folder = str(p.resolve().parent)  # the student's own helper modules next to the file
    sys.path.insert(0, folder)
    try:
        _run_sources(p, text, module)
    finally:
        sys.path.remove(folder)
    return module


def _run_sources(p: Path, text: str, module: types.ModuleType) -> None:
    for filename, source in _sources(p, text):
        try:
            code = compile(source, filename, "exec")
        except SyntaxError as exc:
            line = (exc.text or "").strip()
            raise StudentError(filename, exc.lineno or 0, f"SyntaxError: {exc.msg}",
                               line) from None
        try:
            with time_limit(LOAD_S):
                exec(code, module.__dict__)
        except (Exception, Hang, SystemExit) as exc:
            raise locate(exc) from None


def _sources(p: Path, text: str) -> list[tuple[str, str]]:
    """(filename, source) pairs to run: the file, or one per notebook code cell."""
    try:
        return sources(p, text)
    except ValueError as exc:
        raise StudentError(str(p), 0, str(exc)) from None


def definition(fn: Callable[..., Any]) -> tuple[str, int]:
    """Where the student's function is defined: (file, line), ("your code", 0) unknown."""
    where = getattr(fn, "where", None)  # a function across the process boundary
    if isinstance(where, tuple):
        return where
    code = getattr(fn, "__code__", None)
    return (code.co_filename, code.co_firstlineno) if code else ("your code", 0)


class CheckedLaw:
    """The student's function as the lab calls it in a run, its output checked.

    The first thing that goes wrong (an exception, a wrong shape, NaN) is kept as
    :attr:`error` (their file and line) and raised, so the run stops; the run's harness
    then reports :attr:`error` rather than how the lab's loop saw it.
    """

    def __init__(self, fn: Callable[..., Any], name: str,
                 shape: Callable[[tuple[Any, ...]], tuple[int, ...]] | tuple[int, ...]) -> None:
        self.fn, self.name, self.shape = fn, name, shape
        self.error: StudentError | None = None

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        """Call the student's function; its value as a float array (a float for one
        number), so that the lab's loop never meets a list or a tuple."""
        try:
            out = self.fn(*args, **kwargs)
        except StudentError as exc:  # from across the process boundary: located already
            self.error = self.error or exc
            raise
        except Exception as exc:
            self.error = self.error or locate(exc, fallback=self.fn)
            raise
        want = self.shape(args) if callable(self.shape) else self.shape
        try:
            arr = np.array(out, dtype=float)
        except (TypeError, ValueError, OverflowError):
            arr = None
        why = ""
        if arr is None:
            why = f"{self.name} returned {type(out).__name__}, not numbers"
        elif arr.shape != want:
            why = f"{self.name} returned shape {arr.shape}, expected {want}"
        elif not np.all(np.isfinite(arr)):
            why = f"{self.name} returned NaN or inf: {arr.tolist()}"
        if why or arr is None:
            err = StudentError(*definition(self.fn), why)
            self.error = self.error or err
            raise err
        return arr if arr.ndim else float(arr)

    def raise_error(self) -> None:
        """Raise the first error the run met in the student's function, if any."""
        if self.error is not None:
            raise self.error
