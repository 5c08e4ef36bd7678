"""Singular poses whose closed-form point lies outside the limits while the continuum of
answers enters them: a free shoulder, an aligned wrist. Found by a hostile search.

At such a pose the closed form returns one point of a continuum (the free joint at the
reference, or one split of ``q4 + q6``); when that point is outside the limits the
branches are polished into them, then rerun from other references.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import optik


def _checked(robot: optik.Robot, q: np.ndarray) -> None:
    """``q`` inside the limits; its pose gets in-limit branches, single and batched."""
    assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
    T = robot.fk(q)
    branches = optik.analytic_ik(robot, T)
    assert branches
    for b in branches:
        F = robot.fk(b)
        assert np.max(np.abs(F - T)) < 1e-9
        assert np.all(b >= robot.lower) and np.all(b <= robot.upper)
    batch = optik.analytic_ik_batch(robot, T[None])
    assert batch.counts[0] == len(branches)
    np.testing.assert_array_equal(batch.q[0, : len(branches)], np.array(branches))


def test_the_drills_shoulder_over_its_axis_takes_another_joint_1() -> None:
    """The wrist centre on axis 1: joint 1 is free; at the reference (0) the wrist falls
    outside its +-90 deg, at -1.95 rad it does not."""
    robot = optik.load_problem("jumbo_drill_6dof").robot
    q3 = 4.176679543492919
    q = np.array([-1.952582298765603, math.asin(0.6 / q3), q3, 0.2581, -1.2751, -0.4202])
    _checked(robot, q)


def test_the_pumas_aligned_wrist_splits_q4_q6_inside_narrow_limits() -> None:
    puma = optik.load_problem("puma560").robot
    lower, upper = puma.lower.copy(), puma.upper.copy()
    lower[3], upper[3], lower[5], upper[5] = -0.5, 1.2, -0.3, 0.4
    robot = puma.with_limits(lower, upper)
    q = np.array([1.283031200006818, 3.5739593889079986, -0.20124593271221514, 0.9727, 0.0, 0.2312])
    _checked(robot, q)


@pytest.mark.parametrize("q5", [0.0, 1e-12])
def test_the_ur5s_aligned_wrist_inside_one_radian_limits(q5: float) -> None:
    robot = optik.load_problem("ur5").robot.with_limits(-np.ones(6), np.ones(6))
    q = np.array(
        [-0.9216674507053655, 0.7461623961970483, -0.4041987776948748, -0.178, q5, -0.9427]
    )
    _checked(robot, q)


def test_an_aligned_wrist_on_random_poses_always_keeps_an_in_limit_branch() -> None:
    """50 poses of the UR5 within +-1 rad with q5 = 0 (23 of 50 lost every branch)."""
    robot = optik.load_problem("ur5").robot.with_limits(-np.ones(6), np.ones(6))
    rng = np.random.default_rng(5)
    for q in rng.uniform(-1.0, 1.0, (50, 6)):
        q[4] = 0.0
        assert optik.analytic_ik(robot, robot.fk(q)), q


def test_the_drills_narrow_window_of_joint_1_is_found() -> None:
    # The wrist centre over axis 1 and the wrist's limits narrowed: the in-limit answers
    # are a window of joint 1 about 3 % of its range wide, which 8 references spread
    # over the range missed on 19 of 40 such poses; the search of the excursion's dips
    # finds it.
    lower = np.array([-1.1502432, -0.11671717, 2.28831923, -0.08066126, -1.08097263, -1.81167339])
    upper = np.array([1.20595129, 2.23947732, 4.28831923, 1.49013507, 0.4898237, 1.32991926])
    robot = optik.load_problem("jumbo_drill_6dof").robot.with_limits(lower, upper)
    over_axis = np.array(
        [0.969202893717013, 0.2014283568349306, 2.9989651703107616,
         -0.027102362104046547, -0.05079316230171638, 1.2033274472878022]
    )  # fmt: skip
    assert np.linalg.svd(robot.jacobian(over_axis), compute_uv=False)[-1] < 1e-12
    rng = np.random.default_rng(0)
    for q1 in [over_axis[0], *rng.uniform(lower[0] + 0.05, upper[0] - 0.05, 15)]:
        q = over_axis.copy()
        q[0] = q1
        _checked(robot, q)
