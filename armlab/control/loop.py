"""The control loop: one period = read the servos, run the controller, write goals, record.

``ControlLoop`` runs at the fixed period ``params.period`` either in its own
thread paced by the wall clock (``start()`` / ``shutdown()``), on a
:class:`~armlab.control.periodic.SharedClock` with other loops and the world it steps
(``clock=``; a class's private arms), or stepped as fast as possible by the caller
(``step()``, ``run_for(seconds)``) for headless runs and tests. Backend time is
the loop's own clock k·T, so a simulated arm gives the same numbers paced or not. On a
shared clock, a period running the lab's own law waits at it for the clock's
:class:`~armlab.control.law_batch.LawBatch`, which computes the law of every period due
at the tick as one, with the same numbers.

One writer per piece of state: only the loop touches the backend and the
controller. Other threads

* replace the parameters (``set_params``, which applies the lab's one rule on gains,
  :func:`~armlab.control.params.check_gains`; swapped at the next period boundary),
* post commands (``post``; applied at the next period, in order),
* read ``status`` (a frozen snapshot) and ``recorder.snapshot()``.

Safety: every goal is clamped into the joint limits (model and backend) and
every speed into the joint's speed limit before ``write``. A non-finite value,
a reference acceleration beyond ``max_accel`` or a reference speed at the
servo's limit (gains unstable for this arm and period), a joint lagging its
reference by more than ``max_lag`` for ``lag_time`` (blocked, or an oscillation
growing), a servo error or a ``BackendError`` stops the controller: torque goes
off (``backend.estop()``), ``status.fault`` says why, nothing escapes the
thread; ``Reset`` starts again from where the arm is. A lost link (a
``BackendError``) is retried once a second on a backend that can reconnect
(:class:`~armlab.control.backend.Reconnectable`), or at once on ``Reconnect``; the link
found again is configured and left torque-off until ``Reset``.
"""

from __future__ import annotations

import math
import queue
import sys
import threading
import time
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np

from armlab.control.backend import (
    Backend,
    BackendError,
    GripperState,
    Gripping,
    JointState,
    Pushable,
    Reconnectable,
    Touchable,
    WallSetting,
)
from armlab.control.commands import (
    COMMANDS,
    Command,
    EStop,
    Push,
    Reconnect,
    Reset,
    RunTrajectory,
    SetController,
    SetGripper,
    SetTarget,
    SetVirtualWall,
    Spring,
    Stop,
    UseSpareJoints,
)
from armlab.control.compliance import MODES, ComplianceController, ControllerState, Laws, Mode
from armlab.control.law_batch import LawAnswer, LawAsk, LawBatch
from armlab.control.params import DEFAULT, GainCheck, Params, check_gains
from armlab.control.periodic import SPIN_S, DrivenPacer, Pacer, SharedClock
from armlab.control.recorder import Recorder
from armlab.control.trajectory import JointTrajectory, approach_duration, minimum_jerk
from armlab.control.virtual_wall import rendered_wall
from armlab.kinematics.dynamics import dynamics_model
from armlab.kinematics.ik import rmrc
from armlab.kinematics.model import SerialChain
from armlab.kinematics.redundancy import POSITION_ROWS, aim_gradient, null_space_rate, task_jacobian
from armlab.kinematics.smallarrays import all_finite, clamp
from armlab.kinematics.validate import scalar

DEFAULT_MAX_SPEED = 10.0  #: rad/s when the model gives no velocity limit
TARGET_SPEED = 0.156  #: m/s hand speed when following a target (thesis: 2.5 mm / 16 ms)
SWITCH_INTERVAL = 0.001  #: s, the interpreter's thread switch interval while paced
APPROACH_MIN = 0.01  #: rad; a trajectory starting farther than this from the command is approached
#: N: a virtual wall is not set where it would push the hand harder than this at once
#: (the Contact tab's own limit for placing a wall)
VIRTUAL_WALL_SET_MAX_N = 5.0
#: rad/s, the fastest joint of the spare joints' self-motion (``UseSpareJoints``)
SPARE_MAX_SPEED = 0.5
#: rad/s, the fastest joint while the hand follows a target: near a singularity or a joint
#: limit one RMRC step of 2.5 mm may ask for 10 rad/s (the SO-101 resting folded on its
#: shoulder's limit, as a serial arm is caught), which the reference-acceleration check
#: takes for unstable gains and switches the torque off
TARGET_MAX_JOINT_SPEED = 1.5
#: rad/s: an arm faster than this on any joint when its torque goes on (a limp arm still
#: falling, a hand still moving it) is caught first (:meth:`ControlLoop._catch`)
CATCH_SPEED = 0.2
#: s, the longest catch: an arm still moving after it (a person moving it by hand) gets
#: the controller from where it is then
CATCH_MAX = 1.5


