"""The lab's own law of the periods due at one tick of a shared clock, computed as one.

A class's private arms (``armlab serve --classroom``: each student's "My arm") are
:class:`~armlab.control.loop.ControlLoop` s on one
:class:`~armlab.control.periodic.SharedClock`. Each period reads its arm, applies its
commands, checks what its servos report and works out its command and τ_dyn on its own.
Then, instead of each running the controller's few dozen numpy calls on its own
3-vectors, the periods due at the tick wait here for their law. Once the tick's periods
have run (:meth:`SharedClock.finish_periods`), the batch runs
:meth:`~armlab.control.compliance.ComplianceController.step` once on (K, n) arrays for
each group of periods that make the same choices (mode, compliance, law, feedforward)
under the same joint limits, sends each period its row, and each finishes on its own: its run-time
checks, its write, its record.

The arithmetic is the per-arm step's, element by element, so every arm's numbers are its
own loop's to the last bit (``tests/test_law_batch.py``). A student's own law runs in its
own period, never here; a group smaller than :data:`SMALLEST`, or a group whose batched
step fails, computes each period's law on its own.
"""

from __future__ import annotations

import weakref
from collections.abc import Generator
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from armlab.control.backend import JointState
from armlab.control.compliance import ComplianceController, ControllerState
from armlab.control.params import GAINS, ParamColumns, Params

if TYPE_CHECKING:
    from armlab.control.loop import ControlLoop
    from armlab.control.periodic import SharedClock

#: (θ_ref, θ̇_ref), each (n,): what the controller's step returns to a period
LawAnswer = tuple[np.ndarray, np.ndarray]
#: a period waiting for its law: it is sent its answer, or None to compute its own
Waiting = Generator["LawAsk", "LawAnswer | None", None]

_STATE = tuple(f.name for f in fields(ControllerState))
#: the smallest group stepped as one: gathering a group into one table and back costs
#: about what four periods' own steps cost (measured on the thesis arm)
SMALLEST = 5


@dataclass(frozen=True)
class LawAsk:
    """What one period's :meth:`ComplianceController.step` is called with (its arguments,
    each (n,)); ``state`` is updated in place, as the step updates it."""

    controller: ComplianceController
    params: Params
    state: ControllerState
    q_cmd: np.ndarray
    qd_cmd: np.ndarray
    qdd_cmd: np.ndarray
    measured: JointState
    tau_dyn: np.ndarray

    def group(self) -> tuple[object, ...]:
        """The periods whose laws can be computed as one share this: the mode run, the
        choices of compliance, law and feedforward, the controller's joint and speed
        limits."""
        c, p = self.controller, self.params
        return (c.effective_mode(p), p.compliance, p.law, p.feedforward, c.lower.tobytes(),
                c.upper.tobytes(), c.max_speed.tobytes())


def step_many(asks: list[LawAsk]) -> list[LawAnswer]:
    """:meth:`ComplianceController.step` of K periods of one :meth:`LawAsk.group`, as one
    step on (K, n) arrays: each ask's state updated (its rows), its (θ_ref, θ̇_ref)
    returned. Raises what the step raises, every state then as it was.

    Every number of the K asks is gathered into one (K, gains + 15 n) table, once; the
    step's arrays are its columns (views). Gathering and scattering cost about four
    periods' own steps, so it pays from :data:`SMALLEST` periods on."""
    first = asks[0]
    n = len(first.q_cmd)
    rows = []
    for a in asks:
        row = [getattr(a.params, g) for g in GAINS]
        for v in (*(getattr(a.state, f) for f in _STATE), a.q_cmd, a.qd_cmd, a.qdd_cmd,
                  a.measured.position, a.measured.velocity, a.measured.load, a.tau_dyn):
            row += v.tolist()
        rows.append(row)
    table = np.array(rows)
    g = len(GAINS)
    gains = (table[:, i:i + 1] for i in range(g))
    p = first.params
    params = ParamColumns(**dict(zip(GAINS, gains, strict=True)), compliance=p.compliance,
                          law=p.law, feedforward=p.feedforward)
    blocks = [table[:, g + i * n:g + (i + 1) * n] for i in range(len(_STATE) + 7)]
    state = ControllerState(*blocks[:len(_STATE)])
    q_cmd, qd_cmd, qdd_cmd, position, velocity, load, tau_dyn = blocks[len(_STATE):]
    measured = JointState(t=first.measured.t, position=position, velocity=velocity, load=load,
                          errors=(), torque_on=())
    q_ref, qd_ref = first.controller.step(params, state, q_cmd, qd_cmd, qdd_cmd, measured,
                                          tau_dyn)
    for name in _STATE:
        for a, row_of in zip(asks, getattr(state, name), strict=True):
            setattr(a.state, name, row_of)
    return list(zip(q_ref, qd_ref, strict=True))


class LawBatch:
    """The periods of a clock's loops waiting, at one tick, for their law (module doc).
    One per clock (:meth:`of`); used by the clock's thread only, the clock's lock held."""

    _of: weakref.WeakKeyDictionary[SharedClock, LawBatch] = weakref.WeakKeyDictionary()

    def __init__(self, *, smallest: int = SMALLEST) -> None:
        #: groups of fewer periods compute each period's own law
        self.smallest = smallest
        #: periods whose law a batched step computed (since the batch was made)
        self.batched = 0
        self._waiting: dict[ControlLoop, tuple[Waiting, LawAsk]] = {}

    @classmethod
    def of(cls, clock: SharedClock) -> LawBatch:
        """``clock``'s batch, made and put at the end of its ticks the first time."""
        batch = cls._of.get(clock)
        if batch is None:
            batch = cls._of[clock] = cls()
            clock.finish_periods(batch.finish)
        return batch

    def add(self, loop: ControlLoop, period: Waiting, ask: LawAsk) -> None:
        """``loop``'s ``period`` waits for its law (``ask``) until the tick's end."""
        self.settle(loop)
        self._waiting[loop] = (period, ask)

    def settle(self, loop: ControlLoop) -> None:
        """A period of ``loop`` still waiting computes its own law and finishes now (before
        the loop's next period: a loop faster than the clock's step has two in a tick)."""
        waiting = self._waiting.pop(loop, None)
        if waiting is not None:
            loop._drive(waiting[0], None)

    def finish(self) -> None:
        """Every waiting period's law, each group's as one; then each period finishes."""
        waiting, self._waiting = self._waiting, {}
        groups: dict[tuple[object, ...], list[tuple[ControlLoop, Waiting, LawAsk]]] = {}
        for loop, (period, ask) in waiting.items():
            try:
                key = ask.group()
            except Exception:  # noqa: BLE001 - then it computes its own
                key = ("alone", id(loop))
            groups.setdefault(key, []).append((loop, period, ask))
        for group in groups.values():
            answers: list[LawAnswer | None] = [None] * len(group)
            if len(group) >= max(2, self.smallest):
                try:
                    answers = list(step_many([ask for _, _, ask in group]))
                    self.batched += len(group)
                except Exception:  # noqa: BLE001 - each period then computes its own
                    pass
            for (loop, period, _), answer in zip(group, answers, strict=True):
                loop._drive(period, answer)
