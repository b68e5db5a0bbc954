"""Where a servo-arm lesson's arm comes from, and how it is let go (a helper module, not
a lesson; the compliance and your-own-arm lessons share it).

Three places, by the lesson's context:

- ``ctx.arms``: a student's own arm, run by the class and kept by their seat;
- ``ctx.arm_process`` (a simulated classroom): the shared arm in its worker process
  (:mod:`armlab.app.workers.worker_process`, RX-24F servos), unless servos with a firmware
  simulation of their own (X-series, Feetech STS) and a gripper keep it in the server;
- otherwise the lab's backend (``--backend``) opened here, its loop not started yet.
  With ``ctx.law`` (``armlab serve --exercise``) its loop runs the student's law, beside a
  simulated reference arm run by the lab's own (:class:`armlab.app.arm.student_law.LawLoop`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from armlab.app.arm.backends import has_firmware_sim, loop_over, make_backend
from armlab.app.arm.student_law import law_loop
from armlab.app.lessons import LessonContext
from armlab.control.backend import Backend
from armlab.control.loop import ControlLoop
from armlab.control.params import Params
from armlab.control.restart import RestartableArm
from armlab.kinematics.model import SerialChain


def open_arm(ctx: LessonContext, model: SerialChain, params: Params, *, preset: str,
             q0: np.ndarray, history_s: float, backend_kw: dict[str, Any] | None = None,
             restartable: bool = False) -> tuple[Backend, ControlLoop]:
    """The arm a lesson drives and its compliance loop (see the module docstring): a
    student's or a worker's at ``q0`` (n,) rad when new, named ``preset``; the lab's
    opened by ``make_backend(ctx.backend, model, port, baud, **backend_kw)``, with
    ``restartable`` a simulated one that a challenge's run can start again at a pose
    (:class:`armlab.control.restart.RestartableArm`, its ``q0`` in ``backend_kw``; a
    class's arms always can)."""
    if ctx.arms is not None:
        return ctx.arms.arm_for(model, params, preset=preset, q0=q0, history_s=history_s)
    if ctx.arm_process is not None and not has_firmware_sim(model):
        arm = ctx.arm_process.add(model, params, preset=preset, q0=q0, history_s=history_s)
        return arm.backend, arm.loop
    kw = dict(backend_kw or {})
    if restartable and ctx.backend == "sim" and not has_firmware_sim(model):
        def fresh(q: np.ndarray) -> Backend:
            return make_backend("sim", model, port=ctx.port, baud=ctx.baud, **{**kw, "q0": q})
        backend: Any = RestartableArm(fresh, kw.get("q0", q0))
    else:
        backend = make_backend(ctx.backend, model, port=ctx.port, baud=ctx.baud, **kw)
    if ctx.law is not None:  # the student's law, the lab's own on a reference arm beside it
        return backend, law_loop(ctx.law, backend, model, params, q0=q0,
                                 realtime=ctx.realtime, history_s=history_s)
    return backend, loop_over(backend, model, params, realtime=ctx.realtime,
                              history_s=history_s)


def shut_arm(backend: Backend, loop: ControlLoop) -> None:
    """Stop ``loop`` with torque off, E-STOP ``backend`` again (even after a link fault
    stopped the loop; never raises), then close it (not for a student's arm: their seat
    keeps it)."""
    try:
        loop.shutdown(torque_off=True)
        backend.estop()
    finally:
        backend.close()
