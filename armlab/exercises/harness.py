"""The child's side of ``armlab check``'s process boundary: a standalone script that runs a
student's file and calls their function on the inputs the checker sends, nothing more.

``armlab check`` starts it as ``python -P -u harness.py IN_FD OUT_FD`` (a fresh
interpreter, unbuffered, the script's folder not on ``sys.path``). It imports only the
standard library and numpy, then refuses every import of ``armlab`` (:class:`RefuseArmlab`,
first on ``sys.meta_path``), so the student's file cannot call the lab's reference by name.
It reads requests from ``IN_FD`` and writes replies to ``OUT_FD``, one frame each (a 4-byte
big-endian length, then UTF-8 JSON; numpy arrays as their raw bytes, base64):

- ``{"op": "load", "path": P, "functions": [NAME, ...]}``: run the student's ``.py`` (or
  the code cells of a ``.ipynb``) as a module; reply ``{"loaded": {"exercise": EXERCISE
  or null, "where": {NAME: [file, line]}}}`` for each NAME the file defines as a callable.
- ``{"op": "call", "fn": NAME, "args": [...], "kwargs": {...}, "seconds": S}``: call it
  with SIGALRM after S seconds; reply ``{"ok": VALUE}``, whatever it returned, encoded.

A failure of the student's code (an exception, a syntax error, a hang, ``sys.exit``, a
``KeyboardInterrupt``, a value that cannot be sent) replies ``{"error": {"path", "line",
"error", "source"}}``: their file and line. The checker (the parent) alone judges the
values; nothing this process does can reach its verdict.

The parent imports this module too (as ``armlab.exercises.harness``) for :func:`encode`,
:func:`decode`, :func:`sources`, :func:`time_limit` and :func:`outside`, which is why it
imports no armlab.
"""

from __future__ import annotations

import base64
import importlib.abc
import json
import linecache
import os
import signal
import struct
import sys
import sysconfig
import threading
import time
import traceback
import types
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

#: Seconds a student's file may take to load (its top-level code).
LOAD_S = 10.0
#: A notebook cell that calls the check is not run again by ``armlab check``.
CHECK_CALLS = ("armlab.check(", "exercises.check(")
#: Largest frame either side accepts, bytes.
MAX_FRAME = 64 * 2**20
#: dtypes an array may travel in as raw bytes (anything else travels as nested lists).
ARRAY_KINDS = "fiub"


class Hang(BaseException):
    """The student's code ran past its time limit (a BaseException: a student's
    ``except Exception`` does not swallow it)."""


class LinkBroken(Exception):
    """A frame could not be read or made sense of (the other side died or wrote nonsense)."""


# ---------------------------------------------------------------------------
# Values on the wire


def encode(value: Any, depth: int = 0) -> Any:
    """``value`` as JSON-able data: numbers, strings, None, lists, ``{"__tuple__": [...]}``,
    ``{"__nd__": [dtype, shape, base64]}`` for an array of real numbers, and
    ``{"__other__": "type: repr"}`` for anything else (a dict, complex, an object)."""
    if depth > 64:
        raise ValueError("nested more than 64 deep")
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, np.generic) and not isinstance(value, np.complexfloating):
        value = value.item()
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return float(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind in ARRAY_KINDS and value.dtype.itemsize <= 8:
            data = np.ascontiguousarray(value)
            return {"__nd__": [data.dtype.str, list(data.shape),
                               base64.b64encode(data.tobytes()).decode("ascii")]}
        if value.dtype.kind == "O":
            return {"__nd__obj__": [list(value.shape),
                                    [encode(v, depth + 1) for v in value.ravel().tolist()]]}
        return _other(value)
    if isinstance(value, list):
        return [encode(v, depth + 1) for v in value]
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v, depth + 1) for v in value]}
    return _other(value)


def _other(value: Any) -> dict[str, str]:
    try:
        text = repr(value)
    except Exception:
        text = "?"
    return {"__other__": f"{type(value).__name__} {text[:80]}"}


