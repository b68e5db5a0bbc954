"""Controller parameters: the gains a student moves with the sliders, checked and preset.

A :class:`Params` is frozen and validated when built, so the control loop can
swap a whole object at a period boundary and never sees half an update or a NaN.

Units (joint space, SI): Kp in 1/s², Kv in 1/s (eq. 2.20 gives an acceleration
per rad of error); the virtual environment of eq. 2.7 has M_env in N·m·s²/rad,
D_env in N·m·s/rad, K_env in N·m/rad and K_f dimensionless, so that its static
gain C_f = K_f / K_env is in rad per N·m of external torque.

The thesis's own laws differ in where K_env, D_env, M_env act: law "2.6" (the
default) offsets the reference by θ_env itself, so a steady external torque τ
moves the arm by C_f·τ; the thesis-literal law "2.26" multiplies the offsets by
K_env, D_env, M_env again, so the same τ moves it by K_f·τ. Chapter 4 of the
thesis prints and runs law 2.26 with Table 4.1, which is why the two thesis
presets select it. With law 2.6 the static offset θ_env of those numbers is
K_env = 12x smaller, but that holds for the offset only: on the simulated
chapter-4 push (3 N) the arm's yield drops from 18.8° to 9.4°, 2x, because with
Kp 3.8 the PD loop alone already gives way 10.0° (docs/compliance.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np

from armlab.control.laws import LAWS as _REGISTRY
from armlab.control.metrics import overshoot_pct, pd_damping
from armlab.kinematics.validate import scalar

Law = Literal["2.6", "2.26"]
LAWS: tuple[str, ...] = tuple(_REGISTRY)  #: the keys of the laws (armlab.control.laws)


@dataclass(frozen=True)
class ParamSpec:
    """How a UI slider shows one parameter; ``min``/``max`` are also the valid range."""

    min: float
    max: float
    step: float
    unit: str
    label: str
    help: str


#: name -> slider description (the numeric fields of :class:`Params`).
PARAM_SPECS: dict[str, ParamSpec] = {
    "kp": ParamSpec(0.0, 200.0, 0.1, "1/s²", "Kp",
                    "position gain of the PD reference loop (eq. 2.20); ωp = √Kp"),
    "kv": ParamSpec(0.0, 50.0, 0.01, "1/s", "Kv",
                    "velocity gain of the PD reference loop (eq. 2.20); ζp = Kv / (2√Kp)"),
    "m_env": ParamSpec(0.01, 20.0, 0.01, "N·m·s²/rad", "M_env",
                       "virtual mass of the environment (eq. 2.7); must be > 0"),
    "d_env": ParamSpec(0.0, 100.0, 0.1, "N·m·s/rad", "D_env",
                       "virtual damping of the environment (eq. 2.7)"),
    "k_env": ParamSpec(0.1, 100.0, 0.1, "N·m/rad", "K_env",
                       "virtual stiffness of the environment (eq. 2.7)"),
    "k_f": ParamSpec(0.0, 10.0, 0.01, "", "K_f",
                     "force gain (eq. 2.7); a steady torque τ moves the arm by K_f·τ/K_env"),
    "alpha": ParamSpec(0.005, 1.0, 0.005, "", "α (LPF)",
                       "low-pass filter on the servo load: y += α(x − y); small = smooth, slow"),
    "period": ParamSpec(0.001, 0.050, 0.001, "s", "period",
                        "control period (thesis: 16 ms in chapter 4, 20 ms timer in §2.5)"),
}


@dataclass(frozen=True)
class Params:
    """Gains of the PD/compliance controller (thesis eq. 2.6, 2.7, 2.20, 2.26).

    Attributes:
        kp: Kp, 1/s².
        kv: Kv, 1/s.
        m_env: M_env > 0, N·m·s²/rad.
        d_env: D_env >= 0, N·m·s/rad.
        k_env: K_env > 0, N·m/rad.
        k_f: K_f >= 0 (dimensionless).
        alpha: LPF coefficient on the load torque, (0, 1] (thesis uses 0.05).
        period: control period, s, 0.001..0.050 (thesis: 0.016).
        compliance: False turns the environment term off (the compliance
            controller then acts as the plain PD loop).
        law: "2.6" (consistent form, default) or "2.26" (thesis-literal).
        feedforward: add the commanded acceleration θ̈_cmd to θ̈_ref. Not in the
            thesis (its reference model 2.3 lags a moving command); with it the
            reference follows the RMRC trajectory exactly on an ideal joint and the
            feedback only corrects what the servos miss. Off in the thesis presets.

    Raises:
        ValueError: naming the field when a value is non-finite or out of range.
    """

    kp: float = 20.0
    kv: float = 5.0
    m_env: float = 1.0
    d_env: float = 6.4
    k_env: float = 16.0
    k_f: float = 4.0
    alpha: float = 0.05
    period: float = 0.016
    compliance: bool = True
    law: Law = "2.6"
    feedforward: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name not in PARAM_SPECS:
                continue
            x = scalar(f.name, getattr(self, f.name))
            spec = PARAM_SPECS[f.name]
            if f.name == "m_env" and x <= 0.0:
                raise ValueError(f"m_env must be > 0 (virtual mass of eq. 2.7), got {x:g}")
            if not spec.min <= x <= spec.max:
                raise ValueError(
                    f"{f.name} must be in [{spec.min:g}, {spec.max:g}] {spec.unit}, got {x:g}"
                )
            object.__setattr__(self, f.name, x)
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {', '.join(LAWS)}, got {self.law!r}")
        for name in ("compliance", "feedforward"):
            value = getattr(self, name)
            if not isinstance(value, bool | np.bool_):
                raise ValueError(f"{name} must be True or False, got {value!r}")
            object.__setattr__(self, name, bool(value))

    def as_dict(self) -> dict[str, float | bool | str]:
        """Every field by name (for CSV headers and JSON)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


