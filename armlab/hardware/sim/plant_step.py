"""One step of :class:`~armlab.hardware.sim.plant.Plant` as straight-line code (its fast path).

:meth:`Plant.step` ticks every servo's firmware, then integrates the rigid body by RK4
with the servo duties held. On a few joints the step's cost is Python's: the per-joint
list comprehensions, closures and calls around the four forward-dynamics evaluations
cost more than the dynamics themselves. :func:`rk4_step` writes the same step out joint
by joint, once per shape (joint count, joints with dry friction, held torque vectors),
and compiles it. Every float operation is the one the plant's readable step does, in the
same order, so the two give bit-identical states (tests/test_plant.py compares them
step by step, with and without friction, pushes and applied torques).

The step here covers what is held over a step (servo duties, pushes, applied joint
torques) and, when asked (``fields``), the spring's and wall's torques, which change
within the step: the plant's function of them is called at each RK4 stage, as the
readable step calls it. A step where a joint-limit stop acts takes the plant's readable
path.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache

#: ``step(q, qd, servos, directions, viscous, coulomb, held, fd, gravity, armature, dt,
#: field)`` -> (q, qd) after one dt, as lists.
StepFunction = Callable[..., tuple[list[float], list[float]]]


@cache
def rk4_step(n: int, coulomb_joints: tuple[int, ...], held: int, fields: bool = False
             ) -> StepFunction:
    """The compiled step of an ``n``-joint plant whose joints ``coulomb_joints`` have
    dry friction and that holds ``held`` torque vectors (a push's J^T F, the applied
    joint torques) over the step, added in that order after the friction; with
    ``fields``, the torques ``field(q, qd)`` returns (n,) at each stage (a spring's, a
    wall's) added last.

    The function it returns takes the state lists ``q``, ``qd``; the servo models (each
    ticked once, at direction · state); the joints' directions and viscous friction; one
    (coulomb, 1 / friction speed) pair per joint of ``coulomb_joints``; the ``held``
    vectors; the chain's generated forward dynamics ``fd`` with its gravity and armature;
    ``dt``; and ``field`` (None without ``fields``). It returns the new (q, qd).
    """
    js = range(n)

    def names(prefix: str) -> str:
        return ", ".join(f"{prefix}{i}" for i in js) + ","

    lines = [
        "def step(q, qd, servos, directions, viscous, coulomb, held, fd, g, arm, dt, "
        "field=None):",
        f"    {names('q')} = q",
        f"    {names('v')} = qd",
        f"    {names('s')} = servos",
        f"    {names('o')} = directions",
        f"    {names('f')} = viscous",
    ]
    lines += [f"    s{i}.update(dt, o{i} * q{i}, o{i} * v{i})" for i in js]
    lines += [f"    dr{i} = o{i} * s{i}.drive" for i in js]
    lines += [f"    dm{i} = s{i}.damping + f{i}" for i in js]
    for k, i in enumerate(coulomb_joints):
        lines.append(f"    cf{i}, cr{i} = coulomb[{k}]")
    for m in range(held):
        lines.append(f"    {names(f'e{m}_')} = held[{m}]")

    def torques(v: str) -> str:
        """The joint torques at velocities ``{v}{i}``, as the plant's derivative sums them."""
        out = []
        for i in js:
            term = f"dr{i} - dm{i} * {v}{i}"
            if i in coulomb_joints:
                term += f" - cf{i} * _tanh({v}{i} * cr{i})"
            term += "".join(f" + e{m}_{i}" for m in range(held))
            if fields:
                term += f" + t{v}{i}"
            out.append(term)
        return "(" + ", ".join(out) + ",)"

    def vec(prefix: str) -> str:
        return "(" + names(prefix) + ")"

    def stage(out: str, x: str, v: str) -> list[str]:
        """``out`` = q̈ at positions ``{x}{i}``, velocities ``{v}{i}``."""
        field = [f"    {names(f't{v}')} = field({vec(x)}, {vec(v)})"] if fields else []
        return [*field, f"    {names(out)} = fd({vec(x)}, {vec(v)}, {torques(v)}, g, arm)"]

    lines += ["    h = 0.5 * dt", *stage("a", "q", "v")]
    lines += [f"    x{i} = q{i} + h * v{i}" for i in js]
    lines += [f"    w{i} = v{i} + h * a{i}" for i in js]
    lines += stage("b", "x", "w")
    lines += [f"    y{i} = q{i} + h * w{i}" for i in js]
    lines += [f"    u{i} = v{i} + h * b{i}" for i in js]
    lines += stage("c", "y", "u")
    lines += [f"    z{i} = q{i} + dt * u{i}" for i in js]
    lines += [f"    p{i} = v{i} + dt * c{i}" for i in js]
    lines += stage("d", "z", "p")
    lines.append("    s = dt / 6.0")
    new_q = ", ".join(f"q{i} + s * (v{i} + 2.0 * (w{i} + u{i}) + p{i})" for i in js)
    new_qd = ", ".join(f"v{i} + s * (a{i} + 2.0 * (b{i} + c{i}) + d{i})" for i in js)
    lines.append(f"    return [{new_q}], [{new_qd}]")
    namespace: dict[str, object] = {"_tanh": math.tanh}
    exec(compile("\n".join(lines) + "\n", f"<plant step, {n} joints>", "exec"), namespace)
    return namespace["step"]  # type: ignore[return-value]  # the generated step function
