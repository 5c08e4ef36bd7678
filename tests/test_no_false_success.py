"""No false success: every success of solve_ik_batch re-verified by an independent FK.

100,000 random targets per robot (FK of uniform in-limit configurations), checked with a
vectorised product of the robots' own DH (or modified DH) matrices, written here
independently of optik's kernels.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import coupling_from_rows

import optik
from optik.problems import builtin_problems, load_problem

N = 100_000
NAMES = [p.stem for p in builtin_problems()]


def _dh_batch(robot: optik.Robot, Q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) tool poses from the DH rows, vectorised over the batch."""
    assert robot.dh is not None
    t = Q @ coupling_from_rows(robot).T
    N = len(Q)
    T = np.broadcast_to(robot.T_world_base, (N, 4, 4)).copy()
    for i, row in enumerate(robot.dh):
        theta = row.theta + (t[:, i] if row.kind == "revolute" else 0.0)
        d = row.d + (t[:, i] if row.kind == "prismatic" else 0.0)
        theta = np.broadcast_to(theta, (N,))
        d = np.broadcast_to(d, (N,))
        ct, st = np.cos(theta), np.sin(theta)
        ca, sa = np.cos(row.alpha), np.sin(row.alpha)
        A = np.zeros((N, 4, 4))
        if robot.convention == "mdh":  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
            A[:, 0, 0], A[:, 0, 1], A[:, 0, 3] = ct, -st, row.a
            A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st * ca, ct * ca, -sa, -sa * d
            A[:, 2, 0], A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = st * sa, ct * sa, ca, ca * d
        else:  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
            A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = ct, -st * ca, st * sa, row.a * ct
            A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st, ct * ca, -ct * sa, row.a * st
            A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca, d
        A[:, 3, 3] = 1.0
        T = T @ A
    return T @ robot.T_flange_tool


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_no_false_success_over_100000_targets(name: str) -> None:
    robot = load_problem(name).robot
    rng = np.random.default_rng(100_000 + len(name))
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    Q = rng.uniform(lower, upper, (N, robot.dof))
    mode = "pose" if robot.dof >= 6 else "position"
    targets = _dh_batch(robot, Q)
    np.testing.assert_allclose(targets, robot.fk(Q), atol=1e-9)  # the reference agrees
    res = optik.solve_ik_batch(robot, targets, mode=mode, restarts=20)
    ok = res.success
    F = _dh_batch(robot, res.q[ok])
    position = np.linalg.norm(F[:, :3, 3] - targets[ok, :3, 3], axis=1)
    assert np.all(position <= 1e-6), f"{int(np.sum(position > 1e-6))} false successes"
    if mode == "pose":
        R = np.swapaxes(targets[ok, :3, :3], 1, 2) @ F[:, :3, :3]
        cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
        assert np.all(np.arccos(cos) <= 1e-5)  # arccos floor ~1e-8; tol is 1e-6
    Qok = res.q[ok]
    assert np.all(Qok >= robot.lower - 1e-12) and np.all(Qok <= robot.upper + 1e-12)
    assert ok.mean() >= 0.99, f"success {ok.mean():.5f}"  # numeric dls, 20 restarts
