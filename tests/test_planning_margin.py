"""plan_path's cost prefers configurations away from the joint limits.

Lines on the Panda whose plans ran along a limit before the margin entered the path's
cost (the minimum normalised margin, distance to the nearer limit over the joint's range,
was 0.0 to 0.05): every waypoint is re-verified here from forward kinematics, and the
plan's smallest normalised margin must now clear the comfort band.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from optik.model import Robot
from optik.paths import line
from optik.plan_choice import MARGIN_BAND, Comfort, choose
from optik.planning import PathPlan, plan_path
from optik.problems import load_problem
from optik.spatial import rot_x, rotation_angle, transform


def _normalised_margin(robot: Robot, Q: np.ndarray) -> float:
    """Smallest distance to the nearer limit over the joint's range, along the plan."""
    margin = np.minimum(Q - robot.lower, robot.upper - Q) / (robot.upper - robot.lower)
    return float(np.min(margin))


def _verify(robot: Robot, plan: PathPlan, mode: str) -> None:
    assert plan.status == ["ok"] * len(plan.status)
    assert plan.largest_step <= plan.max_joint_step
    for q, T in zip(plan.q, plan.poses, strict=True):
        F = robot.fk(q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
        if mode == "pose":
            assert float(rotation_angle(F[:3, :3].T @ T[:3, :3])) <= 1e-6
        assert np.all(q >= robot.lower) and np.all(q <= robot.upper)


# (start, end) of tool-down lines (m); the first ran along joint 6's lower limit, with a
# 1.95 rad jump and an unsolved waypoint; the second along joint 2's limit.
LINES = {
    "position": ([0.3, 0.0, 0.5], [0.6, 0.0, 0.5]),
    "pose": ([0.5, -0.3, 0.5], [0.5, 0.3, 0.1]),
}


@pytest.mark.parametrize("mode", sorted(LINES))
def test_panda_line_keeps_clear_of_the_limits(mode: str) -> None:
    robot = load_problem("panda").robot
    start, end = LINES[mode]
    poses = line(transform(rot_x(math.pi), start), transform(rot_x(math.pi), end), 0.01)
    path = poses[:, :3, 3] if mode == "position" else poses
    plan = plan_path(robot, path, mode=mode, max_joint_step=0.1)
    _verify(robot, plan, mode)
    assert _normalised_margin(robot, plan.q) >= MARGIN_BAND


def test_the_choice_prefers_margin_at_equal_motion() -> None:
    robot = load_problem("puma560").robot
    comfort = Comfort.of(robot)
    mid = robot.mid_limits
    near_limit = mid.copy()
    near_limit[1] = robot.lower[1] + 0.01
    away = mid.copy()
    away[1] = robot.lower[1] + 0.3 * (robot.upper[1] - robot.lower[1])
    start = 0.5 * (near_limit + away)  # both equally far
    layers = [[near_limit, away], [near_limit, away]]
    assert choose(layers, 1.0, False, start, comfort) == [1, 1]
    # ... but never at the price of a discontinuity: after a waypoint with the near-limit
    # candidate only, the other is a jump (> max_step), and the near-limit one is kept.
    assert choose([[near_limit], [near_limit, away]], 0.05, False, None, comfort) == [0, 0]


def test_comfort_box_leaves_infinite_and_held_joints_alone() -> None:
    robot = load_problem("puma560").robot
    held = robot.with_limits(
        np.where(np.arange(robot.dof) == 0, 0.2, robot.lower),
        np.where(np.arange(robot.dof) == 0, 0.2, robot.upper),
    )
    comfort = Comfort.of(held)
    assert comfort.lower[0] == comfort.upper[0] == 0.2
    span = robot.upper[1:] - robot.lower[1:]
    np.testing.assert_allclose(comfort.lower[1:], robot.lower[1:] + MARGIN_BAND * span)
    q = held.mid_limits.copy()
    q[2] = robot.upper[2]  # at the limit: MARGIN_BAND * range from the box
    assert comfort.distance(q) == pytest.approx(MARGIN_BAND * (robot.upper[2] - robot.lower[2]))
    moved = comfort.towards(q, 0.05)
    assert moved[2] == pytest.approx(robot.upper[2] - 0.05)
    np.testing.assert_array_equal(np.delete(moved, 2), np.delete(q, 2))