#: the numeric fields of :class:`Params`, in their order
GAINS: tuple[str, ...] = tuple(PARAM_SPECS)


@dataclass(frozen=True)
class ParamColumns:
    """The parameters of K arms stepped as one (:class:`~armlab.control.law_batch.LawBatch`):
    each numeric field of :class:`Params` a (K, 1) column of their values, so that an
    equation written for one arm's (n,) arrays broadcasts over their (K, n) rows; the
    choices (``compliance``, ``law``, ``feedforward``) are the K arms' one choice. The
    numeric fields come first, in :data:`GAINS`' order."""

    kp: np.ndarray
    kv: np.ndarray
    m_env: np.ndarray
    d_env: np.ndarray
    k_env: np.ndarray
    k_f: np.ndarray
    alpha: np.ndarray
    period: np.ndarray
    compliance: bool
    law: Law
    feedforward: bool


#: The well-damped default, designed with eq. 2.11–2.19 and the servos' own lag:
#:   PD loop  Kp 20, Kv 5 -> ωp = 4.5 rad/s, ζp = 0.56: %OS 12 %, Tp 0.85 s, Ts 1.6 s;
#:            ωp·T = 0.07 at 16 ms. Kv is what excites the servos' own position loop
#:            (≈18 rad/s, ζ ≈ 0.25 with the arm stretched out): Kv 5 keeps the loop
#:            closed through them damped (ζ ≈ 0.11 there; Kp 36, Kv 10 oscillates).
#:            With feedforward of θ̈_cmd the reference follows the RMRC line itself.
#:   environment M 1, D 6.4, K 16 -> ωf = 4 rad/s, ζf = 0.8: a push is followed
#:            without ringing, no faster than the PD loop (ωf <= ωp) so the arm can
#:            follow the yielding reference; K_f 4 -> C_f = 0.25 rad/(N·m): a steady
#:            1 N·m (4 N at the hand) offsets the reference by 14°. On the chapter-4
#:            push (3 N) servo 3 then falls 16.2° behind its command (the thesis's
#:            metric; it reports "over 15°"), a yield of 11.4° from the free run.
DEFAULT = Params()

PRESETS: dict[str, Params] = {
    "well-damped default": DEFAULT,
    "thesis Table 4.1": Params(kp=3.8, kv=0.2, k_f=0.3, k_env=12.0, d_env=5.0, m_env=1.0,
                               law="2.26", feedforward=False),
    "thesis conclusion": Params(kp=3.8, kv=0.02, k_f=0.2, k_env=9.0, d_env=5.0, m_env=9.0,
                                law="2.26", feedforward=False),
}


