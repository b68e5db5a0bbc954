"""The parent's side of ``armlab check``'s process boundary: the student's file runs in a
child process (:mod:`armlab.exercises.harness`, a fresh interpreter that cannot import
armlab), and :class:`RemoteFunction` calls their function there.

The parent (the checker) sends each call's inputs over a pipe and gets back what the
function returned, or the student's error as their file and line (:class:`StudentError`),
and judges it itself: whatever the child patches, prints, writes, forks or signals happens
in the child. A child that dies, hangs past its time limit, or answers nonsense raises
:class:`ChildGone` (a BaseException: the lab's loop does not take it for a law's error),
and the cases left fail with one line saying why.

While the child runs the parent is not dumpable (``PR_SET_DUMPABLE`` 0: a process of the
same user cannot ptrace it or read its memory) and a child subreaper, so that a process
the student's code forks and detaches is still found and killed when the check ends
(:meth:`StudentProcess.close`).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NoReturn

from armlab.exercises import harness
from armlab.exercises.harness import LinkBroken, decode, encode, read_frame, write_frame
from armlab.exercises.student import StudentError

#: Seconds the parent waits past a call's own limit (the child's SIGALRM) before it takes
#: the child for hung and kills it: a loaded machine may deliver the alarm late.
GRACE_S = 3.0
#: Lines of what the student's code printed that the check shows (after the cases).
PRINTED_LINES = 20

_PR_GET_DUMPABLE, _PR_SET_DUMPABLE = 3, 4
_PR_SET_CHILD_SUBREAPER, _PR_GET_CHILD_SUBREAPER = 36, 37


class ChildGone(BaseException):  # noqa: N818 -- a state, as KeyboardInterrupt is
    """The student's process can no longer answer: ``reason`` says why, one line."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _prctl(option: int, arg: int = 0) -> int | None:
    """``prctl(option, arg)`` on Linux (None elsewhere, or if it fails)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if option == _PR_GET_CHILD_SUBREAPER:
            out = ctypes.c_int(0)
            ok = libc.prctl(option, ctypes.byref(out), 0, 0, 0)
            return int(out.value) if ok == 0 else None
        res = libc.prctl(option, ctypes.c_ulong(arg), 0, 0, 0)
        return None if res < 0 else int(res)
    except (OSError, AttributeError):
        return None


def _children() -> set[int]:
    """The pids of this process's children (every thread's)."""
    out: set[int] = set()
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tasks:
        try:
            text = Path(f"/proc/self/task/{tid}/children").read_text()
        except OSError:
            continue
        out.update(int(p) for p in text.split())
    return out


def _descendants(pid: int) -> set[int]:
    """``pid``'s children, grandchildren, ... as /proc shows them now."""
    found, todo = set(), [pid]
    while todo:
        p = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for tid in tasks:
            try:
                kids = Path(f"/proc/{p}/task/{tid}/children").read_text().split()
            except OSError:
                continue
            for k in map(int, kids):
                if k not in found:
                    found.add(k)
                    todo.append(k)
    return found


def _wait_dead(pids: set[int], seconds: float) -> None:
    """Wait (at most ``seconds``) until each of ``pids`` has died: gone, or a zombie (its
    exit done, its children handed to their subreaper)."""
    end = time.monotonic() + seconds
    for p in pids:
        while time.monotonic() < end:
            try:
                state = Path(f"/proc/{p}/stat").read_text().rpartition(")")[2].split()[0]
            except (OSError, IndexError):
                break
            if state in ("Z", "X"):
                break
            time.sleep(0.001)


