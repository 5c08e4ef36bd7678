"""Solvers called from several threads at once: no crash, the answers of serial calls.

Each threaded run is a child process, so that a crash (the way a shared native solver
fails) is a failed test rather than a dead test worker.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import optik

_CHILD = r"""
import sys
from concurrent.futures import ThreadPoolExecutor
import numpy as np
import optik
solver = sys.argv[1]
robot = optik.load_problem("puma560").robot
rng = np.random.default_rng(0)
Q = rng.uniform(0.8 * robot.lower, 0.8 * robot.upper, size=(8, 6))
V = rng.normal(size=(8, 6)) * 0.1
def call(i):
    try:
        return optik.diff_ik(robot, Q[i % 8], V[i % 8], dt=0.01, solver=solver)
    except optik.OptikError as exc:
        return f"{type(exc).__name__}: {exc}"
serial = [call(i) for i in range(8)]
assert all(isinstance(s, np.ndarray) for s in serial), serial
with ThreadPoolExecutor(8) as pool:
    got = list(pool.map(call, range(96)))
bad = [
    g for i, g in enumerate(got)
    if isinstance(g, str) or not np.allclose(g, serial[i % 8], atol=1e-9)
]
print(len(bad), bad[:2])
sys.exit(3 if bad else 0)
"""


@pytest.mark.parametrize(
    "solver", [s for s in optik.available_solvers(kind="step") if s.startswith("casadi:")]
)
def test_diff_ik_with_a_casadi_conic_backend_from_eight_threads(solver: str) -> None:
    """One casadi.Function per plugin and shape was shared by every thread: daqp crashed
    10 of 10 processes, proxqp 6 of 10, the others raised spurious SolverErrors."""
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, solver], capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, (done.returncode, done.stdout[-500:], done.stderr[-1500:])


def test_qp_osqp_answers_do_not_depend_on_the_previous_solve() -> None:
    """OSQP's adaptive step size carried over from the thread's previous solve: the same
    call gave another answer (3.8e-15 serially, 5e-9 rad under threads)."""
    robot = optik.load_problem("puma560").robot
    rng = np.random.default_rng(0)
    targets = robot.fk(rng.uniform(robot.lower * 0.8, robot.upper * 0.8, size=(4, 6)))
    options = {"solver": "qp:osqp", "warm_start": "q0", "seed": 0}
    first = optik.solve_ik(robot, targets[0], **options)
    for other in targets[1:]:
        optik.solve_ik(robot, other, **options)
        again = optik.solve_ik(robot, targets[0], **options)
        assert np.array_equal(first.q, again.q)
        assert first.iterations == again.iterations
