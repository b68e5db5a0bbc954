"""One firmware tick of every servo of a class, compiled to machine code (numba).

:meth:`BatchedPlant._tick <armlab.hardware.families.dynamixel1.batched_plant.BatchedPlant>`
runs the RX-24F's firmware (``ServoModel.update``, thesis §2.3: the set-point moving to
the goal at Moving Speed, the compliance curve, wheel mode, overload shutdown) as numpy
over (joints, arms) arrays: about eighty numpy calls a tick, whatever the class's size.
:func:`tick_servos` is the same arithmetic written per servo, one loop over every joint
of every arm; numba compiles it (in a thread, :class:`armlab.kinematics.machine_code.MachineCode`),
and its results equal the numpy code's bit for bit (a test runs both on random registers).
"""

from __future__ import annotations

import numpy as np

from armlab.hardware.families.dynamixel1.firmware import ERROR_OVERLOAD
from armlab.hardware.servos.servo_spec import DIRECTION_BIT
from armlab.kinematics.machine_code import Kernel, MachineCode

A = np.ndarray  # (every array argument; numba reads the types off the arrays)


def tick_servos(q: A, qd: A, regs: A, shutdown: A, overload: A, stall: A,  # noqa: C901, PLR0912, PLR0913, PLR0915 - one servo's firmware, as in _tick
                was_enabled: A, setpoint: A, joint: A, slopes: A, dt: float, present: A,
                velocity: A, enabled: A, sp_out: A, duty_out: A, moving_out: A,
                angle_error_out: A, drive: A, damping: A) -> None:
    """One tick of servo (j, k) for every joint j of every arm k (``BatchedPlant._tick``,
    per servo, its operations in its order).

    Inputs: ``q``, ``qd`` (n, N) rad, rad/s; ``regs`` (12, n, N) int64: Torque Limit,
    Torque Enable, CW and CCW Angle Limit, Goal Position, Moving Speed, CW and CCW
    Compliance Margin, CW and CCW Compliance Slope, Punch, Alarm Shutdown (Torque Enable
    and Torque Limit set to 0 where an overload shuts a servo down); ``shutdown``,
    ``overload`` (n, N) bool and ``stall`` (n, N) s (written: the tick's); the last tick's
    ``was_enabled`` and ``setpoint``; ``joint`` (8, n) per joint: direction, counts per
    rad, counts per speed unit·s, speed unit, stall speed, overload time, stall torque,
    back-EMF damping; ``slopes`` (256,) the effective slopes (Table 2.4); ``dt`` s.
    Outputs, (n, N): Present Position counts, velocity, enabled, set-point, duty, Moving,
    angle error, drive torque and its damping.
    """
    n, arms = q.shape
    for j in range(n):
        direction, cpr, cpsu, speed_unit = joint[0, j], joint[1, j], joint[2, j], joint[3, j]
        stall_speed, overload_time = joint[4, j], joint[5, j]
        stall_torque, backemf = joint[6, j], joint[7, j]
        for k in range(arms):
            angle = direction * q[j, k]
            v = direction * qd[j, k]
            velocity[j, k] = v
            counts = np.rint(512.0 + angle * cpr)
            counts = min(max(counts, 0.0), 1023.0)
            pres = int(counts)
            present[j, k] = pres
            present_f = float(pres)
            torque_limit = regs[0, j, k] & 0x3FF
            sd, ov, st = shutdown[j, k], overload[j, k], stall[j, k]
            te = regs[1, j, k] != 0
            if sd and torque_limit > 0 and te:  # Torque Limit and Torque Enable written again
                sd, ov, st = False, False, 0.0
            on_now = te and not sd
            sp = present_f if (on_now and not was_enabled[j, k]) else setpoint[j, k]
            cw, ccw = regs[2, j, k] & 0x3FF, regs[3, j, k] & 0x3FF
            goal = regs[4, j, k] & 0x3FF
            wheel = cw == 0 and ccw == 0
            # joint mode: the set-point moves towards the goal at Moving Speed
            target = float(cw if goal < cw else (ccw if goal > ccw else goal))
            raw_speed = regs[5, j, k] & 0x3FF
            step = raw_speed * cpsu * dt
            if sp < target:
                moved = min(sp + step, target)
            else:
                moved = max(sp - step, target)
            if sp == target:
                moved = sp
            if not on_now:
                sp = present_f
            elif raw_speed == 0:
                sp = target
            else:
                sp = moved
            # the compliance curve
            rsp = int(np.rint(sp))
            error = rsp - pres
            if error > 0:
                margin, slope = regs[7, j, k], regs[9, j, k]
            else:
                margin, slope = regs[6, j, k], regs[8, j, k]
            err = abs(error)
            punch = min(regs[10, j, k], torque_limit)
            level = punch + (err - margin) * (torque_limit - punch) / slopes[slope & 0xFF]
            duty = min(level, float(torque_limit)) / 1023.0
            if rsp < pres:
                duty = -duty
            if not (on_now and torque_limit > 0 and err > margin):
                duty = 0.0
            moving = sp != target or abs(v) > speed_unit
            angle_error = not (cw <= goal and goal <= ccw)
            if wheel:  # wheel mode: Moving Speed is the PWM duty
                wspeed = regs[5, j, k] & 0x7FF
                wduty = min(wspeed & 0x3FF, torque_limit) / 1023.0
                if wspeed & DIRECTION_BIT != 0:
                    wduty = -wduty
                duty = wduty if on_now else 0.0
                sp = present_f
                moving = wspeed & 0x3FF != 0
                angle_error = False
            # overload: full duty (at Torque Limit) without moving for overload_time
            full = torque_limit > 0 and abs(duty) * 1023.0 >= torque_limit - 0.5
            if full or st != 0.0:
                st = st + dt if (full and abs(v) < stall_speed) else 0.0
                ov = sd or st > overload_time
                if ov and not sd and (regs[11, j, k] & ERROR_OVERLOAD) != 0:
                    sd = True  # Alarm Shutdown: torque off, Torque Limit 0 until written
                    regs[1, j, k] = 0
                    regs[0, j, k] = 0
                    on_now = False
                    duty = 0.0
            shutdown[j, k], overload[j, k], stall[j, k] = sd, ov, st
            enabled[j, k], sp_out[j, k], duty_out[j, k] = on_now, sp, duty
            moving_out[j, k], angle_error_out[j, k] = moving, angle_error
            if duty != 0.0:
                drive[j, k], damping[j, k] = duty * stall_torque, backemf
            else:
                drive[j, k], damping[j, k] = 0.0, 0.0


def _build() -> dict[str, Kernel]:
    """:func:`tick_servos` compiled, for the plant's arrays' types (C-ordered)."""
    import numba

    kernel = numba.njit(nogil=True, cache=True)(tick_servos)
    f, b, i = np.zeros((1, 1)), np.zeros((1, 1), dtype=bool), np.zeros((1, 1), dtype=np.int64)
    kernel(f, f.copy(), np.zeros((12, 1, 1), dtype=np.int64), b.copy(), b.copy(), f.copy(),
           b.copy(), f.copy(), np.ones((8, 1)), np.ones(256, dtype=np.int64), 1e-3, i.copy(),
           f.copy(), b.copy(), f.copy(), f.copy(), b.copy(), b.copy(), f.copy(), f.copy())
    return {"tick": kernel}


#: the process's compiled tick (one for every plant: it takes any n and N)
MACHINE = MachineCode(_build, "the servos' firmware tick")