@dataclass(frozen=True)
class LoopStatus:
    """A snapshot of the loop for the UI (all times in s unless the name says ms).

    Attributes:
        running: the loop thread is alive (always False when stepped headless).
        active: the controller is writing goals (False after a fault, e-stop, before start).
        torque_on: the loop last switched the servos' torque on.
        estopped: an e-stop is in force (until Reset).
        fault: why the controller stopped, or None.
        message: the latest note for a person (a refused push, an unreachable target...).
        t: loop time.
        steps: periods run.
        controller: "none", "pd" or "compliance" (the mode asked for).
        trajectory: name of the trajectory playing, or None.
        progress: 0..1 through it.
        period_ms: the nominal period.
        period_mean_ms: mean measured period (paced runs; None headless).
        jitter_p50_ms, jitter_p99_ms, jitter_max_ms: lateness of period starts
            over the last 1000 periods (paced runs; None headless).
        overruns: period starts so late that periods were skipped.
        skipped, skipped_recent: periods skipped (wall time dropped rather than run in a
            burst), in all and in the last 10 s.
        torque_off_unsent: the last torque-off (E-STOP, fault) could not be sent: the
            servos may still hold torque (retried once a second until it goes out).
        link_down: the backend's link failed and is not back (retried once a second on a
            backend that can reconnect); Reset and Run do nothing until it is.
        held_off: why the loop keeps the torque off until a person's Reset (an arm whose
            joint map is not calibrated: its angles may not be the model's), or None.
        catching: the arm was moving when its torque went on and the servos are holding
            it where it was until it comes to rest; the controller starts from there.
    """

    running: bool
    active: bool
    torque_on: bool
    estopped: bool
    fault: str | None
    message: str
    t: float
    steps: int
    controller: str
    trajectory: str | None
    progress: float
    period_ms: float
    period_mean_ms: float | None
    jitter_p50_ms: float | None
    jitter_p99_ms: float | None
    jitter_max_ms: float | None
    overruns: int
    skipped: int = 0
    skipped_recent: int = 0
    torque_off_unsent: bool = False
    link_down: bool = False
    held_off: str | None = None
    catching: bool = False


class _Fault(Exception):
    """Raised inside a period to stop the controller with a message."""


