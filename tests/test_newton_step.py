"""The Newton step that restores closed-form branches of an inexact table to rounding.

:mod:`optik.analytic._newton` works on the FK prefixes the pipeline's check forms; each
piece is compared with an independent reference: the residual with numpy on ``Robot.fk``,
the Jacobian with central differences of ``Robot.fk``, the steps with numpy's solvers.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
from pathlib import Path

import numpy as np
import pytest
from conftest import damped_step_reference, fd_jacobian, pose_residual_reference, robot_of

from optik import Robot
from optik.analytic import (
    FAMILIES,
    _compiled,
    _newton,
    _pipeline,
    _row_steps,
    _rows,
    analytic_ik,
    analytic_ik_batch,
)
from optik.analytic.geometry import joint_axes, point_line_distance, wrist_centre
from optik.limits import LIMIT_TOLERANCE

LAYOUT = _pipeline.SIX_JOINT_LAYOUT


def _kinova() -> Robot | None:
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    root = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    path = root / "kinova_description" / "robots" / "kinova.urdf"
    return Robot.from_urdf(path, "j2s6s200_link_base", "j2s6s200_end_effector")


KINOVA = _kinova()
# CI installs the test extra: there a missing package is a failure, never a skip.
needs_erd = pytest.mark.skipif(
    KINOVA is None and not os.environ.get("CI"),
    reason="example-robot-data is not installed (pip install 'optik[test]'): "
    "the makers' URDFs are not available",
)


def _prefixes(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(params, pre, rows)``: the pipeline's FK of ``q`` as its check leaves it."""
    family = FAMILIES["spherical_wrist"] if robot.dof == 6 else None
    assert family is not None and family.fits(robot)
    params = _compiled.params_of(robot, family.kernel)
    rows = np.zeros((3 * _compiled.MAX_BRANCHES, 6))
    rows[0] = q
    rows[_compiled.SIN_ROWS] = np.sin(q)
    rows[_compiled.COS_ROWS] = np.cos(q)
    pre = np.empty((8, 12))
    pre[0] = params[_compiled.AT_CHAIN : _compiled.AT_CHAIN + 12]
    _rows.fk_shared(params, LAYOUT, rows, 0, pre, np.int64(0))
    return params, pre, rows


def _step(
    robot: Robot, q: np.ndarray, target: np.ndarray, held: int = -1, wrist: bool = True
) -> tuple[np.ndarray, float]:
    """``newton_step`` on ``q`` towards ``target``: (the step taken, its largest entry)."""
    params, pre, rows = _prefixes(robot, q)
    work = np.empty(_newton.newton_work_size(6))
    _newton.pose_residual(pre, 6, target[None], 0, work)
    wrist_at = LAYOUT[6] if wrist else -1
    at, stride, max_step = LAYOUT[0], LAYOUT[1], _newton.REFINE_MAX_STEP
    largest = _newton.newton_step(
        params, at, stride, 6, held, wrist_at, pre, rows, 0, work, max_step
    )
    return rows[0] - q, largest


