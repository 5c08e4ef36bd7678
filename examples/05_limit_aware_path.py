"""A limit-aware joint path for a straight Puma 560 line, against the greedy choice.

Run: ``python examples/05_limit_aware_path.py [OUT_DIR]``; writes plans and plots.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import optik
from optik.paths import line


def main(out_dir: str | Path = ".") -> dict[str, float]:
    """Plan the line optimally and greedily; save both plots and the plan files."""
    robot = optik.load_problem("puma560").robot
    q_now = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
    q_goal = np.array([-0.7299, 3.927, -1.5419, 1.3596, 0.5327, 4.2171])
    poses = line(robot.fk(q_now), robot.fk(q_goal), 0.01)
    plan = optik.plan_path(robot, poses, max_joint_step=0.2, q_start=q_now)
    greedy = optik.plan_path(robot, poses, max_joint_step=0.2, q_start=q_now, greedy=True)
    out = Path(out_dir)
    plan.save(out / "puma_line_plan.csv")
    plan.plot(out / "puma_line_plan.png", robot)
    greedy.plot(out / "puma_line_greedy.png", robot)
    print(f"optimal plan: {plan.summary()}")
    print(f"greedy plan:  {greedy.summary()}")
    print(f"largest step: {plan.largest_step:.3f} rad (plan), {greedy.largest_step:.3f} (greedy)")
    return {"plan_step": plan.largest_step, "greedy_step": greedy.largest_step}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
