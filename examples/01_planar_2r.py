"""Seed 003's two-link arm: the pseudoinverse iteration to (1.2, 1.3), with its trajectory.

Run: ``python examples/01_planar_2r.py [OUT_DIR]``; writes ``planar_2r_trajectory.png``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

import optik
from optik.compare import planar_2r_example
from optik.plots import plot_planar_trajectory


def main(out_dir: str | Path = ".") -> dict[str, float]:
    """Solve the seed's example as printed (step 0.001, tolerance 0.01), then to 1e-9."""
    problem = optik.load_problem("planar_2r")
    robot = problem.robot
    target = problem.targets["seed003"]

    # The note's Algorithm 1: theta <- theta + 0.001 J^+ delta until |delta| < 0.01, from
    # theta = (0.5, 0.5) rad (the same computation as the report's seed 003 section).
    (row,), trajectory = planar_2r_example(problem, steps=(0.001,))
    iterations = int(row.iterations or 0)
    error = float(row.position_error or 0.0)
    q = trajectory[-1]
    print(
        f"seed 003 (step 0.001): {iterations} iterations, error {error:.4f} m, "
        f"q = ({math.degrees(q[0]):.2f}, {math.degrees(q[1]):.2f}) deg"
    )

    precise = optik.solve_ik(robot, target.position, mode="position", tol=1e-9)
    print(
        f"closed form ({precise.solver}): error {precise.position_error:.1e} m, "
        f"q = {np.degrees(precise.q).round(4)} deg"
    )
    branches = optik.analytic_ik(robot, target.position, mode="position")
    print(f"both elbow branches: {[np.degrees(b).round(2).tolist() for b in branches]}")

    path = plot_planar_trajectory(
        robot, trajectory, target.position, Path(out_dir) / "planar_2r_trajectory.png"
    )
    print(f"wrote {path}")
    return {"iterations": iterations, "error": error, "precise_error": precise.position_error}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
