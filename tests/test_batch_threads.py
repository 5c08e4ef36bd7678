"""A batch split over worker threads gives the serial batch's answers, piece for piece."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.solvers._batch_threads import solve_batch
from optik.solvers._lm_kernel import lm_solve_batch_serial
from optik.solvers._seeds import seed_table
from optik.solvers.iterative import DLSSolver
from optik.task import make_task


@pytest.mark.parametrize("n", [0, 1, 33, 101])
@pytest.mark.parametrize("threads", [2, 3, 5])
def test_threads_change_no_answer(n: int, threads: int) -> None:
    robot = optik.load_problem("puma560").robot
    rng = np.random.default_rng(n)
    Q = rng.uniform(robot.lower, robot.upper, size=(n, robot.dof))
    targets = np.ascontiguousarray(robot.fk(Q).reshape(n, 4, 4))
    targets[::4, :3, 3] += 0.3  # some targets off the arm's reach of their orientation
    job = (
        targets,
        make_task().packed,
        np.empty((1, 0, robot.dof)),
        seed_table(robot).kernel_args(),
        (100, DLSSolver.w_bias, 2),
        np.arange(n, dtype=np.int64) + 7,
    )
    chain = robot.chain.kernel_args()
    serial = lm_solve_batch_serial(chain, job)
    threaded = solve_batch(chain, job, threads)
    for a, b in zip(serial, threaded, strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)
    # the answers are real: every target flagged ok is within tolerance by FK
    for k in np.flatnonzero(threaded[3]):
        F = robot.fk(threaded[0][k])
        assert np.linalg.norm(F[:3, 3] - targets[k, :3, 3]) <= 1e-6
