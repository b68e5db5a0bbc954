"""Running a student's code: loading their file, calling their function, and saying where
it went wrong as *their* file and line, never the checker's traceback.

:func:`load_module` executes a student's ``.py`` file (or the code cells of a ``.ipynb``
notebook) as a fresh module; :func:`guarded_call` calls one of its functions with a time
limit. Both turn whatever goes wrong in the student's code (an exception, a syntax error,
a hang) into one :class:`StudentError` carrying the student's file, line and the error.
``armlab check`` uses them, and so can anything else that runs a student's function in
place of the lab's own (``armlab serve --exercise``).
"""

from __future__ import annotations

import importlib.util
import json
import linecache
import signal
import sys
import sysconfig
import threading
import time
import traceback
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

#: Seconds a student's file may take to load (its top-level code).
LOAD_S = 10.0
#: A notebook cell that calls the check is not run again by ``armlab check``.
CHECK_CALLS = ("armlab.check(", "exercises.check(")


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


class Hang(BaseException):
    """The student's code ran past its time limit (a BaseException: a student's
    ``except Exception`` does not swallow it)."""


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
    if filename.startswith("<frozen") or filename in ("<string>", "<__array_function__>"):
        return False
    try:
        resolved = str(Path(filename).resolve())
    except (OSError, ValueError):
        resolved = filename
    return not any(resolved == d or resolved.startswith(d + "/") for d in _LIBRARY)


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


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` in the calling thread after ``seconds``.

    Uses SIGALRM, so it acts only in the main thread (where ``armlab check`` and a
    notebook's cells run); elsewhere it does nothing. A timer already running (pytest's
    timeout, an outer limit) is shortened to this one and given back its rest afterwards.
    """
    if (threading.current_thread() is not threading.main_thread()
            or not hasattr(signal, "setitimer")):
        yield
        return

    def alarm(signum: int, frame: types.FrameType | None) -> None:
        raise Hang(f"still running after {seconds:g} s (an endless loop?)")

    outer, _ = signal.getitimer(signal.ITIMER_REAL)
    start = time.monotonic()
    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, min(seconds, outer) if outer > 0 else seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
        if outer > 0:
            signal.setitimer(signal.ITIMER_REAL,
                             max(outer - (time.monotonic() - start), 1e-3))


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
    """(filename, source) pairs to run: the file, or one per notebook code cell (each
    cell's text registered with linecache, so errors show its line)."""
    if p.suffix != ".ipynb":
        return [(str(p), text)]
    try:
        cells = json.loads(text)["cells"]
    except (ValueError, KeyError, TypeError) as exc:
        raise StudentError(str(p), 0, f"not a Jupyter notebook ({exc})") from None
    out = []
    for k, cell in enumerate(cells, start=1):
        if cell.get("cell_type") != "code":
            continue
        src = cell.get("source", "")
        src = "".join(src) if isinstance(src, list) else str(src)
        if any(call in src for call in CHECK_CALLS):
            continue
        lines = [("pass  # " + ln if ln.lstrip().startswith(("%", "!")) else ln)
                 for ln in src.splitlines(keepends=True)]
        src = "".join(lines)
        name = f"{p} [cell {k}]"
        linecache.cache[name] = (len(src), None, src.splitlines(keepends=True), name)
        out.append((name, src))
    return out


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
        try:
            out = self.fn(*args, **kwargs)
        except Exception as exc:
            self.error = self.error or locate(exc, fallback=self.fn)
            raise
        want = self.shape(args) if callable(self.shape) else self.shape
        try:
            arr = np.asarray(out, dtype=float)
        except (TypeError, ValueError):
            arr = None
        why = ""
        if arr is None:
            why = f"{self.name} returned {type(out).__name__}, not numbers"
        elif arr.shape != want:
            why = f"{self.name} returned shape {arr.shape}, expected {want}"
        elif not np.all(np.isfinite(arr)):
            why = f"{self.name} returned NaN or inf: {arr.tolist()}"
        if why:
            code = getattr(self.fn, "__code__", None)
            err = StudentError(code.co_filename if code else "your code",
                               code.co_firstlineno if code else 0, why)
            self.error = self.error or err
            raise err
        return out

    def raise_error(self) -> None:
        """Raise the first error the run met in the student's function, if any."""
        if self.error is not None:
            raise self.error
