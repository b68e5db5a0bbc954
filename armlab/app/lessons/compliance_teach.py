"""The teaching panel: the equations in use with live numbers, design figures vs measured.

Pure functions from (parameters, recorded signals) to Markdown, so the panel's
text can be tested without a browser. Design figures come from
:mod:`armlab.control.metrics` (thesis eq. 2.11–2.19); measured ones from the last
step (PD loop) or push (environment) the student ran, measured by
:mod:`armlab.control.response`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armlab.control import metrics
from armlab.control.laws import LAWS
from armlab.control.params import PRESETS, Params
from armlab.control.response import Measured
from armlab.kinematics.units import KGF_CM_PER_NM

DEG = 180.0 / math.pi


def people(x: float, digits: int = 3) -> str:
    """``x`` to ``digits`` significant digits as people write it: plain digits between
    0.001 and a million ("100", "0.25", "2.86"; never "1e+02"), else scientific."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    size = abs(x)
    if not 1e-3 <= size < 1e6:
        return f"{x:.{max(digits - 1, 0)}e}"
    places = max(0, digits - 1 - math.floor(math.log10(size)))
    text = f"{x:.{places}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def _f(x: float | None, digits: int = 3, unit: str = "") -> str:
    if x is None or not math.isfinite(x):
        return "—"
    return f"{people(x, digits)}{(' ' + unit) if unit else ''}"


def measured_line(m: Measured) -> str:
    """One line of what a step or push measured, shown beside the button that made it."""
    parts = [f"Tp {_f(m.peak_time_s, unit='s')}", f"%OS {_f(m.overshoot_pct, 2, '%')}",
             f"Ts {_f(m.settling_time_s, unit='s')}"]
    if m.static_gain is not None:
        parts.append(f"C_f {_f(m.static_gain, unit='rad/N·m')}")
    return f"**Measured** ({m.what}): " + ", ".join(parts) + " (Teach tab: beside the formulas)"


#: The mark of a measured figure whose gains are no longer those in use.
STALE = "⚠"
#: The gains each half of the table is measured with: a measured figure whose gains
#: differ from those in use is stale beside their design figures.
PD_GAINS = (("kp", "Kp"), ("kv", "Kv"), ("period", "T"))
ENV_GAINS = (("m_env", "M_env"), ("d_env", "D_env"), ("k_env", "K_env"), ("k_f", "K_f"),
             ("alpha", "α"), ("law", "law"), ("period", "T"))


def stale_gains(m: Measured | None, params: Params, names: tuple[tuple[str, str], ...]
                ) -> str | None:
    """The gains ``m`` was measured with, where they differ from ``params`` ("Kp 20, Kv 5"),
    or None (not stale, or not said)."""
    if m is None or m.params is None:
        return None
    was = [(label, getattr(m.params, key)) for key, label in names
           if getattr(m.params, key) != getattr(params, key)]

    def shown(label: str, v: str | float) -> str:
        if isinstance(v, str):
            return f"{label} {v}"
        return f"{label} {people(v * 1000)} ms" if label == "T" else f"{label} {people(v)}"

    return ", ".join(shown(label, v) for label, v in was) or None


