"""Seed 000's spherical (RRP) arm: the four position branches and the unique pose branch.

Run: ``python examples/02_spherical_arm_branches.py``.
"""

from __future__ import annotations

import numpy as np

import optik


def main() -> dict[str, int]:
    """Print every branch for one target, with and without the joint limits."""
    robot = optik.load_problem("jumbo_spherical_arm").robot
    q = np.array([0.4, 0.6, 3.5])  # swing, lift (rad), stroke (m)
    T = robot.fk(q)
    every = optik.analytic_ik(robot, T[:3, 3], mode="position", within_limits=False)
    inside = optik.analytic_ik(robot, T[:3, 3], mode="position")
    print(f"target position {T[:3, 3].round(4)} m")
    print("position only (eq. 27, 33, 34): four branches, before the limits")
    for b in every:
        outside = [
            j.name for j, v in zip(robot.joints, b, strict=True) if not j.lower <= v <= j.upper
        ]
        tag = "inside" if not outside else "outside: " + ", ".join(outside)
        print(
            f"  swing {np.degrees(b[0]):8.2f} deg  lift {np.degrees(b[1]):8.2f} deg  "
            f"stroke {b[2]:7.3f} m   {tag}"
        )
    pose = optik.analytic_ik(robot, T, mode="pose")
    print(f"full pose (eq. 35-42, corrected eq. 36): {len(pose)} branch: {pose[0].round(6)}")
    return {"branches": len(every), "inside": len(inside), "pose_branches": len(pose)}


if __name__ == "__main__":
    main()