class Other:
    """A returned value that is not numbers, as the other side described it."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def decode(data: Any, depth: int = 0) -> Any:
    """The value :func:`encode` made, checked: arrays only of the dtypes in
    :data:`ARRAY_KINDS`; anything unexpected raises LinkBroken."""
    if depth > 66:
        raise LinkBroken("nested too deep")
    if data is None or isinstance(data, bool | int | float | str):
        return data
    if isinstance(data, list):
        return [decode(v, depth + 1) for v in data]
    if isinstance(data, dict) and len(data) == 1:
        (key, val), = data.items()
        if key == "__tuple__" and isinstance(val, list):
            return tuple(decode(v, depth + 1) for v in val)
        if key == "__other__" and isinstance(val, str):
            return Other(val[:200])
        if key == "__nd__" and isinstance(val, list) and len(val) == 3:
            return _array(*val)
        if key == "__nd__obj__" and isinstance(val, list) and len(val) == 2:
            shape, items = val
            if not (isinstance(shape, list) and all(isinstance(n, int) and n >= 0
                                                    for n in shape) and isinstance(items, list)):
                raise LinkBroken("a malformed object array")
            out = np.empty(len(items), dtype=object)
            out[:] = [decode(v, depth + 1) for v in items]
            try:
                return out.reshape(shape)
            except ValueError:
                raise LinkBroken("a malformed object array") from None
    raise LinkBroken(f"an unexpected value {str(data)[:60]}")


def _array(dtype: Any, shape: Any, text: Any) -> np.ndarray:
    try:
        dt = np.dtype(str(dtype))
    except TypeError:
        raise LinkBroken(f"an array of dtype {dtype!r}") from None
    if dt.kind not in ARRAY_KINDS or dt.itemsize > 8 or dt.fields is not None or dt.subdtype:
        raise LinkBroken(f"an array of dtype {dt}")
    if not (isinstance(shape, list) and len(shape) <= 32
            and all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape)
            and isinstance(text, str)):
        raise LinkBroken("a malformed array")
    try:
        raw = base64.b64decode(text, validate=True)
    except ValueError:
        raise LinkBroken("a malformed array") from None
    size = 1
    for n in shape:
        size *= n
    if len(raw) != size * dt.itemsize:
        raise LinkBroken("an array whose bytes do not fit its shape")
    return np.frombuffer(raw, dtype=dt).reshape(shape).copy()


def write_frame(fd: int, message: dict[str, Any]) -> None:
    """Send one message (JSON, NaN and inf allowed) on the pipe ``fd``."""
    body = json.dumps(message, allow_nan=True).encode("utf-8")
    if len(body) > MAX_FRAME:
        raise ValueError(f"a message of {len(body) / 2**20:.0f} MB is too large to send")
    data = struct.pack(">I", len(body)) + body
    while data:
        n = os.write(fd, data)
        data = data[n:]


def read_exact(fd: int, n: int, deadline: float | None) -> bytes:
    """``n`` bytes from ``fd`` before ``deadline`` (time.monotonic; None: no limit).

    Raises:
        LinkBroken: the pipe closed first.
        TimeoutError: the deadline passed first.
    """
    import select

    chunks, got = [], 0
    while got < n:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                raise TimeoutError
        chunk = os.read(fd, min(n - got, 1 << 20))
        if not chunk:
            raise LinkBroken("the pipe closed")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def read_frame(fd: int, deadline: float | None = None) -> dict[str, Any]:
    """One message from ``fd`` (see :func:`read_exact` for what it raises)."""
    (n,) = struct.unpack(">I", read_exact(fd, 4, deadline))
    if n > MAX_FRAME:
        raise LinkBroken(f"a frame of {n} bytes")
    body = read_exact(fd, n, deadline)
    try:
        message = json.loads(body.decode("utf-8"))
    except (ValueError, RecursionError) as exc:
        raise LinkBroken(f"not a message ({type(exc).__name__})") from None
    if not isinstance(message, dict):
        raise LinkBroken("not a message")
    return message


# ---------------------------------------------------------------------------
# Running the student's code


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` in the calling thread after ``seconds``.

    Uses SIGALRM, so it acts only in the main thread (where ``armlab check``'s child and a
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


def sources(p: Path, text: str) -> list[tuple[str, str]]:
    """(filename, source) pairs to run: the file, or one per notebook code cell (each
    cell's text registered with linecache, so errors show its line; cells that call the
    check and IPython's ``%``/``!`` lines left out).

    Raises:
        ValueError: a ``.ipynb`` that is not a notebook (the message says why).
    """
    if p.suffix != ".ipynb":
        return [(str(p), text)]
    try:
        cells = json.loads(text)["cells"]
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"not a Jupyter notebook ({exc})") from None
    out = []
    for k, cell in enumerate(cells, start=1):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
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


class RefuseArmlab(importlib.abc.MetaPathFinder):
    """First on ``sys.meta_path`` in the child: ``import armlab`` (or any ``armlab.*``)
    fails, so the lab's own reference cannot be called by name."""

    refuses_armlab = True

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> None:
        if name == "armlab" or name.startswith("armlab."):
            raise ModuleNotFoundError(
                f"No module named {name!r}: armlab check runs your file without the lab "
                "(write the equation yourself)", name=name)
        return None


def outside(filename: str, dirs: tuple[str, ...]) -> bool:
    """Whether a frame's ``filename`` lies outside every folder of ``dirs`` (resolved
    paths) and is a file at all (not ``<frozen ...>``, ``<string>``, numpy's
    ``<__array_function__>``): a frame of the student's code."""
    if filename.startswith("<frozen") or filename in ("<string>", "<__array_function__>"):
        return False
    try:
        resolved = str(Path(filename).resolve())
    except (OSError, ValueError):
        resolved = filename
    return not any(resolved == d or resolved.startswith(d + "/") for d in dirs)


def _library_dirs() -> tuple[str, ...]:
    paths = sysconfig.get_paths()
    dirs = {paths[k] for k in ("stdlib", "platstdlib", "purelib", "platlib") if k in paths}
    return tuple(sorted(str(Path(d).resolve()) for d in dirs))


class _Student:
    """The child's state: the student's module and where its frames are."""

    def __init__(self) -> None:
        self.library = _library_dirs()
        self.me = str(Path(__file__).resolve())
        self.namespace: dict[str, Any] = {}

    def is_theirs(self, filename: str) -> bool:
        return outside(filename, self.library + (self.me,))

    def locate(self, exc: BaseException, fallback: Any = None) -> dict[str, Any]:
        """Where ``exc`` happened in the student's code: their innermost frame, else
        ``fallback``'s definition."""
        frames = [f for f in traceback.extract_tb(exc.__traceback__)
                  if self.is_theirs(f.filename)]
        text = str(exc).strip().splitlines()
        error = f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
        if frames:
            f = frames[-1]
            return {"path": f.filename, "line": f.lineno or 0, "error": error,
                    "source": (f.line or "").strip()}
        code = getattr(fallback, "__code__", None)
        if code is not None:
            return {"path": code.co_filename, "line": code.co_firstlineno, "error": error,
                    "source": linecache.getline(code.co_filename,
                                                code.co_firstlineno).strip()}
        return {"path": "your code", "line": 0, "error": error, "source": ""}

    def load(self, path: str, functions: list[str]) -> dict[str, Any]:
        """Run the student's file as a module; what the parent needs to pick the exercise."""
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            return {"error": {"path": str(p), "line": 0, "source": "",
                              "error": f"cannot read the file ({exc})"}}
        module = types.ModuleType("__student__")
        module.__file__ = str(p)
        sys.modules["__student__"] = module  # what dataclasses and pickle look a module up in
        sys.path.insert(0, str(p.resolve().parent))  # their own helpers next to the file
        try:
            pairs = sources(p, text)
        except ValueError as exc:
            return {"error": {"path": str(p), "line": 0, "error": str(exc), "source": ""}}
        for filename, source in pairs:
            try:
                code = compile(source, filename, "exec")
            except SyntaxError as exc:
                return {"error": {"path": filename, "line": exc.lineno or 0,
                                  "error": f"SyntaxError: {exc.msg}",
                                  "source": (exc.text or "").strip()}}
            try:
                with time_limit(LOAD_S):
                    exec(code, module.__dict__)
            except BaseException as exc:  # noqa: B036 -- every failure is theirs
                return {"error": self.locate(exc)}
        self.namespace = module.__dict__
        exercise = self.namespace.get("EXERCISE")
        where = {}
        for name in functions:
            fn = self.namespace.get(name)
            if callable(fn):
                fn_code = getattr(fn, "__code__", None)
                where[name] = ([fn_code.co_filename, fn_code.co_firstlineno]
                               if fn_code is not None else [str(p), 0])
        return {"loaded": {"exercise": exercise if isinstance(exercise, str) else None,
                           "where": where}}

    def call(self, name: str, args: Any, kwargs: Any, seconds: float) -> dict[str, Any]:
        """Call the student's function ``name``; its value, or where it went wrong."""
        fn = self.namespace.get(name)
        try:
            a = decode(args)
            if not isinstance(a, list) or not isinstance(kwargs, dict):
                raise LinkBroken("not a call")
            kw = {str(k): decode(v) for k, v in kwargs.items()}
        except LinkBroken as exc:
            return {"error": {"path": "the check", "line": 0, "source": "",
                              "error": f"bad request ({exc})"}}
        if not callable(fn):
            return {"error": {"path": "your file", "line": 0, "source": "",
                              "error": f"no function {name}()"}}
        try:
            with time_limit(seconds):
                out = fn(*a, **kw)
                value = encode(out)
        except BaseException as exc:  # noqa: B036 -- every failure is theirs
            return {"error": self.locate(exc, fallback=fn)}
        return {"ok": value}


def serve(in_fd: int, out_fd: int) -> None:
    """Answer the parent's requests until it closes the pipe or says ``exit``."""
    student = _Student()
    while True:
        try:
            request = read_frame(in_fd)
        except LinkBroken:
            return
        op = request.get("op")
        if op == "load":
            reply = student.load(str(request.get("path")), list(request.get("functions", [])))
        elif op == "call":
            reply = student.call(str(request.get("fn")), request.get("args", []),
                                 request.get("kwargs", {}), float(request.get("seconds", 5)))
        else:
            return
        reply["id"] = request.get("id")
        try:
            write_frame(out_fd, reply)
        except ValueError as exc:  # the value was too large to send
            write_frame(out_fd, {"id": request.get("id"), "error": {
                "path": "your code", "line": 0, "source": "", "error": str(exc)}})


def main(argv: list[str]) -> None:
    """``harness.py IN_FD OUT_FD``: refuse armlab, then serve."""
    in_fd, out_fd = int(argv[1]), int(argv[2])
    for name in [m for m in sys.modules if m == "armlab" or m.startswith("armlab.")]:
        del sys.modules[name]
    sys.meta_path.insert(0, RefuseArmlab())
    serve(in_fd, out_fd)
    sys.stdout.flush()
    os._exit(0)  # the student's atexit hooks are theirs; the parent has its replies


if __name__ == "__main__":
    main(sys.argv)