def design_table(params: Params, pd: Measured | None, env: Measured | None, *,
                 servo_step_deg: float | None = None) -> str:
    """Markdown table: formula figures (2.11–2.19) beside the measured ones; a measured
    half marked stale when it was measured with other gains than ``params``, and the
    settling band stated beside the servo's position step (``servo_step_deg``) where a
    measured Ts is longer than the formula's."""
    wp = metrics.pd_natural_frequency(params.kp) if params.kp > 0 else float("nan")
    zp = metrics.pd_damping(params.kp, params.kv) if params.kp > 0 else float("nan")
    wf = metrics.env_natural_frequency(params.m_env, params.k_env)
    zf = metrics.env_damping(params.m_env, params.d_env, params.k_env)
    cf = metrics.static_gain(params.k_f, params.k_env)
    fp = metrics.formula_metrics(wp, zp) if params.kp > 0 else None
    fe = metrics.formula_metrics(wf, zf)
    pd_old = stale_gains(pd, params, PD_GAINS)
    env_old = stale_gains(env, params, ENV_GAINS)

    def row(name: str, formula: str, a: float | None, b: float | None, digits: int = 3,
            unit: str = "", old: str | None = None) -> str:
        got = _f(b, digits, unit)
        mark = f" {STALE}" if old and got != "—" else ""
        return f"| {name} | {formula} | {_f(a, digits, unit)} | {got}{mark} |"

    pd_m = pd or Measured("", None, None, None, None, None, None)
    env_m = env or Measured("", None, None, None, None, None, None)
    lines = [
        "| | formula | design | measured |",
        "|---|---|---|---|",
        f"| **PD loop** | | | {STALE + ' old gains' if pd_old else ''} |",
        row("ωp", "√Kp (2.11)", wp, pd_m.omega_n, unit="rad/s", old=pd_old),
        row("ζp", "Kv/(2√Kp) (2.12)", zp, pd_m.zeta, old=pd_old),
        row("Tp", "π/(ωp√(1−ζp²)) (2.16)", fp.peak_time_s if fp else None, pd_m.peak_time_s,
            unit="s", old=pd_old),
        row("%OS", "e^(−ζpπ/√(1−ζp²))·100 (2.17)", fp.overshoot_pct if fp else None,
            pd_m.overshoot_pct, 2, "%", old=pd_old),
        row("Ts", "4/(ζpωp) (2.18)", fp.settling_time_s if fp else None,
            pd_m.settling_time_s, unit="s", old=pd_old),
        row("Tr", "1.8/ωp (2.19)", fp.rise_time_s if fp else None, pd_m.rise_time_s,
            unit="s", old=pd_old),
        f"| **environment** | | | {STALE + ' old gains' if env_old else ''} |",
        row("ωf", "√(K_env/M_env) (2.13)", wf, env_m.omega_n, unit="rad/s", old=env_old),
        row("ζf", "D_env/(2√(M_env K_env)) (2.14)", zf, env_m.zeta, old=env_old),
        row("C_f", "K_f/K_env (2.15)", cf, env_m.static_gain, unit="rad/N·m", old=env_old),
        row("Tp", "π/(ωf√(1−ζf²)) (2.16)", fe.peak_time_s, env_m.peak_time_s, unit="s",
            old=env_old),
        row("%OS", "e^(−ζfπ/√(1−ζf²))·100 (2.17)", fe.overshoot_pct, env_m.overshoot_pct, 2,
            "%", old=env_old),
        row("Ts", "4/(ζfωf) (2.18)", fe.settling_time_s, env_m.settling_time_s, unit="s",
            old=env_old),
        row("Tr", "1.8/ωf (2.19)", fe.rise_time_s, env_m.rise_time_s, unit="s", old=env_old),
    ]
    notes = []
    if pd is not None:
        notes.append(f"PD measured on: {pd.what}.")
        if pd_old:
            notes.append(f"{STALE} Measured with {pd_old}, not the gains in use: press **Step** "
                         "again.")
        ts, design_ts = pd.settling_time_s, fp.settling_time_s if fp else None
        if (pd.band is not None and ts is not None and design_ts is not None
                and ts > 1.25 * design_ts):
            band = math.degrees(pd.band)
            servo = (f", {'less than' if band < servo_step_deg else 'about'} the servo's "
                     f"{people(servo_step_deg, 2)}° position step, so the arm settles when "
                     "its servo's steps do" if servo_step_deg else "")
            notes.append(f"Ts is the time θ stays within 2 % of the step (±{people(band, 2)}°"
                         f"{servo}); the formula assumes a smooth joint.")
    if env is not None:
        notes.append(f"Environment measured on: {env.what} (θ_env against τ_ext; the LPF "
                     "on τ slows it).")
        if env_old:
            notes.append(f"{STALE} Measured with {env_old}, not the gains in use: press "
                         "**Push** again.")
    if not notes:
        notes.append("Press **Step** (Run tab) or **Push** to measure.")
    return "\n".join(lines) + "\n\n" + " ".join(notes)