@pytest.mark.parametrize("name", ["puma560", "stanford_arm"])
def test_residual_and_jacobian_match_fk(name: str, rng: np.random.Generator) -> None:
    """The residual equals numpy's on ``Robot.fk``; the Jacobian central differences."""
    robot = robot_of(name)
    for _ in range(5):
        q = rng.uniform(robot.lower, robot.upper)
        target = robot.fk(q + rng.normal(scale=1e-4, size=6))
        params, pre, _ = _prefixes(robot, q)
        work = np.empty(_newton.newton_work_size(6))
        squared = _newton.pose_residual(pre, 6, target[None], 0, work)
        expected = pose_residual_reference(robot, q, target)
        np.testing.assert_allclose(work[:6], expected, rtol=0, atol=1e-15)
        assert squared == pytest.approx(float(expected @ expected), rel=1e-12)
        jac = 6 + 2 * 6
        _newton._jacobian(params, LAYOUT[0], LAYOUT[1], 6, -1, pre, work, jac)
        J = work[jac : jac + 36].reshape(6, 6).T  # stored by columns
        np.testing.assert_allclose(J, fd_jacobian(robot, q), rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", ["puma560", "stanford_arm"])
def test_damped_step_is_numpys_damped_least_squares(name: str, rng: np.random.Generator) -> None:
    robot = robot_of(name)
    for _ in range(5):
        q = rng.uniform(robot.lower, robot.upper)
        target = robot.fk(q + rng.normal(scale=1e-6, size=6))
        dq, largest = _step(robot, q, target, wrist=False)
        expected = damped_step_reference(
            robot.jacobian(q), pose_residual_reference(robot, q, target)
        )
        np.testing.assert_allclose(dq, expected, rtol=1e-7, atol=1e-16)
        assert largest == pytest.approx(float(np.max(np.abs(dq))), rel=1e-9)


def test_held_joint_stays_and_the_others_solve_without_it(rng: np.random.Generator) -> None:
    robot = robot_of("puma560")
    q = rng.uniform(robot.lower, robot.upper)
    target = robot.fk(q + rng.normal(scale=1e-6, size=6))
    dq, _ = _step(robot, q, target, held=2)
    assert dq[2] == 0.0
    J = robot.jacobian(q)
    J[:, 2] = 0.0
    np.testing.assert_allclose(
        dq,
        damped_step_reference(J, pose_residual_reference(robot, q, target)),
        rtol=1e-7,
        atol=1e-16,
    )


@pytest.mark.parametrize("name", ["puma560", "stanford_arm"])
def test_wrist_centre_step_is_the_newton_step(name: str, rng: np.random.Generator) -> None:
    """Axes 4-6 through one point: the two 3 x 3 solves give ``J^-1 e`` (numpy)."""
    robot = robot_of(name)
    for _ in range(5):
        q = rng.uniform(robot.lower, robot.upper)
        q[4] = math.copysign(max(abs(q[4]), 0.3), q[4])  # away from the wrist singularity
        target = robot.fk(q + rng.normal(scale=1e-6, size=6))
        dq, _ = _step(robot, q, target)
        expected = np.linalg.solve(robot.jacobian(q), pose_residual_reference(robot, q, target))
        np.testing.assert_allclose(dq, expected, rtol=1e-7, atol=1e-16)


def test_aligned_wrist_falls_back_to_the_damped_step(rng: np.random.Generator) -> None:
    """At q5 = 0 (axes 4 and 6 aligned) the wrist block is singular: the damped step
    moves the pose to the target without a large move along the free direction."""
    robot = robot_of("puma560")
    q = rng.uniform(robot.lower, robot.upper)
    q[4] = 0.0
    delta = rng.normal(scale=1e-7, size=6)
    target = robot.fk(q + delta)
    dq, largest = _step(robot, q, target)
    assert 0.0 < largest <= 10 * float(np.max(np.abs(delta)))
    before = np.linalg.norm(pose_residual_reference(robot, q, target))
    after = np.linalg.norm(pose_residual_reference(robot, q + dq, target))
    assert after < 1e-3 * before


def test_a_step_above_the_bound_is_refused(rng: np.random.Generator) -> None:
    robot = robot_of("puma560")
    q = rng.uniform(robot.lower, robot.upper)
    q[4] = 0.7
    target = robot.fk(q + 1e-2)
    for wrist in (True, False):
        dq, largest = _step(robot, q, target, wrist=wrist)
        assert largest == 0.0 and not np.any(dq)


def test_wrist_centre_is_on_axes_4_5_6() -> None:
    for name in ("puma560", "stanford_arm"):
        robot = robot_of(name)
        axes = joint_axes(robot)
        c = wrist_centre(axes)
        world = axes.tool[:3, :3] @ c + axes.tool[:3, 3]
        for i in (3, 4, 5):
            assert point_line_distance(axes.directions[i], axes.points[i], world) < 1e-12


@needs_erd
def test_kinova_branches_reach_rounding_and_stay_inside_the_limits() -> None:
    """The Jaco 2's table is not exact: every branch is refined, none leaves the limits.

    With the limits of joint 2 moved onto the source configuration's value, the
    branch there is still returned, inside its limits to :data:`LIMIT_TOLERANCE`.
    """
    robot = KINOVA
    assert robot is not None
    assert not FAMILIES["spherical_wrist"].model(robot).exact
    rng = np.random.default_rng(11)
    lower, upper = np.maximum(robot.lower, -math.pi), np.minimum(robot.upper, math.pi)
    Q = rng.uniform(lower, upper, (60, 6))
    T = robot.fk(Q)
    batch = analytic_ik_batch(robot, T, within_limits=False)
    for i in range(len(Q)):
        for b in batch.branches(i):
            assert np.max(np.abs(robot.fk(b) - T[i])) < 1e-13
    for q in Q[:20]:
        tight_lower, tight_upper = robot.lower.copy(), robot.upper.copy()
        tight_lower[1] = tight_upper[1] = q[1]
        tight = robot.with_limits(tight_lower, tight_upper)
        branches = analytic_ik(tight, tight.fk(q))
        assert any(np.max(np.abs(b - q)) < 1e-8 for b in branches)
        for b in branches:
            assert tight_lower[1] - LIMIT_TOLERANCE <= b[1] <= tight_upper[1] + LIMIT_TOLERANCE
            assert np.max(np.abs(tight.fk(b) - tight.fk(q))) < 1e-9


def test_a_branch_at_rounding_takes_no_step_and_one_off_by_1e_10_is_restored(
    rng: np.random.Generator,
) -> None:
    """A row whose residual is at rounding takes no step (the pipeline does not call
    ``_refine_row``); a row 1e-10 off its target is brought to rounding (``Robot.fk``)."""
    robot = robot_of("puma560")
    verify = float(_compiled.tolerance_block()[_compiled.TOL_VERIFY])
    for _ in range(10):
        q = rng.uniform(robot.lower, robot.upper)
        for offset, moved in ((0.0, False), (1e-10, True)):
            target = robot.fk(q + offset)
            params, pre, rows = _prefixes(robot, q)
            work = np.empty(_newton.newton_work_size(6))
            depth = np.int64(6)
            ref = q[None].copy()
            squared = _newton.pose_residual(pre, 6, target[None], 0, work)
            if not moved:
                assert squared <= _newton.REFINE_ROUNDING**2  # the pipeline calls no step
                continue
            args = (params, LAYOUT, 6, -1, 0.0, target[None], 0, ref, 0, True, rows, 0, pre)
            _, keep = _row_steps._refine_row(*args, depth, verify, work, _newton.REFINE_MAX_STEP)
            assert keep
            assert not np.array_equal(rows[0], q)
            assert np.linalg.norm(pose_residual_reference(robot, rows[0], target)) < 1e-14
