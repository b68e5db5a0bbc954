"""The disturbance and reaction-torque observers (thesis §2.1.1) on every joint of a
position-servo arm, fed the control loop's record row by row, and the hand's force each
torque estimate implies along a wall's normal.

The lab's own estimate of the world's torque is τ_ext = LPF(τ_dist) − τ_dyn (thesis
eq. 2.21–2.23, in the loop). The observers read the same servo load τ_dist (Present
Load, N·m: the observers' K_tn I with K_tn = 1) and the same measured angles, one joint
at a time, as :mod:`armlab.control.experiments.observers` runs them on current-sensing
servos:

    DOB   τ̂_dis  = g/(s + g) · (τ_dist + g J_n θ̇) − g J_n θ̇                  (eq. 2.36)
    RTOB  τ̂_reac = g/(s + g) · (τ_dist + g J_n θ̇ − g(θ) − C(θ, θ̇) θ̇) − g J_n θ̇  (eq. 2.37)

each step one call of :func:`armlab.control.observers.disturbance_observer` /
:func:`~armlab.control.observers.reaction_torque_observer` per joint. J_n is the joint's
own inertia, the arm model's mass-matrix diagonal M_ii(θ) at the row's pose (the rotor's
reflected inertia and the other joints' coupling are left out, as on the servos); the RTOB's
known load is the model's gravity and velocity torques (RNEA with θ̈ = 0, eq. 2.41–2.50),
no friction. The record keeps the measured angles, not the speeds, so θ̇ is the backward
difference of two rows' angles (the servo's 0.29° counts make it coarse; the observers'
low-pass takes most of that out).

The DOB reads the whole disturbance, gravity included, so the force it implies is its
change since a reference row (the run's start, the arm at rest off the wall): what
``armlab experiment observers`` does on servos (−Δτ̂_dis). The RTOB reads the external
torque itself.

Causal: each row's estimates use that row and the ones before only, so the Contact tab
(rows as the loop appends them) and ``armlab experiment contact`` (a whole record) give
the same numbers for the same rows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from armlab.control.observers import (
    ObserverState,
    disturbance_observer,
    reaction_torque_observer,
)
from armlab.control.recorder import Recorder
from armlab.kinematics.dynamics import bias_torques, mass_matrix
from armlab.kinematics.fk import fk_and_jacobian
from armlab.kinematics.model import SerialChain
from armlab.kinematics.smallarrays import all_finite

#: rad/s, both observers' cut-off on the arm (``armlab experiment observers``'s on servos:
#: well under 1 / period at the lab's 16 ms, and above the LPF of eq. 2.21's 3.2 rad/s)
CUTOFF = 20.0


class ArmObservers:
    """The DOB and the RTOB on every joint of ``model``, one loop record row at a time.

    Args:
        model: the arm.
        g_dis, g_reac: the DOB's and the RTOB's cut-offs, rad/s.
    """

    def __init__(self, model: SerialChain, *, g_dis: float = CUTOFF,
                 g_reac: float = CUTOFF) -> None:
        self.model = model
        self.g_dis, self.g_reac = float(g_dis), float(g_reac)
        self.reset()

    def reset(self) -> None:
        """Forget every row: the next one starts both filters settled on its reading."""
        n = self.model.n
        self._dob = [ObserverState() for _ in range(n)]
        self._rtob = [ObserverState() for _ in range(n)]
        self._last: tuple[float, np.ndarray] | None = None  #: (t s, θ rad) of the last row

    @property
    def last_t(self) -> float | None:
        """Loop time of the last row taken, s (None: none since the reset)."""
        return None if self._last is None else self._last[0]

    def step(self, t: float, q: np.ndarray, load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One record row: loop time ``t`` s, measured ``q`` (n,) rad, servo load ``load``
        (n,) N·m (τ_dist). Returns (τ̂_dis, τ̂_reac), each (n,) N·m (thesis sign: the
        torque the motor works against); NaN for a row whose angles or load are not finite
        (it leaves the filters as they were)."""
        n = self.model.n
        q = np.asarray(q, dtype=float)
        load = np.asarray(load, dtype=float)
        if not all_finite(q, load):
            return np.full(n, math.nan), np.full(n, math.nan)
        last = self._last
        first = last is None or not t > last[0]
        dt = 1.0 if first or last is None else float(t) - last[0]
        qd = np.zeros(n) if first or last is None else (q - last[1]) / dt
        self._last = (float(t), q.copy())
        j_n = np.diag(mass_matrix(self.model, q))
        known = bias_torques(self.model, q, qd)
        dis, reac = np.empty(n), np.empty(n)
        for j in range(n):
            if first:  # settled on this reading: τ̂ = its input
                self._dob[j].z = float(load[j])
                self._rtob[j].z = float(load[j] - known[j])
            dis[j] = disturbance_observer(self._dob[j], float(load[j]), float(qd[j]),
                                          j_n=float(j_n[j]), kt_n=1.0, g_dis=self.g_dis,
                                          dt=dt)
            reac[j] = reaction_torque_observer(self._rtob[j], float(load[j]), float(qd[j]),
                                               float(known[j]), j_n=float(j_n[j]), kt_n=1.0,
                                               g_reac=self.g_reac, dt=dt)
        return dis, reac

    def run(self, t: Sequence[float] | np.ndarray, q: np.ndarray, load: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`step` over rows ``t`` (m,) s, ``q`` (m, n) rad, ``load`` (m, n) N·m:
        (τ̂_dis, τ̂_reac), each (m, n) N·m."""
        m, n = len(t), self.model.n
        dis, reac = np.empty((m, n)), np.empty((m, n))
        for k in range(m):
            dis[k], reac[k] = self.step(float(t[k]), q[k], load[k])
        return dis, reac


def observe_record(model: SerialChain, t: np.ndarray, q: np.ndarray, load: np.ndarray, *,
                   g_dis: float = CUTOFF, g_reac: float = CUTOFF
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Both observers over a whole record from its first row (settled there): (τ̂_dis,
    τ̂_reac), each (m, n) N·m."""
    return ArmObservers(model, g_dis=g_dis, g_reac=g_reac).run(t, q, load)


def hand_normal_forces(model: SerialChain, q: np.ndarray, taus: Sequence[np.ndarray],
                       normal: np.ndarray) -> list[np.ndarray]:
    """N the hand presses a wall with, by each joint-torque estimate of ``taus`` (each
    (m, n) N·m, thesis sign: the torque the motors spend against the world), at each of
    ``q`` (m, n) rad: n · F, F = (J_vᵀ)⁺(−τ) the world's force on the hand (the statics
    τ = J_vᵀ F by least squares) and n the wall's unit ``normal`` (3,) towards the free
    side, so a press reads positive as the wall's own force does. One (m,) array per
    estimate; NaN where the estimate or the pose is not finite (τ_ext under PD)."""
    q = np.asarray(q, dtype=float)
    m = len(q)
    n = np.asarray(normal, dtype=float)
    out = [np.full(m, math.nan) for _ in taus]
    rows = np.flatnonzero(np.all(np.isfinite(q), axis=1)) if m else np.zeros(0, dtype=int)
    if not len(rows):
        return out
    Jv = np.array([fk_and_jacobian(model, q[k], check=False)[1][:3] for k in rows])
    # n · (J_vᵀ)⁺(−τ) = −((J_vᵀ)⁺ᵀ n) · τ: one vector a row serves every estimate
    w = np.linalg.pinv(np.transpose(Jv, (0, 2, 1))).transpose(0, 2, 1) @ n  # (r, n)
    for i, tau in enumerate(taus):
        out[i][rows] = -np.einsum("rj,rj->r", w, np.asarray(tau, dtype=float)[rows])
    return out


#: s of readings before a reference time the DOB's reference is the mean of (the arm at
#: rest: the load reading's steps averaged out)
REST_S = 0.5


class FollowedRecord:
    """Both observers kept up with a control loop's record as it grows: each
    :meth:`update` steps them over the rows appended since the last (``Recorder.since``),
    so a page that redraws a chart many times a second pays for the new periods only; the
    estimates of the last ``window_s`` s are kept for :meth:`at`.

    Args:
        model: the arm.  recorder: the loop's ``Recorder``.
        window_s: s of estimates kept (the chart's window).
        period: s, the loop's period (how many rows the first update takes: the window's).
        g: both observers' cut-off, rad/s.
    """

    def __init__(self, model: SerialChain, recorder: Recorder, *, window_s: float,
                 period: float, g: float = CUTOFF) -> None:
        self.model, self.recorder, self.window_s = model, recorder, float(window_s)
        self._first_rows = int(math.ceil(window_s / period)) + 2
        self._obs = ArmObservers(model, g_dis=g, g_reac=g)
        self._written: int | None = None
        n = model.n
        self.t = np.zeros(0)  #: (k,) s, the rows estimated, oldest first
        self.dis = np.zeros((0, n))  #: (k, n) N·m, τ̂_dis at each
        self.reac = np.zeros((0, n))  #: (k, n) N·m, τ̂_reac at each

    def update(self) -> None:
        """Step the observers over the rows appended since the last update (the newest
        window's on the first; after a gap longer than the record keeps, from where it
        resumes, settled there)."""
        if self._written is None:
            raw, count = self.recorder.recent(self._first_rows)
        else:
            raw, count = self.recorder.since(self._written)
            if count - self._written > len(raw):  # rows lost: start again, settled
                self._obs.reset()
        self._written = count
        if not len(raw):
            return
        rows = self.recorder.unpack(raw)
        dis, reac = self._obs.run(rows["t"], rows["q"], rows["load"])
        t = np.concatenate([self.t, rows["t"]])
        keep = t >= t[-1] - self.window_s - 1.0
        self.t = t[keep]
        self.dis = np.concatenate([self.dis, dis])[keep]
        self.reac = np.concatenate([self.reac, reac])[keep]

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(τ̂_dis, τ̂_reac) at the rows of loop times ``t`` (m,) s, each (m, n) N·m; NaN
        at a time not estimated (before the window)."""
        t = np.asarray(t, dtype=float)
        n = self.model.n
        if not len(self.t):
            return np.full((len(t), n), math.nan), np.full((len(t), n), math.nan)
        k = np.clip(np.searchsorted(self.t, t), 0, len(self.t) - 1)
        found = np.abs(self.t[k] - t) < 1e-9
        dis, reac = self.dis[k], self.reac[k]
        dis[~found] = math.nan
        reac[~found] = math.nan
        return dis, reac

    def rest_reading(self, until: float) -> np.ndarray | None:
        """(n,) N·m, the DOB's mean over the :data:`REST_S` s of rows up to loop time
        ``until`` (the reference its change is read from); None when none is kept."""
        rows = (self.t > until - REST_S) & (self.t <= until + 1e-9)
        ok = rows & np.all(np.isfinite(self.dis), axis=1)
        return self.dis[ok].mean(axis=0) if ok.any() else None