@dataclass(frozen=True)
class LiveValues:
    """The newest recorded values of one joint (SI)."""

    joint: str
    q_cmd: float
    q: float
    q_env: float
    tau_load: float
    tau_dyn: float
    tau_ext: float


def latest_values(snap: dict[str, np.ndarray], joint: int, name: str) -> LiveValues | None:
    """The newest finite row of ``snap`` (a recorder snapshot) for ``joint``; None if none."""
    t = snap.get("t")
    if t is None or len(t) == 0:
        return None
    for k in range(len(t) - 1, max(-1, len(t) - 10), -1):
        row = {s: float(snap[s][k, joint]) for s in ("q_cmd", "q", "q_env", "tau_load",
                                                     "tau_dyn", "tau_ext")}
        if all(math.isfinite(v) for v in row.values()):
            return LiveValues(name, **row)
    return None


def after_minus(text: str) -> str:
    """A number written after a minus sign: ``(−0.06 N·m)`` when it is negative, as it is
    otherwise (never "− -0.06")."""
    t = text.lstrip("+")
    return f"(−{t[1:]})" if t.startswith("-") else t


def torque_text(nm: float, unit: str) -> str:
    """A torque in N·m shown in ``unit`` ("N·m" or "kgf·cm")."""
    return f"{nm * KGF_CM_PER_NM:+.2f} kgf·cm" if unit == "kgf·cm" else f"{nm:+.3f} N·m"


def _ff(p: Params) -> str:
    """The feed-forward term when it is on (the thesis's law has none)."""
    return " + θ̈_cmd  (feed-forward: not in the thesis)" if p.feedforward else ""


def equations_markdown(params: Params, live: LiveValues | None, *, torque_unit: str = "N·m",
                       mode: str = "compliance") -> str:
    """The control law in use with the newest numbers of one joint (angles in degrees)."""
    p = params
    effective = "pd" if mode == "compliance" and not p.compliance else mode
    out: list[str] = []
    if effective == "none":
        out.append("**No position controller**: θ_ref = θ_cmd (RMRC angles sent as they are).")
    elif effective == "pd":
        out.append("**PD reference loop (2.20)**  \n"
                   "θ̈_ref = Kp (θ_cmd − θ) + Kv (θ̇_cmd − θ̇)" + _ff(p))
        if live is not None:
            e = (live.q_cmd - live.q) * DEG
            out.append(f"{live.joint}: Kp (θ_cmd − θ) = {p.kp:.3g} × ({live.q_cmd * DEG:.2f}° − "
                       f"{after_minus(f'{live.q * DEG:.2f}°')}) = {p.kp * e:.3g} °/s²")
    else:
        law = LAWS[p.law]
        out.append(f"**{law.title}**  \n{law.formula}" + _ff(p))
        out.append("**Environment (2.7)**  \nM_env θ̈_env + D_env θ̇_env + K_env θ_env = "
                   f"K_f τ_ext  with M_env {p.m_env:.3g}, D_env {p.d_env:.3g}, "
                   f"K_env {p.k_env:.3g}, K_f {p.k_f:.3g}")
        if live is not None:
            gain = law.env_gain(p)
            pos = (live.q_cmd - live.q - gain * live.q_env) * DEG
            env_term = (f"{gain:.3g}·{after_minus(f'{live.q_env * DEG:.2f}°')}"
                        if law.env_symbol else after_minus(f"{live.q_env * DEG:.2f}°"))
            out.append(f"{live.joint} now: Kp (θ_cmd − θ − {law.env_symbol}"
                       f"θ_env) = {p.kp:.3g} × ({live.q_cmd * DEG:.2f}° − "
                       f"{after_minus(f'{live.q * DEG:.2f}°')} − {env_term}) = "
                       f"{p.kp * pos:.3g} °/s²  \n"
                       f"steady state: θ_env → C_f τ_ext = {p.k_f / p.k_env:.3g} × "
                       f"{torque_text(live.tau_ext, 'N·m')} = "
                       f"{p.k_f / p.k_env * live.tau_ext * DEG:.2f}°; now "
                       f"{live.q_env * DEG:.2f}°")
    out.append(f"**External torque (2.23)**  \nτ_ext = LPF(τ_servo) − τ_NE, "
               f"LPF y += α(x − y), α = {p.alpha:.3g}")
    if live is not None:
        out.append(f"{live.joint} now: τ_ext = {torque_text(live.tau_load, torque_unit)} − "
                   f"{after_minus(torque_text(live.tau_dyn, torque_unit))} = "
                   f"{torque_text(live.tau_ext, torque_unit)}")
    out.append(f"**Integration**: θ̇_ref += T θ̈_ref, θ_ref += T θ̇_ref, T = {p.period * 1e3:.3g} ms "
               "(θ_ref, θ̇_ref go to the servos as Goal Position and Moving Speed)")
    return "\n\n".join(out)