class StudentProcess:
    """The child running the student's file, and the link to it.

    Use as a context manager: entering starts the child, leaving kills it and every
    process it started. :meth:`load` runs the file; :meth:`call` calls a function of it.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.proc: subprocess.Popen[bytes] | None = None
        self.gone: str | None = None
        self._to = self._from = -1
        self._next_id = 0
        self._out = tempfile.TemporaryFile()
        self._before: set[int] = set()
        self._dumpable: int | None = None
        self._reaper: int | None = None
        self._closed = False

    def __enter__(self) -> StudentProcess:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Start the child (a fresh interpreter running :mod:`harness`)."""
        self._dumpable = _prctl(_PR_GET_DUMPABLE)
        _prctl(_PR_SET_DUMPABLE, 0)
        self._reaper = _prctl(_PR_GET_CHILD_SUBREAPER)
        _prctl(_PR_SET_CHILD_SUBREAPER, 1)
        self._before = _children()
        req_r, req_w = os.pipe()  # the parent's requests
        rep_r, rep_w = os.pipe()  # the child's replies
        # -P: the harness's folder (armlab's own armlab/exercises/) is not on sys.path; the
        # environment stays (a course's PYTHONPATH, the student's own --user packages)
        self.proc = subprocess.Popen(
            [sys.executable, "-P", "-u", harness.__file__, str(req_r), str(rep_w)],
            stdin=subprocess.DEVNULL, stdout=self._out, stderr=subprocess.STDOUT,
            pass_fds=(req_r, rep_w), start_new_session=True, close_fds=True)
        os.close(req_r)
        os.close(rep_w)
        self._to, self._from = req_w, rep_r

    def close(self) -> None:
        """Kill the child, its process group and every process it left behind (found as
        this process's new children: it is their subreaper while the child runs).

        SIGINT, SIGTERM and SIGHUP wait until it is done (a signal that stops the check
        cannot leave the student's processes running)."""
        blocked = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
        masked = threading.current_thread() is threading.main_thread()
        old = signal.pthread_sigmask(signal.SIG_BLOCK, blocked) if masked else None
        try:
            self._close()
        finally:
            if old is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, old)

    def _close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for fd in (self._to, self._from):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._to = self._from = -1
        if self.proc is not None:
            pid = self.proc.pid
            # while the child is unreaped its pid and group cannot name another process
            doomed = _descendants(pid) if self.proc.poll() is None else set()
            with contextlib.suppress(OSError):
                os.killpg(pid, signal.SIGKILL)
            for p in doomed:
                with contextlib.suppress(OSError):
                    os.kill(p, signal.SIGKILL)
            with contextlib.suppress(OSError):
                self.proc.kill()
            self.proc.wait()
            _wait_dead(doomed, 2.0)  # dead, so their own children have come to us
            for _ in range(1000):  # orphans come to this process, their subreaper
                strays = _children() - self._before - {pid}
                if not strays:
                    break
                for p in strays:
                    with contextlib.suppress(OSError):
                        os.kill(p, signal.SIGKILL)
                for p in strays:
                    with contextlib.suppress(OSError):
                        os.waitpid(p, 0)
        if self._reaper is not None:
            _prctl(_PR_SET_CHILD_SUBREAPER, self._reaper)
        if self._dumpable is not None:
            _prctl(_PR_SET_DUMPABLE, self._dumpable)

    def printed(self) -> list[str]:
        """What the student's code printed (stdout and stderr), as lines."""
        self._out.seek(0)
        return self._out.read(1 << 20).decode("utf-8", "replace").splitlines()

    def _exchange(self, message: dict[str, Any], seconds: float, what: str) -> dict[str, Any]:
        """Send ``message`` and wait for its reply; the child has ``seconds`` (plus
        :data:`GRACE_S`) for it.

        Raises:
            ChildGone: the child had already gone, died, hung or answered nonsense.
        """
        if self.gone is not None:
            raise ChildGone(self.gone)
        self._next_id += 1
        message["id"] = self._next_id
        try:
            write_frame(self._to, message)
            while True:
                reply = read_frame(self._from, time.monotonic() + seconds + GRACE_S)
                if reply.get("id") == self._next_id:
                    return reply
        except TimeoutError:
            self._lose(f"your code was still running {seconds + GRACE_S:g} s into {what} "
                       f"and did not stop at its {seconds:g} s limit: its process was "
                       "stopped")
        except (LinkBroken, OSError) as exc:
            self._lose(self._death(what, exc))
        raise AssertionError("unreachable")

    def _death(self, what: str, exc: Exception) -> str:
        assert self.proc is not None
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout=2.0)
        code = self.proc.poll()
        if code is None:
            return f"the link to your code's process broke during {what} ({exc})"
        how = (f"was killed by signal {-code}" if code < 0 else f"exited (status {code})")
        return f"your code's process {how} during {what} (os._exit, a crash?)"

    def _lose(self, reason: str) -> NoReturn:
        self.gone = reason
        self.close()
        raise ChildGone(reason)

    def load(self, functions: list[str]) -> tuple[str | None, dict[str, tuple[str, int]]]:
        """Run the student's file in the child.

        Returns:
            (its ``EXERCISE`` name or None, {function name: (file, line)} for each of
            ``functions`` the file defines).

        Raises:
            StudentError: the file does not load (their file and line).
            ChildGone: the child died or hung while loading it.
        """
        reply = self._exchange({"op": "load", "path": str(self.path), "functions": functions},
                               harness.LOAD_S, "loading your file")
        if "error" in reply:
            raise _student_error(reply["error"])
        loaded = reply.get("loaded")
        if not isinstance(loaded, dict):
            self._lose("your code's process answered nonsense while loading")
        exercise = loaded.get("exercise")
        where = {}
        for name, loc in dict(loaded.get("where") or {}).items():
            if name in functions and isinstance(loc, list) and len(loc) == 2:
                where[name] = (str(loc[0]), int(loc[1]) if isinstance(loc[1], int) else 0)
        return (exercise if isinstance(exercise, str) else None), where

    def call(self, name: str, args: tuple[Any, ...], kwargs: dict[str, Any],
             seconds: float) -> Any:
        """``name(*args, **kwargs)`` in the child, within ``seconds``.

        Raises:
            StudentError: their function raised, hung or returned what cannot be sent.
            ChildGone: the child died or hung past the limit.
        """
        reply = self._exchange({"op": "call", "fn": name, "args": encode(list(args)),
                                "kwargs": {k: encode(v) for k, v in kwargs.items()},
                                "seconds": seconds}, seconds, f"a call of {name}()")
        if "error" in reply:
            raise _student_error(reply["error"])
        if "ok" not in reply:
            self._lose(f"your code's process answered nonsense to a call of {name}()")
        try:
            return decode(reply["ok"])
        except LinkBroken as exc:
            self._lose(f"your code's process sent back what no function returns ({exc})")


