"""Thesis 000 chapter 4 on the simulated (or a real) arm, and the step-response check.

``armlab experiment thesis-line --controller none|pd|compliance [--push N] [--preset NAME]``
runs the chapter-4 20 cm line twice through the same :class:`ControlLoop` the lab
uses, headless: once in free motion (max angle error θ_cmd − θ per joint, the
thesis's own metric, and the torque error LPF(servo load) − Newton–Euler, thesis
fig. 4.2/4.4/4.6) and once with a hand pushing against the motion (the same angle
error, fig. 4.9/4.12, and apart from it the yield: how far the push moved each
joint compared with the free run).

``armlab experiment step --kp K --kv K`` prints eq. 2.16–2.19 next to the same
figures measured on the sampled ideal joint and on eq. 2.3 (with its zero).

The backend comes from ``backend_factory`` (the CLI makes it from
``--backend``/``--port``/``--baud``): armlab/control/ never imports hardware/.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Literal, cast

import numpy as np

from armlab.control.backend import Backend, Pushable
from armlab.control.commands import Push, RunTrajectory
from armlab.control.compliance import Laws, Mode
from armlab.control.experiments import BackendOptions, Experiment, Keep, advance, option
from armlab.control.loop import APPROACH_MIN, ControlLoop
from armlab.control.params import PRESETS, Law, Params, preset
from armlab.control.response import simulate_ideal_joint_step, step_report
from armlab.control.runs import Run, lab_version, run_from_snapshot, utc_now
from armlab.control.trajectory import (
    THESIS_PERIOD,
    JointTrajectory,
    approach_duration,
    hold,
    minimum_jerk,
    thesis_line,
)
from armlab.kinematics.catalog import load_robot
from armlab.kinematics.model import SerialChain

BackendFactory = Callable[..., Backend]

SETTLE_S = 1.0  #: hold at the line's start before it runs
TAIL_S = 2.0  #: hold at its end afterwards
PUSH_DELAY_S = 0.3  #: the push starts this long after the line does
PUSH_S = 1.5  #: and lasts this long
DEFAULT_PUSH_N = 3.0


@dataclass(frozen=True)
class LineRun:
    """One run of the line: the plan, the loop's recording and what was commanded when
    ({"t": loop time s, "kind": the command's class, ...} in order)."""

    plan: JointTrajectory
    line_start: float
    line_end: float
    snapshot: dict[str, np.ndarray]
    commands: tuple[dict[str, Any], ...] = ()


def line_plan(model: SerialChain, *, line_period: float = THESIS_PERIOD
              ) -> tuple[JointTrajectory, float, float]:
    """Hold at the start, the thesis line, hold at the end; with the line's start/end times.

    ``line_period``: seconds per 2.5 mm step of the line (the thesis: 16 ms, so 1.28 s).
    """
    line = thesis_line(model, period=line_period)
    plan = hold(line.q[0], SETTLE_S).then(line).then(hold(line.q[-1], TAIL_S), name=line.name)
    return plan, SETTLE_S, SETTLE_S + line.duration


def run_line(model: SerialChain, backend_factory: BackendFactory, params: Params, *,
             controller: str, push_n: float = 0.0, realtime: bool = False,
             line_period: float = THESIS_PERIOD, laws: Laws | None = None) -> LineRun:
    """Run the plan; push the hand along −y (base frame) when ``push_n`` > 0.

    ``laws``: the controller's equations (default: the lab's own).

    A simulated arm starts on the line's first point and runs headless (``realtime``
    False); real servos run paced by the clock, and are first moved to the line's
    start (minimum jerk) from wherever they stand.

    Raises:
        ValueError: the loop stopped on a fault, or the backend cannot be pushed.
    """
    plan, settle, line_end = line_plan(model, line_period=line_period)
    backend = backend_factory(model, q0=plan.q[0])
    loop: ControlLoop | None = None
    try:
        if push_n > 0 and not isinstance(backend, Pushable):
            raise ValueError("this backend cannot be pushed; use --push 0 and push the "
                             "real arm by hand")
        loop = ControlLoop(model, backend, params, controller=controller,  # type: ignore[arg-type]  # a Pushable backend is a Backend too (the factory's)
                           realtime=realtime, history_s=plan.duration + 15.0, laws=laws)
        if realtime:
            loop.start()
        advance(loop, 0.1)
        here = loop.recorder.snapshot(0.0)["q_cmd"][-1]
        full, lead = plan, 0.0
        if np.max(np.abs(here - plan.q[0])) > APPROACH_MIN:
            approach = minimum_jerk(here, plan.q[0], approach_duration(here, plan.q[0]))
            full, lead = approach.then(plan, name=plan.name), approach.duration
        start = loop.status.t  # a command posted now applies at the period starting now
        loop.post(RunTrajectory(full, approach=False))
        commands = [{"t": start, "kind": "RunTrajectory", "name": full.name,
                     "duration_s": full.duration, "line_start_s": start + lead + settle,
                     "line_end_s": start + lead + line_end}]
        t0, t1 = start + lead + settle, start + lead + line_end
        if push_n > 0:
            advance(loop, t0 + PUSH_DELAY_S)
            force = np.array([0.0, -push_n, 0.0])
            loop.post(Push(force, model.n - 1, model.tip[:3, 3], PUSH_S))
            commands.append({"t": loop.status.t, "kind": "Push", "force_n": force.tolist(),
                             "link": model.n - 1, "point_m": model.tip[:3, 3].tolist(),
                             "duration_s": PUSH_S})
        advance(loop, start + full.duration + 0.05)
        status = loop.status
        if status.fault:
            raise ValueError(f"the loop stopped: {status.fault}")
        return LineRun(full, t0, t1, loop.recorder.snapshot(), tuple(commands))
    finally:
        if loop is not None:
            loop.shutdown()
        backend.close()


def max_angle_error(run: LineRun, until: float | None = None) -> np.ndarray:
    """The thesis's chapter-4 metric: max |θ_cmd − θ| per joint (command minus actual), rad.

    Taken from the line's start to its end, or to ``until`` (s, loop time) when that is
    later (a push that outlasts the line keeps bending the arm away from its command).
    """
    s = run.snapshot
    end = run.line_end if until is None else max(run.line_end, until)
    on = (s["t"] >= run.line_start) & (s["t"] <= end)
    return np.nanmax(np.abs(s["error"][on]), axis=0)


def line_record(model: SerialChain, params: Params, run: LineRun, *, controller: str) -> Run:
    """One run of the line as a run file's :class:`Run`: the loop's recorded signals at its
    period, the gains, the trajectory and the push as commanded."""
    return run_from_snapshot(run.snapshot, robot=model.name, joint_names=model.joint_names,
                             source="experiment:thesis-line",
                             params={**params.as_dict(), "controller": controller},
                             commands=run.commands,
                             extra={"line_start_s": run.line_start, "line_end_s": run.line_end,
                                    "pushed": any(c["kind"] == "Push" for c in run.commands)})


def thesis_line_figures(model: SerialChain, backend_factory: BackendFactory, params: Params, *,
                        controller: str, push_n: float, realtime: bool = False,
                        line_period: float = THESIS_PERIOD,
                        keep: Keep | None = None) -> dict[str, Any]:
    """The chapter-4 figures for one controller (JSON keys of issue 3's public surface).

    Chapter 4 judges every run by command minus actual angle per servo; that is
    ``max_angle_error_deg`` (free motion, thesis fig. 4.2/4.4) and
    ``max_angle_error_pushed_deg`` (a hand pushing against the motion, fig. 4.9/4.12:
    "over 15° on servo 3" is this figure). How far the push moved each joint compared
    with the free run (``max_yield_deg``) is a different quantity, reported apart.

    ``keep`` is handed the free run, then the pushed one (:func:`line_record`).

    Returns:
        {"controller", "max_angle_error_deg" [n], "max_angle_error_pushed_deg" [n],
        "torque_error_max_nm" [n], "max_yield_deg" [n]}; the pushed figures are zeros
        without a push.
    """
    free = run_line(model, backend_factory, params, controller=controller, realtime=realtime,
                    line_period=line_period)
    if keep is not None:
        keep(line_record(model, params, free, controller=controller))
    s = free.snapshot
    on_line = (s["t"] >= free.line_start) & (s["t"] <= free.line_end)
    err = np.degrees(max_angle_error(free))
    torque = np.nanmax(np.abs(s["tau_load"][on_line] - s["tau_dyn"][on_line]), axis=0)
    if push_n > 0:
        pushed = run_line(model, backend_factory, params, controller=controller, push_n=push_n,
                          realtime=realtime, line_period=line_period)
        if keep is not None:
            keep(line_record(model, params, pushed, controller=controller))
        p = pushed.snapshot
        m = min(len(p["t"]), len(s["t"]))
        yield_deg = np.degrees(np.nanmax(np.abs(p["q"][:m] - s["q"][:m]), axis=0))
        err_pushed = np.degrees(max_angle_error(
            pushed, until=pushed.line_start + PUSH_DELAY_S + PUSH_S))
    else:
        yield_deg = err_pushed = np.zeros(model.n)
    return {
        "controller": controller,
        "max_angle_error_deg": [round(float(x), 3) for x in err],
        "max_angle_error_pushed_deg": [round(float(x), 3) for x in err_pushed],
        "torque_error_max_nm": [round(float(x), 4) for x in torque],
        "max_yield_deg": [round(float(x), 3) for x in yield_deg],
    }


@dataclass(frozen=True)
class LineOptions(BackendOptions):
    """Options of ``thesis-line`` (see :func:`thesis_line_figures`)."""

    controller: Mode = option(
        "compliance", "none: RMRC angles straight to the servos; pd: eq. 2.20; "
        "compliance: eq. 2.6/2.26 (default)")
    push: float | None = option(
        None, f"hand push against the motion, N (default {DEFAULT_PUSH_N:g} on the "
        "simulated arm, 0 on real servos)", metavar="N")
    preset: str = option("well-damped default",
                         "parameter preset: " + ", ".join(repr(k) for k in PRESETS),
                         metavar="NAME")
    law: Law | None = option(None, "override the preset's compliance law")
    feedforward: Literal["on", "off"] | None = option(
        None, "override the preset's feed-forward of θ̈_cmd (not in the thesis; on in the "
        "lab's default, off in the thesis presets)")
    robot: str = option("receptionist_arm", "robot model", hidden=True)


def _line_run(options: LineOptions, *, backend_factory: BackendFactory,
              keep: Keep | None = None) -> dict[str, Any]:
    o = options
    push = o.push
    if push is None:
        push = DEFAULT_PUSH_N if o.backend == "sim" else 0.0
    if not np.isfinite(push) or push < 0:
        raise ValueError(f"--push must be a force >= 0 N, got {push}")
    params = preset(o.preset)
    if o.law:
        params = replace(params, law=o.law)
    if o.feedforward:
        params = replace(params, feedforward=o.feedforward == "on")
    model = cast(SerialChain, load_robot(o.robot))  # an arm's name: the thesis line's arm
    return thesis_line_figures(model, backend_factory, params, controller=o.controller,
                               push_n=push, realtime=o.backend != "sim", keep=keep)


def _line_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    n = len(result["max_angle_error_deg"])
    return [{"joint": j, "controller": result["controller"],
             "max_angle_error_deg": result["max_angle_error_deg"][j],
             "max_angle_error_pushed_deg": result["max_angle_error_pushed_deg"][j],
             "torque_error_max_nm": result["torque_error_max_nm"][j],
             "max_yield_deg": result["max_yield_deg"][j]} for j in range(n)]


@dataclass(frozen=True)
class StepOptions:
    """Options of ``step`` (see :func:`armlab.control.response.step_report`)."""

    kp: float = option(3.8, "Kp, 1/s² (default: thesis 3.8)")
    kv: float = option(0.2, "Kv, 1/s (default: thesis 0.2)")
    period: float = option(1e-3, "integration period of the simulated loop, s (default 0.001)")


def _step_run(options: StepOptions, *, keep: Keep | None = None) -> dict[str, Any]:
    o = options
    if not (np.isfinite(o.period) and 0 < o.period <= 0.05):
        raise ValueError(f"--period must be in (0, 0.05] s, got {o.period}")
    report = step_report(o.kp, o.kv, period=o.period)
    if keep is not None:
        # the ideal joint's step step_report measured (the same call, deterministic)
        t, y = simulate_ideal_joint_step(o.kp, o.kv, period=o.period)
        keep(Run(robot="ideal_joint", joint_names=("joint",), source="experiment:step",
                 lab_version=lab_version(), created=utc_now(),
                 params={"kp": o.kp, "kv": o.kv, "period": o.period},
                 commands=({"t": 0.0, "kind": "Step", "q_cmd_rad": 1.0},), figures={},
                 t=t, signals={"q_cmd": np.ones((len(t), 1)), "q": y[:, None],
                               "error": (1.0 - y)[:, None]}))
    return report


def _step_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    return [{"metric": k, "formula": result["formula"][k], "measured": result["measured"][k],
             "measured_eq_2_3": result["measured_eq_2_3"][k]} for k in result["formula"]]


EXPERIMENTS = (
    Experiment("thesis-line", "thesis ch. 4: the 20 cm line with no controller, PD or "
               "compliance; angle error, torque error and yield under a push",
               LineOptions, _line_run, _line_rows, needs=("backend_factory",)),
    Experiment("step", "step response of the PD loop: eq. 2.16–2.19 vs measured "
               "(ideal joint and eq. 2.3)", StepOptions, _step_run, _step_rows),
)