@dataclass(frozen=True)
class Chapter4:
    """The thesis's chapter-4 figures of the last line runs (degrees, per joint, or None).

    Attributes:
        free: max |θ_cmd − θ| of the last run without a push (fig. 4.2/4.4).
        pushed: max |θ_cmd − θ| of the last run with a push or drag (fig. 4.9/4.12).
        yield_deg: max |θ_pushed − θ_free|: how far the push moved each joint
            compared with the last free run. Not the thesis's metric.
    """

    free: np.ndarray | None = None
    pushed: np.ndarray | None = None
    yield_deg: np.ndarray | None = None


def chapter4_markdown(ch4: Chapter4, names: list[str] | tuple[str, ...]) -> str:
    """The thesis's metric (command minus actual) for free and pushed runs, yield apart."""

    def per_joint(x: np.ndarray | None) -> str:
        if x is None:
            return "—"
        return ", ".join(f"{n} {v:.1f}°" for n, v in zip(names, x, strict=True))

    return "\n".join([
        "**Chapter 4's metric**: max |θ_cmd − θ| over the last thesis-line run",
        f"- free: {per_joint(ch4.free)} (thesis: 6° to over 20° without the PD loop, under "
        "6° with it)",
        f"- pushed (push or drag during the run): {per_joint(ch4.pushed)} (thesis, "
        "compliance on: over 15° on servo 3)",
        f"- yield under the push, pushed − free run (a different quantity): "
        f"{per_joint(ch4.yield_deg)}",
    ])


#: PD loop's free-run lag on the 1.28 s line (max θ_cmd − θ, degrees) per thesis preset,
#: from ``armlab experiment thesis-line --controller pd --preset NAME``.
THESIS_PRESET_PD_LAG_DEG = {"thesis Table 4.1": 19.5, "thesis conclusion": 21.1}


def thesis_preset_note(params: Params) -> str:
    """What a student must know when a thesis preset is chosen ("" otherwise).

    Figures from ``armlab experiment thesis-line`` and ``thesis-readings``
    (docs/compliance.md).
    """
    name = next((k for k, v in PRESETS.items() if v == params and k.startswith("thesis")), None)
    if name is None:
        return ""
    lag = THESIS_PRESET_PD_LAG_DEG.get(name)
    lag_text = f" make the PD loop lag {lag:g}° on the 1.28 s line" if lag else ""
    return (f"**{name}: chapter 4 does not reproduce here.** Read in SI, Kp {params.kp:g} and "
            f"Kv {params.kv:g}{lag_text} (thesis: under 6°). No reading of "
            "the thesis's units reproduces all three of its figures (`armlab experiment "
            "thesis-readings`): gains per control period diverge (pole radius 1.45); Kv per "
            "period with torque in kgf·cm gives PD 3.5° and 54.7° under the push, but no "
            "reading can move the no-controller run (4.6° here, thesis 6° to over 20°), "
            "which uses no gains at all. See docs/compliance.md.")
