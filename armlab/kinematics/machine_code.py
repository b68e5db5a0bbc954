"""Code compiled to machine code (numba) in a thread of its own, while numpy goes on.

A class's plant runs the same arithmetic on every arm: numpy over (n, N) arrays pays its
per-call overhead (about a microsecond a call) hundreds of times a step, where loops over
the arms compiled by numba pay it once. Compiling takes seconds, so :class:`MachineCode`
compiles in a thread of its own, started on first need, and gives the compiled code once
it is there; its owner runs the numpy code until then. Each compiled loop does the numpy
code's IEEE operations in their order (numba without ``fastmath``), so the switch changes
no number; a test checks each one bit for bit against its numpy code.

Without numba (not installed, or a Python it has no wheel for), or when compiling fails,
there is no compiled code and :attr:`MachineCode.error` says why: the numpy code runs.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

#: False: no compiled code runs anywhere, the numpy code does (``armlab bench`` times both)
ENABLED = True

#: a compiled loop: its arrays (the outputs among them, written in place) -> None, or a
#: count of what it wrote
Kernel = Callable[..., Any]


class MachineCode:
    """The compiled loops ``build()`` makes (a dict, name -> loop), once it has made them.

    :meth:`kernel` gives one, or None while there is none; :meth:`start` starts compiling
    in a thread of its own; :meth:`wait` compiles and waits (benches, tests).
    :attr:`error` says why there are none (numba missing, a failed compile).
    """

    def __init__(self, build: Callable[[], dict[str, Kernel]], name: str) -> None:
        self._build, self.name = build, name
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._kernels: dict[str, Kernel] = {}
        self.error: str | None = None

    def kernel(self, name: str) -> Kernel | None:
        """The compiled loop ``name`` when it is ready and :data:`ENABLED`; None otherwise."""
        return self._kernels.get(name) if ENABLED else None

    def start(self) -> None:
        """Start compiling in a thread of its own (nothing when started before, or when
        not :data:`ENABLED`)."""
        if not ENABLED:
            return
        with self._lock:
            if self._thread is not None:
                return
            self._thread = threading.Thread(target=self._compile, daemon=True,
                                            name=f"armlab-compile {self.name}")
            self._thread.start()

    def wait(self, timeout: float | None = None) -> bool:
        """Compile (if not done) and wait up to ``timeout`` s; True when compiled."""
        self.start()
        thread = self._thread
        if thread is not None:
            thread.join(timeout)
        return bool(self._kernels)

    def _compile(self) -> None:
        try:
            self._kernels = self._build()
        except ImportError as exc:
            self.error = f"numba is not installed ({exc})"
        except Exception as exc:  # a numba that cannot compile this: numpy goes on
            self.error = f"numba could not compile {self.name} ({type(exc).__name__}: {exc})"
