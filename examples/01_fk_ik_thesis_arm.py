"""Forward and inverse kinematics of the thesis's arm (thesis §3.2–3.3), no UI.

Run it from the repository's root:  python examples/01_fk_ik_thesis_arm.py

1. Forward kinematics: where is the hand at the thesis's start angles?
2. Inverse kinematics by RMRC (resolved motion rate control, thesis eq. 3.16–3.22):
   which angles put the hand at the two ends of chapter 4's 20 cm line?
"""

from __future__ import annotations

import numpy as np

import armlab
from armlab.control.trajectory import THESIS_LINE_END, THESIS_LINE_START, THESIS_Q_GUESS
from armlab.kinematics.ik import rmrc


def main() -> None:
    """Print the hand's position at the start angles and RMRC's answers for the line's ends."""
    arm = armlab.load_robot("receptionist_arm")  # L1 = 18.5 cm, L2 = 25 cm, thesis frame
    print("joints:", ", ".join(arm.joint_names))

    # 1. Forward kinematics: T = A1 A2 A3 (thesis eq. 3.1-3.13), the hand in the base frame
    q = np.asarray(THESIS_Q_GUESS, dtype=float)
    hand = arm.fk(q)[:3, 3]
    print("fk_q_deg =", " ".join(f"{v:.3f}" for v in np.degrees(q)))
    print("fk_hand_cm =", " ".join(f"{v:.3f}" for v in hand * 100))

    # 2. Inverse kinematics: iterate dq = J^-1 dx from the guess until |dx| < 0.1 mm
    for name, target in (("start", THESIS_LINE_START), ("end", THESIS_LINE_END)):
        result = rmrc(arm, target, q, tol=1e-4)
        reached = arm.fk(result.q)[:3, 3]
        print(f"ik_{name}_target_cm =", " ".join(f"{v:.3f}" for v in target * 100))
        print(f"ik_{name}_q_deg =", " ".join(f"{v:.3f}" for v in np.degrees(result.q)))
        print(f"ik_{name}_error_mm = {np.linalg.norm(reached - target) * 1000:.4f}")
        print(f"ik_{name}_iterations = {result.iterations}")
        q = result.q  # the thesis starts each solve from the previous answer


if __name__ == "__main__":
    main()