def _student_error(data: Any) -> StudentError:
    """The StudentError the child described (checked: it is only text and a line)."""
    if not isinstance(data, dict):
        return StudentError("your code", 0, "an error the check could not read")
    line = data.get("line")
    return StudentError(str(data.get("path", "your code"))[:300],
                        line if isinstance(line, int) and not isinstance(line, bool) else 0,
                        str(data.get("error", ""))[:500] or "an error",
                        str(data.get("source", ""))[:200])


class RemoteFunction:
    """The student's function, called across the boundary: ``fn(*args)`` sends the call to
    the child and returns what their function returned.

    Each call has :attr:`seconds` (a value case's limit); inside :meth:`run_limit` (a
    closed-loop run) each call has what is left of the run's limit, at most that.
    """

    remote = True

    def __init__(self, child: StudentProcess, name: str, where: tuple[str, int]) -> None:
        self.child, self.__name__, self.where = child, name, where
        self.seconds = 5.0
        self._run_deadline: float | None = None
        self._run_seconds = 0.0

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        seconds = self.seconds
        if self._run_deadline is not None:
            left = self._run_deadline - time.monotonic()
            if left <= 0:
                raise StudentError(*self.where, f"Hang: the closed-loop run with your "
                                   f"function in it took more than {self._run_seconds:g} s")
            seconds = min(seconds, left)
        return self.child.call(self.__name__, args, kwargs, seconds)

    @contextlib.contextmanager
    def run_limit(self, seconds: float) -> Iterator[None]:
        """The calls made inside share ``seconds`` in all."""
        self._run_deadline, self._run_seconds = time.monotonic() + seconds, seconds
        try:
            yield
        finally:
            self._run_deadline = None

