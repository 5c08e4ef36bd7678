"""Chains wider than ``WIDE_CHAIN_DOF`` take the LM step in the task's space.

The step ``(D + J^T J) dq = J^T e`` is solved as ``dq = D^-1 J^T y``,
``(I + J D^-1 J^T) y = e`` (:func:`optik.solvers._lm_kernel._wide_step`). It is checked
here against numpy's solve of the joints' own system, on both sides of the threshold,
with a frozen joint and with a joint held on its bound.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import optik
from optik.model import DHJoint, Robot
from optik.solvers._base import IKQuery, run_lm
from optik.solvers._lm_kernel import STALL_RATIO, STALL_WINDOW, WIDE_CHAIN_DOF

W_BIAS = 1e-3


def _snake(dof: int) -> Robot:
    """A spatial chain of ``dof`` short links, twists alternating: about 0.3 m per 10 joints."""
    rows = [
        DHJoint(a=0.02, alpha=(0.5 + 0.3 * (i % 3)) * (-1) ** i, d=0.01, theta=0.1 * i)
        for i in range(dof)
    ]
    return Robot.from_dh(rows, limits=np.tile([-2.5, 2.5], (dof, 1)))


def _reference_step(
    robot: Robot, q0: np.ndarray, target: np.ndarray, bias: float, held: list[int]
) -> np.ndarray:
    """One projected LM step from ``q0`` by numpy: ``(lam I + J^T J) dq = J^T e``, the
    ``held`` joints out of the system; ``lam = e^T e / 2 + W_BIAS * bias`` (scale 1)."""
    T, J = robot.fk_jacobian(q0)
    e = np.concatenate(
        [target[:3, 3] - T[:3, 3], Rotation.from_matrix(target[:3, :3] @ T[:3, :3].T).as_rotvec()]
    )
    lam = 0.5 * float(e @ e) + W_BIAS * bias
    free = [a for a in range(robot.dof) if a not in held]
    Jf = J[:, free]
    dq = np.zeros(robot.dof)
    dq[free] = np.linalg.solve(lam * np.eye(len(free)) + Jf.T @ Jf, Jf.T @ e)
    return np.clip(q0 + dq, robot.lower, robot.upper)


@pytest.mark.parametrize("dof", [WIDE_CHAIN_DOF - 2, WIDE_CHAIN_DOF + 1, 120])
def test_one_step_is_the_joint_space_step(dof: int, rng: np.random.Generator) -> None:
    robot = _snake(dof)
    q_source = rng.uniform(-1.0, 1.0, dof)
    q0 = q_source + rng.normal(0.0, 0.05, dof)
    target = robot.fk(q_source)
    query = IKQuery(robot, target, "pose", 1e-12)
    q1, iterations, _ = run_lm(query, q0, 1, W_BIAS, STALL_WINDOW, STALL_RATIO)
    assert iterations == 1
    expected = _reference_step(robot, q0, target, query.spec.damping_bias, [])
    assert not np.allclose(q1, q0)  # the step was taken (the error fell)
    np.testing.assert_allclose(q1, expected, rtol=0.0, atol=1e-10)


@pytest.mark.parametrize("dof", [WIDE_CHAIN_DOF - 2, WIDE_CHAIN_DOF + 1])
def test_a_frozen_joint_and_a_joint_held_on_its_bound_stay_out_of_the_step(
    dof: int, rng: np.random.Generator
) -> None:
    robot = _snake(dof)
    q_source = rng.uniform(-1.0, 1.0, dof)
    target = robot.fk(q_source)
    q0 = q_source + rng.normal(0.0, 0.05, dof)
    lower, upper = robot.lower.copy(), robot.upper.copy()
    lower[3] = upper[3] = q0[3]  # frozen
    # Joint 7 on the bound that the gradient J^T e pushes it beyond.
    T, J = robot.fk_jacobian(q0)
    e = np.concatenate(
        [target[:3, 3] - T[:3, 3], Rotation.from_matrix(target[:3, :3] @ T[:3, :3].T).as_rotvec()]
    )
    gradient = float(J[:, 7] @ e)
    assert gradient != 0.0
    if gradient < 0.0:
        lower[7] = q0[7]
    else:
        upper[7] = q0[7]
    held_robot = Robot.from_dh(robot.dh, limits=np.column_stack([lower, upper]))
    query = IKQuery(held_robot, target, "pose", 1e-12)
    q1, iterations, _ = run_lm(query, q0, 1, W_BIAS, STALL_WINDOW, STALL_RATIO)
    assert iterations == 1
    expected = _reference_step(held_robot, q0, target, query.spec.damping_bias, [3, 7])
    assert q1[3] == q0[3] and q1[7] == q0[7]
    np.testing.assert_allclose(q1, expected, rtol=0.0, atol=1e-10)


def test_a_chain_of_a_thousand_joints_is_solved() -> None:
    # The joints' system made one iteration of a 2,000-joint chain take about 0.5 s,
    # and solve_ik overran its timeout (checked between attempts) by seconds.
    robot = _snake(1000)
    rng = np.random.default_rng(7)
    q_source = rng.uniform(-0.3, 0.3, robot.dof)
    target = robot.fk(q_source)
    result = optik.solve_ik(robot, target, timeout_s=30.0)
    assert result.success, result.status
    T = robot.fk(result.q)
    assert np.linalg.norm(T[:3, 3] - target[:3, 3]) <= 1e-6
    assert Rotation.from_matrix(T[:3, :3].T @ target[:3, :3]).magnitude() <= 1e-6
    assert np.all(robot.lower <= result.q) and np.all(result.q <= robot.upper)
