"""Seed 001's comparison: pseudoinverse vs Jacobian transpose on the DOBOT's path.

From the home configuration (rear arm vertical, forearm horizontal) through the three
targets of the chapter's Table 2, each part starting where the previous one ended,
position only, accepted error 0.2 mm (the arm's repeatability).

Run: ``python examples/03_dobot_pinv_vs_transpose.py``.
"""

from __future__ import annotations

import math

import numpy as np

import optik
from optik.solvers import IKQuery
from optik.solvers.iterative import PinvSolver, TransposeSolver

CHAPTER_TABLE_2 = {"part1": (22, 55), "part2": (5, 34), "part3": (6, 68)}


def main() -> dict[str, dict[str, int]]:
    """Iterations per method and part, printed beside the chapter's numbers."""
    problem = optik.load_problem("dobot_magician")
    robot = problem.robot
    counts: dict[str, dict[str, int]] = {}
    for solver in (PinvSolver(), TransposeSolver()):
        q = np.zeros(robot.dof)
        for part in ("part1", "part2", "part3"):
            target = problem.targets[part]
            out = solver.solve(
                IKQuery(robot, target.pose, "position", target.tolerance), q, 10_000, math.inf
            )
            if not out.converged:
                raise RuntimeError(f"{solver.name} did not converge on {part}")
            counts.setdefault(part, {})[solver.name] = out.iterations
            q = out.q
    print(f"{'part':<8}{'pinv':>6}{'transpose':>11}   chapter (pinv / transpose)")
    for part, (pinv, transpose) in CHAPTER_TABLE_2.items():
        ours = counts[part]
        print(f"{part:<8}{ours['pinv']:>6}{ours['transpose']:>11}   {pinv} / {transpose}")
    holds = all(c["pinv"] <= c["transpose"] for c in counts.values())
    print(f"the chapter's finding (pinv needs fewer iterations) holds: {holds}")
    return counts


if __name__ == "__main__":
    main()
