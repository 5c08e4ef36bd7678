"""Numeric IK of arms far smaller than a metre: the search balances its units.

A Puma 560 scaled to 1-3 mm (with a 1e-5 wrist offset, so that no fast closed form
answers first) failed 37 of 40 (1 mm) and 30 of 40 (3 mm) FK targets with ``dls``: its
position rows (m) were small beside its rotation rows (rad) and beside the damping's
bias. The search now measures positions in the arm's size
(:func:`optik.task.balanced_search`).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import optik
from optik.task import balanced_search, make_task


def _puma(scale: float) -> optik.Robot:
    rows = [
        {"d": 0.67183, "alpha": np.pi / 2},
        {"a": 0.4318},
        {"d": 0.15005, "a": 0.0203, "alpha": -np.pi / 2},
        {"d": 0.4318, "alpha": np.pi / 2},
        {"a": 1e-5, "alpha": -np.pi / 2},
        {},
    ]
    scaled = [
        {
            "a": row.get("a", 0.0) * scale,
            "d": row.get("d", 0.0) * scale,
            "alpha": row.get("alpha", 0.0),
            "lower": -2.5,
            "upper": 2.5,
        }
        for row in rows
    ]
    return optik.Robot.from_dh(scaled)


def test_balanced_search_scales_rotation_rows_and_bias() -> None:
    task = make_task(weights=[1, 1, 1, 1e-6, 1e-6, 1e-6], tol=(1e-7, 1e-5))
    small = balanced_search(task, 1e-3)
    np.testing.assert_allclose(small.weights, [1, 1, 1, 1e-6, 1e-6, 1e-6])
    assert small.packed[11] == pytest.approx(1e-6)  # the damping's bias, times L^2
    assert (small.position_tol, small.orientation_tol) == (1e-7, 1e-5)
    assert balanced_search(task, 2.0) is task.search  # a metre or more: unchanged
    orientation = make_task("orientation")
    assert balanced_search(orientation, 1e-3) is orientation  # no position rows
    point = balanced_search(make_task("position"), 1e-2)
    assert point.is_pose_or_position and point.packed[11] == pytest.approx(1e-4)


@pytest.mark.parametrize("scale", [2e-3, 1e-2])
def test_millimetre_arm_is_solved_by_dls_and_the_batch(scale: float) -> None:
    robot = _puma(scale)
    rng = np.random.default_rng(0)
    sources = rng.uniform(robot.lower, robot.upper, (20, 6))
    targets = np.array([robot.fk(q) for q in sources])
    tight = (1e-6 * scale, 1e-6)  # 1e-6 of the arm's size, not 1e-6 m
    for T in targets:
        result = optik.solve_ik(robot, T, solver="dls", warm_start="q0", tol=tight)
        assert result.success, (result.status, result.position_error)
        F = robot.fk(result.q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= tight[0]
        assert Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude() <= tight[1]
    batch = optik.solve_ik_batch(robot, targets, tol=tight)
    assert batch.success.all(), batch.status
    points = optik.solve_ik_batch(robot, targets[:, :3, 3], mode="position", tol=tight)
    assert points.success.all()
    reached = np.array([robot.fk(q)[:3, 3] for q in points.q])
    assert np.max(np.linalg.norm(reached - targets[:, :3, 3], axis=1)) <= tight[0]