class ControlLoop:
    """Fixed-period loop running a :class:`ComplianceController` on any :class:`Backend`.

    Args:
        model: the arm (joint order = backend order).
        backend: the servos (simulated or real).
        params: controller parameters (default: the well-damped preset), held to
            :func:`~armlab.control.params.check_gains` as :meth:`set_params` holds a change.
        controller: "none", "pd" or "compliance".
        realtime: ``start()`` paces periods by the wall clock; False runs them back to back.
        history_s: seconds of signals the recorder keeps.
        max_accel: rad/s²; a larger reference acceleration is a fault (unstable gains).
        max_lag, lag_time: a joint farther than ``max_lag`` rad from its reference for
            ``lag_time`` s is a fault (blocked, overloaded, or an oscillation growing).
        target_speed: m/s, hand speed when following a ``SetTarget``.
        clock: run the periods on this :class:`SharedClock` (with other loops and the world
            it steps) instead of a thread of the loop's own; ``start``/``shutdown`` attach
            and detach the loop. The backend's ``sync`` then finds its world already at
            the loop's time (e.g.
            ``armlab.hardware.families.dynamixel1.batched_backend.BatchedArmBackend``).
        laws: the controller's equations (default: the lab's own; coursework runs a
            student's in their place, :class:`~armlab.control.compliance.Laws`).
        hold_off: keep the torque off from the start, watching the arm and commanding
            nothing, until a person's Reset; the text says why (shown in the status).
    """

    def __init__(self, model: SerialChain, backend: Backend, params: Params | None = None, *,
                 controller: Mode = "compliance", realtime: bool = True,
                 history_s: float = 20.0, max_accel: float = 500.0, max_lag: float = 0.5,
                 lag_time: float = 0.5, target_speed: float = TARGET_SPEED,
                 clock: SharedClock | None = None, laws: Laws | None = None,
                 hold_off: str | None = None) -> None:
        if not isinstance(backend, Backend):
            raise ValueError(f"backend must implement armlab.control.backend.Backend, got "
                             f"{type(backend).__name__}")
        if backend.n != model.n:
            raise ValueError(f"backend has {backend.n} joints but the model {model.name!r} "
                             f"has {model.n}")
        #: real (or emulated) servos: nothing but a simulated arm can be pushed by the lab
        self.servos = not isinstance(backend, Pushable)
        gains = check_gains(DEFAULT if params is None else params, servos=self.servos)
        params = gains.params
        if controller not in MODES:
            raise ValueError(f"controller must be one of {', '.join(MODES)}, got {controller!r}")
        scalar("history_s", history_s, positive=True)
        self.model = model
        self.backend = backend
        self.realtime = realtime
        self.history_s = float(history_s)
        self.max_accel = float(max_accel)
        self.max_lag = float(max_lag)
        self.lag_time = float(lag_time)
        self._lag_time = 0.0
        self.target_speed = float(target_speed)
        self.lower = np.maximum(model.lower, np.asarray(backend.lower, dtype=float))
        self.upper = np.minimum(model.upper, np.asarray(backend.upper, dtype=float))
        vel = np.array([j.velocity for j in model.joints], dtype=float)
        self.max_speed = np.where(np.isfinite(vel) & (vel > 0), vel, DEFAULT_MAX_SPEED)
        self._fast_speed = self.max_speed * (1.0 - 1e-9)  # a reference this fast: a fault
        self.controller = ComplianceController(self.lower, self.upper, self.max_speed,
                                               mode=controller, laws=laws)
        self._rnea = dynamics_model(model).rnea
        self._gravity = np.asarray(model.gravity, dtype=float).tolist()
        self._params = params
        self._gains = gains
        self._pending: GainCheck | None = None
        self._commands: queue.SimpleQueue[Command] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self.recorder = Recorder(model.n, self._capacity(params.period),
                                 joint_names=model.joint_names)
        # loop-thread state
        self._k = 0
        self._t = 0.0
        self._state: ControllerState | None = None
        self._hold: np.ndarray | None = None
        self._qd_cmd_prev = np.zeros(model.n)
        self._traj: JointTrajectory | None = None
        self._traj_t0 = 0.0
        self._target: np.ndarray | None = None
        #: loop time a catch ends by (None: no catch), the motion commands it put off
        self._catch_end: float | None = None
        self._deferred: list[Command] = []
        self._spare: UseSpareJoints = UseSpareJoints("off")
        self._active = False
        self._torque_on = False
        self._estopped = False
        self._backend_ok = True
        self._fault: str | None = None
        self._torque_unsent = False  # the last torque-off could not be sent
        self._unsent_retry_t = 0.0
        self._reconnect_t = 0.0  # loop time of the next automatic reconnection attempt
        #: torque stays off until a Reset: a link found again, or ``hold_off``
        self._await_reset = hold_off is not None
        self._held_off = hold_off
        self._message = hold_off or ""
        self._gripper: GripperState | None = None  # the newest gripper reading
        #: the backend whose world may hold a wall: its contact force is recorded
        self._touch: Touchable | None = backend if isinstance(backend, Touchable) else None
        #: the wall the compliance law renders (SetVirtualWall), where the world has none
        self._virtual_wall: WallSetting | None = None
        #: on a shared clock: its batch, which computes the lab's own law of the periods
        #: due at one tick as one (a student's law runs in its own period)
        self._batch = None if clock is None else LawBatch.of(clock)
        self._laws_own = laws is None or laws == Laws()
        self._pacer: Pacer | DrivenPacer = (
            Pacer(self._tick, period=params.period, name="armlab-control", realtime=realtime,
                  spin_s=SPIN_S)  # a period's start within microseconds
            if clock is None else
            clock.pacer(self._clock_tick, period=params.period, name="armlab-control"))

    # ------------------------------------------------------------------ public API

    @property
    def params(self) -> Params:
        """The parameters in force (a pending swap shows after the next period)."""
        return self.gains.params

    @property
    def gains(self) -> GainCheck:
        """What :func:`~armlab.control.params.check_gains` said of the parameters in force
        (a pending swap included): their poles and the warning for a person."""
        with self._lock:
            return self._pending or self._gains

    def set_params(self, params: Params) -> GainCheck:
        """Use ``params`` from the next period boundary on, if the lab's one rule on gains
        (:func:`~armlab.control.params.check_gains`) takes them on this arm: unstable
        gains are refused on real servos and taken on a simulated arm (where the run-time
        checks stop it).

        Returns:
            The rule's verdict (its ``warning`` for a person, None when all is well).

        Raises:
            ValueError: not a Params, or refused (nothing changes then).
        """
        gains = check_gains(params, servos=self.servos)
        with self._lock:
            self._pending = gains
        return gains

    @property
    def spare_joints(self) -> UseSpareJoints:
        """What the spare joints aim for while the hand follows a target (the last
        ``UseSpareJoints`` applied; "off" at first)."""
        with self._lock:
            return self._spare

    def post(self, command: Command) -> None:
        """Queue ``command``; the loop applies it at the start of its next period."""
        if not isinstance(command, COMMANDS):
            raise ValueError(f"not a loop command: {type(command).__name__}")
        self._commands.put(command)

    @property
    def gripper(self) -> GripperState | None:
        """What the gripper's servo reported at the newest period (None: the arm has no
        gripper, or the loop has not read it yet). Safe from any thread."""
        return self._gripper

    @property
    def status(self) -> LoopStatus:
        """A consistent snapshot (cheap; safe from any thread)."""
        pace = self._pacer.stats()
        with self._lock:
            traj, progress = None, 0.0
            if self._traj is not None:
                traj = self._traj.name or "trajectory"
                d = self._traj.duration
                progress = 1.0 if d <= 0 else min(1.0, max(0.0, (self._t - self._traj_t0) / d))
            return LoopStatus(
                running=self._pacer.alive,
                active=self._active, torque_on=self._torque_on, estopped=self._estopped,
                fault=self._fault, message=self._message, t=self._t, steps=self._k,
                controller=self.controller.mode, trajectory=traj, progress=progress,
                period_ms=self._params.period * 1e3,
                period_mean_ms=pace.interval_mean_ms, jitter_p50_ms=pace.late_p50_ms,
                jitter_p99_ms=pace.late_p99_ms, jitter_max_ms=pace.late_max_ms,
                overruns=pace.overruns, skipped=pace.skipped,
                skipped_recent=pace.skipped_recent,
                torque_off_unsent=self._torque_unsent, link_down=not self._backend_ok,
                held_off=self._held_off,
                catching=self._catch_end is not None and self._active,
            )

    def step(self) -> None:
        """Run one period now (headless use; do not mix with a running thread)."""
        if self._pacer.alive:
            raise RuntimeError("the loop thread is running; post commands instead of step()")
        self._tick()

    def run_for(self, seconds: float) -> LoopStatus:
        """Run ``seconds`` of loop time headless (as fast as possible); stops at a fault."""
        end = self._t + float(seconds)
        while self._t + 0.5 * self.params.period <= end:
            self.step()
            if self._fault is not None:
                break
        return self.status

    def start(self) -> None:
        """Run the loop in its own daemon thread (paced when ``realtime``).

        A paced loop lowers the interpreter's thread switch interval to 1 ms
        (``sys.setswitchinterval``; the default 5 ms lets a busy UI thread hold the
        GIL for 5 ms while a period is due).
        """
        if self._pacer.alive:
            return
        if self.realtime:
            sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL))
        self._pacer.start()

    def shutdown(self, *, torque_off: bool = False, timeout: float = 2.0) -> None:
        """Stop the thread (finishing the current period); optionally switch torque off."""
        self._pacer.stop(timeout)
        if torque_off and self._backend_ok and self._safe_estop():
            self._torque_on = False

    # ------------------------------------------------------------------ one period

    def _tick(self) -> None:
        """One period, its law computed here."""
        try:
            self._drive(self._period(batched=False), None)
        finally:
            with self._lock:
                self._k += 1
                self._t += self._params.period

    def _clock_tick(self) -> None:
        """One period on a shared clock: one that runs the lab's own law waits for it in
        the clock's :class:`LawBatch`, which computes it with the other periods due at this
        tick and then lets the period finish (its checks, write and record)."""
        assert self._batch is not None
        self._batch.settle(self)  # a period of this loop still waiting: it finishes first
        try:
            self._drive(self._period(batched=self._laws_own), None)
        finally:
            with self._lock:
                self._k += 1
                self._t += self._params.period

    def _drive(self, period: Generator[LawAsk, LawAnswer | None, None],
               answer: LawAnswer | None) -> None:
        """Run ``period`` on (sent ``answer``: the batch's law, or None to compute its own)
        until it ends or waits for its law (then it joins the batch); a fault it raises
        stops the controller (torque off, the reason in ``status.fault``)."""
        try:
            ask = period.send(answer)
        except StopIteration:
            return
        except _Fault as exc:
            self._fail(str(exc))
        except BackendError as exc:
            self._backend_ok = False
            self._fail(f"backend error: {exc}")
        except ArithmeticError as exc:  # e.g. the simulated plant diverged
            self._fail(f"numerical failure ({exc}); torque off")
        except Exception as exc:  # keep the arm safe whatever went wrong in this period
            self._fail(f"internal error ({type(exc).__name__}: {exc}); torque off")
        else:
            assert self._batch is not None  # a period waits only when batched
            self._batch.add(self, period, ask)

    def _period(self, *, batched: bool) -> Generator[LawAsk, LawAnswer | None, None]:
        """One period's steps; ``batched``: it waits (``yield``) at its law for the clock's
        batch to send it (None from the batch: it computes its own)."""
        self._swap_params()
        cmds: list[Command] = []
        while not self._commands.empty():  # this thread is the only one taking
            cmds.append(self._commands.get_nowait())
        p, t = self._params, self._t
        if self._torque_unsent and t >= self._unsent_retry_t:  # the link may be back
            self._safe_estop()
        if not self._backend_ok and not self._link_back(t, cmds):
            return
        self.backend.sync(t)
        meas = self.backend.read()
        if meas.gripper is not None:
            self._gripper = meas.gripper
        contact = self._contact()
        q, qd, load = (np.asarray(meas.position, dtype=float),
                       np.asarray(meas.velocity, dtype=float), np.asarray(meas.load, dtype=float))
        tau_world = None
        if (self._virtual_wall is not None and not contact and all_finite(q, qd)
                and self.controller.effective_mode(p) == "compliance"):
            force, tau_world = rendered_wall(self.model, self._virtual_wall, q, qd)
            contact = {"f_contact": force, "f_contact_peak": force}
        reset = bool(cmds) and any(isinstance(c, Reset) for c in cmds)
        started = self._state is None or reset
        if self._state is None:
            if self._await_reset and not reset:  # watch the arm, command nothing
                self._record(t, q=q, load=load, error=np.full_like(q, np.nan), **contact)
                return
            self._await_reset = False
            with self._lock:
                self._held_off = None
            self._start(meas)
        for cmd in cmds:
            self._apply(cmd, meas)
        if not self._active:  # faulted or e-stopped: keep watching, write nothing
            self._record(t, q=q, load=load, error=np.full_like(q, np.nan), **contact)
            return
        if not all_finite(q, qd, load):
            for name, arr in (("position", q), ("velocity", qd), ("load", load)):
                if not all_finite(arr):
                    raise _Fault(f"the servos reported a non-finite {name} "
                                 f"({arr.tolist()}); torque off")
        bad = [(j, e) for j, e in enumerate(meas.errors) if e]
        if bad and not started:  # a Reset's torque-on clears them by the next reading
            j, e = bad[0]
            alarm = meas.alarms[j] if meas.alarms else f"its servo reports error bits {e:#04x}"
            raise _Fault(f"joint {self.model.joints[j].name}: {alarm}; torque off "
                         "(check load, temperature and supply, then Reset)")
        if self._catch_end is not None:
            if t < self._catch_end and max(np.abs(qd).tolist()) > CATCH_SPEED:
                self._catch(t, q, load, contact)
                return
            self._caught(meas)
        q_cmd, qd_cmd, qdd_cmd = self._command(t, p.period)
        st = self._state
        assert st is not None
        # τ_dyn, Newton–Euler of the measured motion (thesis eq. 2.41–2.50): the generated
        # code armlab.kinematics.dynamics.rnea runs, without its checks (q, qd, θ̈_ref are finite)
        tau_dyn = np.array(self._rnea(q.tolist(), qd.tolist(), st.qdd_ref.tolist(),
                                      self._gravity))
        answer: LawAnswer | None = None
        if batched and tau_world is None:
            answer = yield LawAsk(self.controller, p, st, q_cmd, qd_cmd, qdd_cmd, meas,
                                  tau_dyn)
        if answer is None:
            q_ref, qd_ref = self.controller.step(p, st, q_cmd, qd_cmd, qdd_cmd, meas, tau_dyn,
                                                 tau_world)
        else:
            q_ref, qd_ref = answer
        if not all_finite(q_ref, qd_ref, st.qdd_ref):
            raise _Fault("the controller produced a non-finite goal (unstable gains?); "
                         "torque off")
        # the checks below reduce with Python's max/any over tolist(): on a few joints
        # numpy's reductions cost more than the arithmetic (armlab.kinematics.smallarrays)
        if max(np.abs(st.qdd_ref).tolist()) > self.max_accel:
            worst = int(np.argmax(np.abs(st.qdd_ref)))
            raise _Fault(
                f"unstable: reference acceleration {st.qdd_ref[worst]:.0f} rad/s² on joint "
                f"{self.model.joints[worst].name} exceeds {self.max_accel:g} "
                f"(Kp {p.kp:g}, Kv {p.kv:g}, M_env {p.m_env:g}, D_env {p.d_env:g}, "
                f"K_env {p.k_env:g}, K_f {p.k_f:g} at {p.period * 1e3:g} ms); torque off")
        speed_ref = np.abs(qd_ref)
        fast = speed_ref >= self._fast_speed
        if any(fast.tolist()):
            j = int(np.argmax(fast))
            raise _Fault(f"unstable: the reference speed of joint {self.model.joints[j].name} "
                         f"reached the servo's limit ({self.max_speed[j]:.1f} rad/s); "
                         "torque off (lower the gains)")
        lag = np.abs(q_ref - q) > self.max_lag
        self._lag_time = self._lag_time + p.period if any(lag.tolist()) else 0.0
        if self._lag_time > self.lag_time:
            j = int(np.argmax(np.abs(q_ref - q)))
            raise _Fault(f"joint {self.model.joints[j].name} has been more than "
                         f"{np.degrees(self.max_lag):.0f}° from its reference for "
                         f"{self.lag_time:g} s (blocked, overloaded or oscillating); torque off")
        goal = clamp(q_ref, self.lower, self.upper)
        speed = np.minimum(speed_ref, self.max_speed)
        self.backend.write(goal, speed)
        self._record(t, q_cmd=q_cmd, q_ref=goal, q=q, error=q_cmd - q, qd_ref=qd_ref,
                     load=load, tau_load=st.tau_lpf, tau_dyn=tau_dyn, tau_ext=st.tau_ext,
                     q_env=st.q_env, **contact)

    def _link_back(self, t: float, cmds: list[Command]) -> bool:
        """With the link failed: try to get it back (a :class:`Reconnectable` backend once a
        second or on Reconnect; any other on Reset). True when this period may go on (only
        for a Reset: a link found again otherwise stays torque-off until one)."""
        reset = any(isinstance(c, Reset) for c in cmds)
        if any(isinstance(c, EStop) for c in cmds):  # still try, and say what came of it
            self._apply(EStop(), None)  # type: ignore[arg-type]  # an EStop needs no measured state
        if isinstance(self.backend, Reconnectable):
            asked = reset or any(isinstance(c, Reconnect) for c in cmds)
            if not (asked or t >= self._reconnect_t):
                return False
            self._reconnect_t = t + 1.0
            try:
                self.backend.reconnect()
            except BackendError as exc:
                if asked:
                    self._note(f"{'Reset' if reset else 'Reconnect'}: nothing happened, the "
                               f"link is still down ({exc}); the lab retries every second")
                return False
            self._safe_estop()  # torque off, and a pending unsent torque-off is now sent
            with self._lock:
                self._backend_ok, self._state, self._torque_on = True, None, False
                self._await_reset = True
                back = "link back: servos configured again, torque off; press Reset to hold the arm"
                lost = self._fault  # what failed (naming the servo), unless told already
                if lost and not lost.startswith("link back"):
                    back += f" (it was lost: {lost})"
                self._fault = self._message = back
            return reset
        if reset:  # e.g. a simulator's error: start again from its state
            with self._lock:
                self._backend_ok, self._state = True, None
            return True
        return False

    def _record(self, t: float, **signals: np.ndarray | float) -> None:
        self.recorder.append(t, signals, wall=time.time() if self._pacer.alive else math.nan)

    def _contact(self) -> dict[str, float]:
        """This period's contact signals (armlab.control.recorder's ``f_contact``, N, and
        ``f_contact_peak``, N, the largest at any plant step since the period before): the
        ground truth of a wall in a simulated arm's world, read after the backend's
        ``sync``; none (NaN in the record) without a wall, and on real servos."""
        touch = self._touch
        if touch is None or touch.wall_setting() is None:
            return {}
        return {"f_contact": touch.wall_force(), "f_contact_peak": touch.wall_peak()}

    def _swap_params(self) -> None:
        with self._lock:
            new, self._pending = self._pending, None
            if new is None:
                return
            old, self._params, self._gains = self._params, new.params, new
        if self._params.period != old.period:
            self.recorder.resize(self._capacity(self._params.period))
            self._pacer.period = self._params.period

    def _capacity(self, period: float) -> int:
        return max(2, int(math.ceil(self.history_s / period)) + 1)

    def _start(self, meas: JointState) -> None:
        """First period (or Reset): hold where the arm is, torque on. An arm still moving
        (faster than :data:`CATCH_SPEED`) is caught first (:meth:`_catch`)."""
        q = np.clip(np.asarray(meas.position, dtype=float), self.lower, self.upper)
        if not np.all(np.isfinite(q)):
            raise _Fault("the servos reported a non-finite position; torque off")
        self._rest_at(q, meas)
        self._traj = None
        self._target = None
        self._deferred = []
        speed = np.nan_to_num(np.abs(np.asarray(meas.velocity, dtype=float)))
        moving = max(speed.tolist()) > CATCH_SPEED
        self.backend.set_torque(True)
        with self._lock:
            self._catch_end = self._t + CATCH_MAX if moving else None
            self._torque_on = True
            self._active = True

    def _rest_at(self, q: np.ndarray, meas: JointState) -> None:
        """The controller's state at rest at ``q`` (n,), holding it."""
        self._state = ControllerState.at_rest(q, np.nan_to_num(np.asarray(meas.load, float)))
        self._lag_time = 0.0
        self._hold = q.copy()
        self._qd_cmd_prev = np.zeros(self.model.n)

    def _catch(self, t: float, q: np.ndarray, load: np.ndarray,
               contact: dict[str, float]) -> None:
        """One period of catching an arm that was moving when its torque went on: the
        servos' own position loops hold the goal where the arm was, until it comes to
        rest. The controller's reference is not run meanwhile: it is driven by the arm's
        measured error and speed (thesis eq. 2.20), so started on an arm moving at speed
        it would wind up past the arm and drive it the other way."""
        assert self._hold is not None
        self.backend.write(self._hold, self.max_speed)
        self._note("catching the arm: it was moving when its torque went on")
        self._record(t, q_cmd=self._hold, q_ref=self._hold, q=q, error=self._hold - q,
                     load=load, **contact)

    def _caught(self, meas: JointState) -> None:
        """The catch is over: the controller starts at rest where the arm is now, and the
        motion commands posted meanwhile run from there, in their order."""
        q = np.clip(np.asarray(meas.position, dtype=float), self.lower, self.upper)
        self._rest_at(q, meas)
        deferred, self._deferred = self._deferred, []
        with self._lock:
            self._catch_end = None
            self._message = "caught: holding the arm where it came to rest"
        for cmd in deferred:
            self._apply(cmd, meas)

    def _fail(self, why: str) -> None:
        sent = self._safe_estop()
        if not sent and not self._torque_on:
            why += "; the servos' torque was already off"
        with self._lock:
            if self._fault is None:
                self._fault = why
                self._message = why
            self._active = False
            self._torque_on = self._torque_on and not sent

    def _safe_estop(self) -> bool:
        """Torque off through the backend; False (and :attr:`LoopStatus.torque_off_unsent`)
        when it could not be sent. A later period tries again (once a second) until it
        goes out."""
        try:
            sent = self.backend.estop() is not False
        except Exception:  # estop must not raise; a raise is a torque-off not sent
            sent = False
        with self._lock:
            # unsent matters only while the servos may hold torque: with the torque
            # already off, a link that is down leaves nothing holding the arm
            self._torque_unsent = not sent and (self._torque_on or self._torque_unsent)
            self._unsent_retry_t = self._t + 1.0
        return sent

    def _note(self, msg: str) -> None:
        with self._lock:
            self._message = msg

    # ------------------------------------------------------------------ commands

    def _clear_fault(self) -> None:
        with self._lock:
            self._fault = None
            self._estopped = False
            self._message = "reset: holding the arm where it is"

    def _apply(self, cmd: Command, meas: JointState) -> None:
        if isinstance(cmd, Reset):
            self._clear_fault()
            self._start(meas)
            return
        if isinstance(cmd, EStop):
            sent = self._safe_estop()
            with self._lock:
                self._estopped = True
                self._active = False
                if sent:
                    self._message = "e-stop: torque off; Reset to go on"
                elif self._torque_on:
                    self._message = ("e-stop: torque off could not be sent; switch the servo "
                                     "power off")
                else:
                    self._message = ("e-stop: the link to the servos is down; their torque "
                                     "was already off")
                self._torque_on = not sent and self._torque_on
            return
        if isinstance(cmd, UseSpareJoints):
            self._use_spare_joints(cmd)
            return
        if isinstance(cmd, SetController):
            self.controller.mode = cmd.mode
            if self._state is not None:  # bumpless: go on from the current reference
                self._state.q_env[:] = self._state.qd_env[:] = self._state.qdd_env[:] = 0.0
            self._note(f"controller: {cmd.mode}")
            return
        if isinstance(cmd, Push | Spring):
            if not isinstance(self.backend, Pushable):
                self._note("this backend cannot be pushed: push the real arm by hand")
            elif isinstance(cmd, Push):
                self.backend.push(cmd.force, link=cmd.link, point=cmd.point,
                                  duration=cmd.duration)
            else:
                self.backend.set_spring(cmd.anchor, stiffness=cmd.stiffness, link=cmd.link,
                                        point=cmd.point)
            return
        if isinstance(cmd, SetGripper):
            self._grip(cmd.position)
            return
        if isinstance(cmd, SetVirtualWall):
            if cmd.wall is not None and meas is not None:
                inside = -float(np.dot(cmd.wall.normal, self.model.fk(
                    np.asarray(meas.position, dtype=float))[:3, 3] - cmd.wall.origin))
                # rendered now, a wall the hand is well inside would throw the arm out
                if inside * cmd.wall.stiffness > VIRTUAL_WALL_SET_MAX_N:
                    self._note(f"virtual wall not set: the hand is {inside * 100:.1f} cm "
                               "inside it; move the hand to its free side first")
                    return
            self._virtual_wall = cmd.wall
            if cmd.wall is None:
                self._note("virtual wall taken away")
            elif self._touch is not None and self._touch.wall_setting() is not None:
                self._note("the simulated world's own wall is touched, not the virtual one")
            else:
                self._note("virtual wall: the compliance law renders it (PD renders none)")
            return
        assert self._hold is not None
        if self._catch_end is not None:  # run once the arm is caught, from where it rests
            self._deferred.append(cmd)
            return
        current = self._current_cmd()
        if isinstance(cmd, Stop):
            self._hold, self._traj, self._target = current, None, None
            self._note("stopped: holding the command")
        elif isinstance(cmd, RunTrajectory):
            traj = cmd.trajectory
            if traj.n != self.model.n:
                self._note(f"trajectory has {traj.n} joints, the arm {self.model.n}; ignored")
                return
            if cmd.approach and np.max(np.abs(traj.q[0] - current)) > APPROACH_MIN:
                approach = minimum_jerk(current, traj.q[0],
                                        approach_duration(current, traj.q[0]))
                traj = approach.then(traj, name=traj.name)
            self._traj, self._traj_t0, self._target = traj, self._t, None
            self._note(f"running {traj.name or 'trajectory'} ({traj.duration:.2f} s)")
        elif isinstance(cmd, SetTarget):
            self._traj = None
            self._hold = current
            self._target = cmd.xyz
            if cmd.xyz is None:
                self._note("target released: holding")

    def _use_spare_joints(self, cmd: UseSpareJoints) -> None:
        if cmd.aim != "off" and self.model.n <= len(POSITION_ROWS):
            self._note(f"{self.model.n} joints have no spare joint for a hand position "
                       "(3 coordinates): nothing to aim for")
            return
        with self._lock:
            self._spare = cmd
        if cmd.aim == "off":
            self._note("spare joints: off")
            return
        if self._traj is None and self._target is None and self._hold is not None:
            self._target = self.model.fk(self._hold)[:3, 3]  # keep the hand where it is
        self._note(f"spare joints: {cmd.aim} (k_a {cmd.gain:g} 1/s) while the hand "
                   "follows its target")

    def _grip(self, position: float) -> None:
        """Hand a gripper goal (the finger joint's units: m, or rad for a jaw) to the
        backend, which sends it with the next goals."""
        if not (isinstance(self.backend, Gripping) and self.backend.gripper_range):
            self._note("this arm has no gripper servo")
        elif not self._active:
            self._note("gripper: the arm is stopped (E-STOP or a fault); Reset first")
        else:
            x = self.backend.set_gripper(position)
            clamped = " (clamped into its range)" if abs(x - position) > 1e-9 else ""
            where = (f"jaw to {math.degrees(x):+.1f}°" if self.backend.gripper_revolute
                     else f"finger to {x * 1e3:+.1f} mm")
            self._note(f"gripper: {where}{clamped}")

    def _current_cmd(self) -> np.ndarray:
        if self._traj is not None:
            return self._traj.sample(self._t - self._traj_t0)[0]
        assert self._hold is not None
        return self._hold.copy()

    def _command(self, t: float, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """θ_cmd, θ̇_cmd, θ̈_cmd for this period (trajectory, target or hold), in limits."""
        if self._traj is not None:
            q, qd, qdd = self._traj.sample(t - self._traj_t0)
            if t - self._traj_t0 >= self._traj.duration:
                self._hold, self._traj = q.copy(), None
                self._note("trajectory done: holding the last point")
        elif self._target is not None:
            q, qd, qdd = self._follow_target(period)
        else:
            assert self._hold is not None
            q, qd, qdd = self._hold.copy(), np.zeros(self.model.n), np.zeros(self.model.n)
        q = clamp(q, self.lower, self.upper)
        self._qd_cmd_prev = qd
        return q, qd, qdd

    def _follow_target(self, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One RMRC sample towards the target: dX limited to ``target_speed``·T (thesis §3.3),
        the joints' step scaled down so none turns faster than
        :data:`TARGET_MAX_JOINT_SPEED` (the direction is kept: the hand goes on towards the
        target, slower), then the spare joints' self-motion, if asked (:meth:`_spare_step`)."""
        assert self._hold is not None and self._target is not None
        q0 = self._hold
        x = self.model.fk(q0)[:3, 3]
        dx = self._target - x
        dist = float(np.linalg.norm(dx))
        reach = self.target_speed * period
        if dist > reach:
            dx *= reach / dist
        if dist < 1e-5:
            q1 = q0
        else:
            res = rmrc(self.model, x + dx, q0, restarts=0, max_iter=20)
            q1 = np.clip(res.q, self.lower, self.upper)
            if not res.reached:
                self._note(f"target out of reach: {res.message}")
            fastest = float(np.max(np.abs(q1 - q0))) / period
            if fastest > TARGET_MAX_JOINT_SPEED:
                q1 = q0 + (q1 - q0) * (TARGET_MAX_JOINT_SPEED / fastest)
        q1 = self._spare_step(q1, period)
        qd = (q1 - q0) / period
        qdd = (qd - self._qd_cmd_prev) / period
        self._hold = q1
        return q1.copy(), qd, qdd

    def _spare_step(self, q: np.ndarray, period: float) -> np.ndarray:
        """``q`` moved for one period along θ̇_NS = (I − J⁺J) k_a ∇H (seed 002 eq. 6 with the
        criterion of the ``UseSpareJoints`` in force), scaled down so no joint turns
        faster than :data:`SPARE_MAX_SPEED` (the direction, and so the null space, is
        kept); in the joint limits. The hand's position does not move to first order; the
        next period's RMRC takes back the second-order drift."""
        spare = self._spare
        if spare.aim == "off" or spare.gain == 0.0:
            return q
        J = task_jacobian(self.model, q, POSITION_ROWS)
        grad = aim_gradient(self.model, q, spare.aim, lower=self.lower, upper=self.upper)
        rate = null_space_rate(J, grad, spare.gain)
        fastest = float(np.max(np.abs(rate)))
        if fastest > SPARE_MAX_SPEED:
            rate *= SPARE_MAX_SPEED / fastest
        return np.clip(q + rate * period, self.lower, self.upper)
