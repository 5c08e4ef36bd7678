"""The task cache: a repeated task is validated once, and caching never changes a task."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.errors import OptikError
from optik.task import _make_task, make_task

FREE_Z = [1.0, 1.0, 0.0, 1.0, 1.0, 1.0]


@pytest.mark.parametrize(
    "weights",
    [FREE_Z, tuple(FREE_Z), [1, 1, 0, 1, 1, 1], np.array(FREE_Z), [0, 0, 0, 1, 1, 0]],
)
def test_equal_weights_give_one_task_equal_to_a_fresh_one(weights: object) -> None:
    first = make_task(weights=weights)
    assert make_task(weights=weights) is first
    fresh = _make_task("pose", "z", weights, 1e-6)  # validated afresh, never cached
    assert fresh is not first
    assert first.mode == fresh.mode and first.axis == fresh.axis
    np.testing.assert_array_equal(first.packed, fresh.packed)
    np.testing.assert_array_equal(first.features, fresh.features)


def test_cached_task_cannot_be_changed_by_the_caller() -> None:
    weights = list(FREE_Z)
    task = make_task(weights=weights)
    weights[0] = 5.0  # the caller's list changes; the cached task must not
    assert make_task(weights=FREE_Z) is task
    assert task.weights[0] == 1.0
    assert not task.weights.flags.writeable and not task.packed.flags.writeable


@pytest.mark.parametrize(
    "weights",
    [
        [True, True, False, True, True, True],  # bools are not numbers here
        [1.0, 1.0, float("nan"), 1.0, 1.0, 1.0],
        [10**400, 1, 1, 1, 1, 1],  # beyond float range
        [1.0, 1.0, -1.0, 1.0, 1.0, 1.0],
        [1.0, 1.0, 1.0, 1.0, 0.0, 0.0],  # two rotational zeros
    ],
)
def test_bad_weights_raise_every_time(weights: list[object]) -> None:
    for _ in range(2):  # the second call must not find a cached answer
        with pytest.raises(OptikError, match="weights"):
            make_task(weights=weights)


def test_cache_keeps_modes_and_tolerances_apart() -> None:
    a = make_task("pose", weights=None, tol=1e-6)
    b = make_task("pose", weights=None, tol=1e-4)
    c = make_task("pose", weights=FREE_Z, tol=1e-6)
    assert len({id(a), id(b), id(c)}) == 3
    assert b.position_tol == 1e-4 and c.weights[2] == 0.0


def test_weighted_solve_is_unchanged_by_the_cache() -> None:
    robot = optik.load_problem("panda").robot
    q = np.linspace(-0.5, 0.5, robot.dof)
    T = robot.fk(q)
    T[:3, 3] += 0.05 * T[:3, 2]  # off along the free axis
    first = optik.solve_ik(robot, T, weights=FREE_Z, solver="dls", seed=3)
    second = optik.solve_ik(robot, T, weights=np.array(FREE_Z), solver="dls", seed=3)
    assert first.success and second.success
    np.testing.assert_array_equal(first.q, second.q)
    F = robot.fk(first.q)
    d = T[:3, :3].T @ (F[:3, 3] - T[:3, 3])
    assert np.linalg.norm(d[:2]) <= 1e-6
