"""A drilling pattern on a tilted plate, planned as 5-D tool-axis targets (mode="axis").

Each hole is an entry point on the plate and a drilling direction (into the plate, along
its normal); the spindle turns, so the roll of the tool about its axis is free. The holes
are visited row by row (a serpentine), planned with :func:`optik.plan_path` in
``mode="axis"`` for the Panda (7 joints, numeric) and the UR5 (6 joints). Every hole's
errors are measured here from forward kinematics: the distance of the tool point to the
entry point (m) and the angle between the tool z axis and the drilling direction (rad).
For comparison, the same pattern with one fixed roll (a full 6-D pose per hole) is planned
too.

Run: ``python examples/drilling_pattern.py``.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

import optik
from optik.spatial import rot_y, rot_z

PLATE_CENTRE = np.array([0.45, 0.0, 0.25])
"""Centre of the plate in the robots' base frame (m)."""
PLATE_TILT = math.radians(30.0)
"""The plate's tilt about the base y axis: its normal leans back towards the robot (rad)."""
ROWS, COLUMNS = 3, 4
SPACING = 0.06
"""Distance between neighbouring holes (m)."""
CAD_ROLL = 2.4
"""Turn of the hole frames' x axis about the drilling axis from one hole to the next (rad)."""


def drilling_pattern() -> np.ndarray:
    """(ROWS * COLUMNS, 4, 4) hole poses in serpentine order.

    Each pose's z axis is the drilling direction (minus the plate's outward normal), its
    origin the entry point. The rotation about z is arbitrary, as a CAD export gives it:
    here it turns by :data:`CAD_ROLL` from hole to hole. ``mode="axis"`` ignores it; a
    full pose would make the wrist follow it.
    """
    R_plate = rot_y(PLATE_TILT)  # columns: row direction, column direction, outward normal
    along, across, normal = R_plate[:, 0], R_plate[:, 1], R_plate[:, 2]
    # Tool frame of a hole: z = -normal (into the plate), x = the row direction.
    R_hole = np.column_stack([along, -across, -normal])
    holes = []
    for i in range(ROWS):
        order = range(COLUMNS) if i % 2 == 0 else reversed(range(COLUMNS))
        for j in order:
            u = (j - (COLUMNS - 1) / 2) * SPACING
            v = (i - (ROWS - 1) / 2) * SPACING
            T = np.eye(4)
            T[:3, :3] = R_hole @ rot_z(CAD_ROLL * len(holes))
            T[:3, 3] = PLATE_CENTRE + u * along + v * across
            holes.append(T)
    return np.array(holes)


def _axis_angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


def drill(name: str, holes: np.ndarray, mode: str) -> dict[str, Any]:
    """Plan the pattern on robot ``name``; errors of every hole measured from FK."""
    robot = optik.load_problem(name).robot
    start = time.perf_counter()
    plan = optik.plan_path(robot, holes, mode=mode, max_joint_step=0.6, restarts=5)
    elapsed = time.perf_counter() - start
    position, axis = [], []
    for k in range(len(holes)):
        if not plan.solved[k]:
            position.append(math.nan)
            axis.append(math.nan)
            continue
        F = robot.fk(plan.q[k])
        position.append(float(np.linalg.norm(F[:3, 3] - holes[k, :3, 3])))
        axis.append(_axis_angle(F[:3, 2], holes[k, :3, 2]))
    return {
        "robot": name,
        "mode": mode,
        "status": list(plan.status),
        "q": plan.q,
        "position_error": position,
        "axis_error": axis,
        "solved": int(plan.solved.sum()),
        "holes": len(holes),
        "largest_step": plan.largest_step,
        "time_s": elapsed,
    }


def _print(result: dict[str, Any], per_hole: bool) -> None:
    print(
        f"{result['robot']} ({result['mode']}): {result['solved']}/{result['holes']} holes "
        f"solved, {result['status'].count('ok')} ok, largest joint step "
        f"{result['largest_step']:.3f} rad, "
        f"planned in {result['time_s']:.2f} s"
    )
    if not per_hole:
        return
    for k, status in enumerate(result["status"]):
        print(
            f"  hole {k:2d}  {status:<14}  position error {result['position_error'][k]:.2e} m"
            f"  axis error {result['axis_error'][k]:.2e} rad"
        )


def main() -> dict[str, dict[str, Any]]:
    """Plan the pattern for the Panda and the UR5, 5-D (axis) and, for contrast, 6-D.

    Returns, per robot (``"panda"``, ``"ur5"``; ``"panda_pose"``, ``"ur5_pose"`` for the
    6-D plans), the statuses, the configurations ``q`` (holes, dof), the FK errors of
    every hole, the holes solved, the largest joint step (rad) and the planning time (s).
    """
    holes = drilling_pattern()
    results: dict[str, dict[str, Any]] = {}
    for name in ("panda", "ur5"):
        five = drill(name, holes, "axis")
        six = drill(name, holes, "pose")
        _print(five, per_hole=True)
        _print(six, per_hole=False)
        results[name] = five
        results[name + "_pose"] = six
    return results


if __name__ == "__main__":
    main()