def preset(name: str) -> Params:
    """The preset called ``name``; ValueError listing the known names otherwise."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(
            f"unknown preset {name!r}; known: {', '.join(repr(k) for k in PRESETS)}"
        ) from None


#: The servos' own position loop seen from the controller, as a second-order lag
#: ωs²/(s² + 2ζs ωs s + ωs²), for the RX-24F with the thesis's compliance slope 64
#: (≈7.7 N·m/rad) moving the stretched-out receptionist arm (≈0.024 kg·m² with the
#: rotor), its slowest case; back-EMF damping 2.6 N·m / 13.2 rad/s gives ζs ≈ 0.25.
#: (On the chapter-4 line a small goal step peaks after 0.07–0.12 s: ωs ≈ 25–45.)
#: Used only to warn, never to refuse (see :func:`check_gains`).
SERVO_OMEGA = 18.0  #: rad/s
SERVO_ZETA = 0.25


@dataclass(frozen=True)
class LoopStability:
    """Poles of the discrete loops at the control period (see :func:`loop_stability`).

    Attributes:
        radius: spectral radius of the PD reference loop on an ideal joint (>= 1: unstable).
        zeta: damping ratio of its dominant pole (continuous equivalent).
        omega: natural frequency of that pole, rad/s.
        env_radius, env_zeta, env_omega: the same for the environment filter (2.7).
    """

    radius: float
    zeta: float
    omega: float
    env_radius: float
    env_zeta: float
    env_omega: float
    servo_zeta: float = 1.0
    servo_omega: float = 0.0

    @property
    def unstable(self) -> bool:
        return self.radius >= 1.0 - 1e-12 or self.env_radius >= 1.0 - 1e-12


def integrated_pd_matrix(kp: float, kv: float, period: float) -> np.ndarray:
    """(2, 2) state map of the integrated PD loop on an ideal joint, state (θ, θ̇).

    The controller computes θ̈_ref = −Kp θ − Kv θ̇ (eq. 2.20 with θ_cmd = 0) and
    integrates it semi-implicitly (θ̇ += T θ̈, then θ += T θ̇); the ideal servo
    reaches the goal within the period, so the next measurement is the reference.
    """
    T = period
    return np.array([[1.0 - T * T * kp, T * (1.0 - T * kv)],
                     [-T * kp, 1.0 - T * kv]])


def _dominant(A: np.ndarray, period: float) -> tuple[float, float, float]:
    z = np.linalg.eigvals(A)
    radius = float(np.max(np.abs(z)))
    zd = z[np.argmax(np.abs(z))]
    if abs(zd) < 1e-300:
        return radius, 1.0, math.inf
    s = np.log(complex(zd)) / period
    omega = abs(s)
    zeta = -s.real / omega if omega > 0 else 1.0
    return radius, float(zeta), float(omega)


def loop_stability(params: Params) -> LoopStability:
    """Poles of the integrated PD loop and of the environment filter at ``params.period``.

    Both are second-order systems integrated once per period by the same
    semi-implicit Euler step the controller uses, so a radius >= 1 means the
    sampled loop diverges even on an ideal servo.
    """
    r, z, w = _dominant(integrated_pd_matrix(params.kp, params.kv, params.period), params.period)
    A_env = integrated_pd_matrix(params.k_env / params.m_env, params.d_env / params.m_env,
                                 params.period)
    er, ez, ew = _dominant(A_env, params.period)
    sz, sw = servo_loop_pole(params.kp, params.kv, params.period)
    return LoopStability(r, z, w, er, ez, ew, sz, sw)


def servo_loop_pole(kp: float, kv: float, period: float, *, omega_s: float = SERVO_OMEGA,
                    zeta_s: float = SERVO_ZETA) -> tuple[float, float]:
    """Least-damped pole of the PD loop closed through the servos' own lag.

    Loop: (Kv s + Kp)/s² (eq. 2.20 integrated twice) · servo lag ωs²/(s² + 2ζs ωs s + ωs²)
    · one period of delay (first-order Padé). Continuous-time estimate.

    Returns:
        (ζ, ω): damping ratio (< 0: the loop oscillates and grows) and rad/s of that pole.
    """
    T = period
    plant = np.polymul([1.0, 0.0, 0.0], [1.0, 2.0 * zeta_s * omega_s, omega_s * omega_s])
    char = np.polyadd(np.polymul(plant, [T / 2.0, 1.0]),
                      np.polymul(np.array([kv, kp]) * omega_s * omega_s, [-T / 2.0, 1.0]))
    roots = np.roots(char)
    roots = roots[np.abs(roots) > 1e-9]
    if len(roots) == 0:
        return 1.0, 0.0
    zetas = -roots.real / np.abs(roots)
    i = int(np.argmin(zetas))
    return float(zetas[i]), float(abs(roots[i]))


def _settles(kp: float, kv: float, period: float) -> bool:
    """Whether the integrated PD loop settles at ``period`` on an ideal joint and, closed
    through the servos' own lag, keeps some damping (ζ > 0.1)."""
    radius = _dominant(integrated_pd_matrix(kp, kv, period), period)[0]
    return radius < 0.999 and servo_loop_pole(kp, kv, period)[0] > 0.1


def stabilising_fix(params: Params) -> str:
    """What to change so that diverging gains settle, worked out for these gains: Kv for
    ζp = 0.7 at this Kp when that settles, else the largest Kp (in steps of 20 %) that
    settles with its own ζp = 0.7 Kv, else a shorter period."""
    kp, kv, T = params.kp, params.kv, params.period
    kv_good = 2.0 * 0.7 * math.sqrt(max(kp, 0.0))
    if kp > 0.0 and _settles(kp, kv_good, T):
        return (f"{'raise' if kv_good > kv else 'lower'} Kv to about {kv_good:.2g} "
                "(ζp = 0.7)")
    k = kp
    for _ in range(40):
        k *= 0.8
        if _settles(k, 2.0 * 0.7 * math.sqrt(k), T):
            return (f"lower Kp to about {k:.2g} with Kv about "
                    f"{2.0 * 0.7 * math.sqrt(k):.2g} (ζp = 0.7)")
    return f"shorten the period below {T * 1e3:g} ms"


