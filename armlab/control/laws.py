"""The compliance laws, one registry: thesis eq. 2.6 (the consistent form, default), eq.
2.26 as printed, and a student's eq. 2.6 put in its place (``armlab serve --exercise``,
``armlab check``).

A law is a value (:class:`ComplianceLaw`): the θ̈_ref it gives from the command, the
measurement and the environment offset θ_env of eq. 2.7, the choice a person picks, its
equation as the Teach tab prints it, and the joint stiffness a steady press settles at.
The controller (:class:`armlab.control.compliance.ComplianceController`), the Teach tab,
the Gains tab's choice, an exported page and the contact experiment's prediction all ask
the law in force, by ``Params.law``, of the mapping the controller runs (:data:`LAWS`, or
:func:`with_student`'s with the student's in the place of eq. 2.6).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

if TYPE_CHECKING:
    from armlab.control.params import Params

#: one law's arrays and floats: all (n,) arrays (the loop) or all floats (a single joint)
ArrayT = TypeVar("ArrayT", np.ndarray, float)


def compliance_accel(kp: float, kv: float, q_cmd: ArrayT, qd_cmd: ArrayT, q: ArrayT, qd: ArrayT,
                     q_env: ArrayT, qd_env: ArrayT, qdd_env: ArrayT) -> ArrayT:
    """Thesis eq. 2.6 in joint space (the consistent form, default law):

    θ̈_ref = Kp (θ_cmd − θ − θ_env) + Kv (θ̇_cmd − θ̇ − θ̇_env) − θ̈_env.

    The reference model (2.3) is then applied to θ_cmd − θ_env, so a steady
    external torque τ_ext moves the arm by −θ_env = −K_f τ_ext / K_env. Each argument
    (rad, rad/s, rad/s²) is (n,) or a scalar; θ̈_ref has their shape.
    """
    return kp * (q_cmd - q - q_env) + kv * (qd_cmd - qd - qd_env) - qdd_env


def compliance_accel_literal(kp: float, kv: float, m_env: float, d_env: float, k_env: float,
                             q_cmd: ArrayT, qd_cmd: ArrayT, q: ArrayT, qd: ArrayT, q_env: ArrayT,
                             qd_env: ArrayT, qdd_env: ArrayT) -> ArrayT:
    """Thesis eq. 2.26 as printed (thesis-literal variant):

    θ̈_ref = Kp (θ_cmd − θ − K_env θ_env) + Kv (θ̇_cmd − θ̇ − D_env θ̇_env) − M_env θ̈_env.

    Dimensionally inconsistent with 2.6/2.7 (the offsets are multiplied by the
    environment's parameters again); a steady τ_ext moves the arm by −K_f τ_ext.
    """
    return (kp * (q_cmd - q - k_env * q_env) + kv * (qd_cmd - qd - d_env * qd_env)
            - m_env * qdd_env)


#: ``(params, q_cmd, qd_cmd, q, qd, q_env, qd_env, qdd_env) -> θ̈_ref``, each (n,)
Accel = Callable[..., np.ndarray]


@dataclass(frozen=True)
class ComplianceLaw:
    """One compliance law.

    Attributes:
        key: its name in the registry and in ``Params.law`` ("2.6", "2.26").
        label: the choice a person picks ("2.6 (consistent, default)").
        title: the Teach tab's heading ("Compliance, law 2.6").
        formula: its equation as printed.
        accel: ``(params, q_cmd, qd_cmd, q, qd, q_env, qd_env, qdd_env) -> θ̈_ref``,
            each (n,) rad, rad/s, rad/s².
        env_gain: ``params -> `` the factor on θ_env in its position error (1 in eq. 2.6,
            K_env in eq. 2.26).
        env_symbol: that factor as the equation writes it ("" or "K_env ").
    """

    key: str
    label: str
    title: str
    formula: str
    accel: Accel
    env_gain: Callable[[Params], float]
    env_symbol: str = ""

    def joint_stiffness(self, params: Params) -> float:
        """N·m/rad every joint holds a steady external torque τ with: eq. 2.7 settles at
        θ_env = K_f τ / K_env, and the law holds θ − θ_cmd = −(env gain) θ_env, so
        K_q = K_env / (K_f · env gain) (K_env / K_f for eq. 2.6, 1 / K_f for eq. 2.26)."""
        return params.k_env / (params.k_f * self.env_gain(params))


def _accel_2_6(p: Params, q_cmd: Any, qd_cmd: Any, q: Any, qd: Any, q_env: Any,
               qd_env: Any, qdd_env: Any) -> Any:
    return compliance_accel(p.kp, p.kv, q_cmd, qd_cmd, q, qd, q_env, qd_env, qdd_env)


def _accel_2_26(p: Params, q_cmd: Any, qd_cmd: Any, q: Any, qd: Any, q_env: Any,
                qd_env: Any, qdd_env: Any) -> Any:
    return compliance_accel_literal(p.kp, p.kv, p.m_env, p.d_env, p.k_env, q_cmd, qd_cmd, q,
                                    qd, q_env, qd_env, qdd_env)


EQ_2_6 = ComplianceLaw(
    key="2.6", label="2.6 (consistent, default)", title="Compliance, law 2.6",
    formula="θ̈_ref = Kp (θ_cmd − θ − θ_env) + Kv (θ̇_cmd − θ̇ − θ̇_env) − θ̈_env",
    accel=_accel_2_6, env_gain=lambda p: 1.0)
EQ_2_26 = ComplianceLaw(
    key="2.26", label="2.26 (thesis literal)", title="Compliance, law 2.26 (thesis literal)",
    formula="θ̈_ref = Kp (θ_cmd − θ − K_env θ_env) + Kv (θ̇_cmd − θ̇ − D_env θ̇_env) "
            "− M_env θ̈_env",
    accel=_accel_2_26, env_gain=lambda p: p.k_env, env_symbol="K_env ")
#: Every law the lab runs, by ``Params.law``.
LAWS: Mapping[str, ComplianceLaw] = {law.key: law for law in (EQ_2_6, EQ_2_26)}


def student_law(fn: Callable[..., Any]) -> ComplianceLaw:
    """A student's ``compliance_accel(kp, kv, q_cmd, qd_cmd, q, qd, q_env, qd_env,
    qdd_env)`` (the exercise of eq. 2.6) as a law: eq. 2.6's entry with their function."""
    def accel(p: Params, *args: Any) -> Any:
        return fn(p.kp, p.kv, *args)
    return replace(EQ_2_6, title="Compliance, your law 2.6", accel=accel)


def with_student(fn: Callable[..., Any]) -> Mapping[str, ComplianceLaw]:
    """The registry with the student's law (:func:`student_law`) in the place of eq. 2.6."""
    return {**LAWS, EQ_2_6.key: student_law(fn)}
