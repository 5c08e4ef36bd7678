"""The Puma 560's eight branches, each refined by a QP-based solver with hard limits.

Run: ``python examples/04_puma_branches_qp.py``.
"""

from __future__ import annotations

import numpy as np

import optik


def main() -> dict[str, int]:
    """All closed-form branches of one pose; the ones inside the limits, refined by a QP."""
    robot = optik.load_problem("puma560").robot
    q = np.radians([20.0, 60.0, -120.0, 30.0, 40.0, 10.0])
    T = robot.fk(q)
    every = optik.analytic_ik(robot, T, within_limits=False)
    inside = optik.analytic_ik(robot, T, q_ref=q)
    print(f"{len(every)} branches, {len(inside)} inside the limits")
    qp = next((s for s in ("qp:proxqp", "qp:osqp") if s in optik.available_solvers()), "dls")
    refined = 0
    for branch in every:
        start = np.clip(branch, robot.lower, robot.upper)
        # Start each branch's refinement from a perturbed copy, clipped into the limits.
        result = optik.solve_ik(
            robot,
            T,
            solver=qp,
            q0=np.clip(start + 0.05, robot.lower, robot.upper),
            warm_start="q0",
            restarts=0,
        )
        mark = "inside" if robot.within_limits(branch) else "outside"
        print(
            f"  {np.degrees(branch).round(1)} deg ({mark}): {qp} -> {result.status}, "
            f"error {result.position_error:.1e} m / {result.orientation_error:.1e} rad"
        )
        refined += result.success
    return {"branches": len(every), "inside": len(inside), "refined": refined}


if __name__ == "__main__":
    main()