def _warning(params: Params, st: LoopStability) -> str | None:
    """A sentence for the student when the gains are unstable, badly damped or too fast.

    Reads the poles ``st`` of the discrete-time integrated PD loop (and, with
    compliance on, of the environment filter) at the sample period; None when all is well.
    """
    T = params.period
    msgs: list[str] = []
    if st.radius >= 1.0 - 1e-12:
        cause = "Kv = 0: nothing damps it, " if params.kv == 0.0 else ""
        msgs.append(f"the PD loop diverges at T = {T * 1e3:g} ms ({cause}pole radius "
                    f"{st.radius:.4f}: at 1 or more the sampled loop never settles); "
                    f"{stabilising_fix(params)}")
    elif params.kp == 0.0:
        msgs.append("Kp = 0: no position feedback, the arm drifts")
    else:
        if st.zeta < 0.2:
            zp = pd_damping(params.kp, params.kv)
            os_pct = overshoot_pct(zp)
            msgs.append(f"badly damped: ζp = {zp:.2f} (overshoot {os_pct:.0f} %); "
                        f"raise Kv towards {1.4 * math.sqrt(params.kp):.2g}")
        if st.omega * T > 0.6:
            msgs.append(f"too fast for the period: ωp·T = {st.omega * T:.2f} "
                        "(under 10 samples per oscillation); lower Kp or the period")
        if st.servo_zeta < 0.0:
            fix = "raise Kv" if st.servo_omega < SERVO_OMEGA / 3 else "lower Kv and Kp"
            msgs.append(f"likely unstable on the servos: with their own lag (≈{SERVO_OMEGA:g} "
                        f"rad/s) and one period of delay the loop grows at "
                        f"{st.servo_omega:.1f} rad/s; {fix}")
        elif st.servo_zeta < 0.1 and st.zeta >= 0.2:
            msgs.append(f"lightly damped on the servos (ζ ≈ {st.servo_zeta:.2f} at "
                        f"{st.servo_omega:.1f} rad/s); lower Kv or Kp")
    if params.compliance:
        if st.env_radius >= 1.0 - 1e-12:
            msgs.append(f"the environment filter (2.7) diverges at T = {T * 1e3:g} ms; "
                        "raise M_env or lower D_env, K_env")
        else:
            if st.env_zeta < 0.2:
                msgs.append(f"environment badly damped: ζf = {st.env_zeta:.2f}; raise D_env")
            if st.env_omega * T > 0.6:
                msgs.append(f"environment too fast for the period: ωf·T = "
                            f"{st.env_omega * T:.2f}; raise M_env")
    return "; ".join(msgs) if msgs else None


#: The start of the message a person sees when :func:`check_gains` refuses gains.
REFUSED_ON_SERVOS = "unstable gains are refused on real servos"


@dataclass(frozen=True)
class GainCheck:
    """What :func:`check_gains` found in parameters it let through.

    Attributes:
        params: the parameters checked.
        stability: the poles of their loops at their period (what the verdict rests on).
        warning: a sentence for the student when the gains are unstable, badly damped or
            too fast for the period or the servos; None when all is well.
    """

    params: Params
    stability: LoopStability
    warning: str | None

    @property
    def unstable(self) -> bool:
        """The sampled loop diverges even on an ideal servo (taken on a simulated arm only)."""
        return self.stability.unstable


def check_gains(params: Params, *, servos: bool) -> GainCheck:
    """The lab's one rule on gains: whether ``params`` may drive the arm, and what to say.

    The poles of the integrated PD loop and of the environment filter at the period
    (:func:`loop_stability`) are computed once; a radius >= 1 (the sampled loop
    diverges even on an ideal servo) is refused on real (or emulated) ``servos``
    and taken on a simulated arm, to be seen failing (the control loop's run-time
    checks then stop it). Badly damped, too fast, or likely unstable through the
    servos' own lag: taken, with a warning.

    Raises:
        ValueError: not a :class:`Params`; or unstable gains on ``servos``, the one
            message a person sees: "unstable gains are refused on real servos: <why>".
    """
    if not isinstance(params, Params):
        raise ValueError(f"params must be a armlab.control.params.Params, got "
                         f"{type(params).__name__}")
    st = loop_stability(params)
    warning = _warning(params, st)
    if servos and st.unstable:
        raise ValueError(f"{REFUSED_ON_SERVOS}: {warning}")
    return GainCheck(params, st, warning)
