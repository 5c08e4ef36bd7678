"""The ``casadi:*`` IK solvers take the whole task: modes, weights, frozen joints, margins.

Targets are reachable by construction (FK of a random configuration inside the bounds; for
``axis`` the FK pose turned by a random roll about the tool axis), and every answer is
re-verified here from FK with errors computed in this file (not read from the result):
the position error over the constrained target axes, the rotation angle of ``R*^T R`` or
the angle between the tool axis and the target's, the bounds (narrowed by the margin, a
frozen joint exactly at its value). The programs run on CasADi's interpreted functions
(``OPTIK_NO_CODEGEN``), which give the compiled functions' answers
(``tests/test_casadi_codegen.py``) without a compile per robot and task shape.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from conftest import SEED, robot_of

import optik
from optik.model import Robot

ROBOTS = ("panda", "ur5", "puma560")
SOLVERS = ("casadi:sqpmethod", "casadi:ipopt")
TOL = 1e-6
TASKS: dict[str, dict[str, Any]] = {
    "pose": {"mode": "pose"},
    "position": {"mode": "position"},
    "orientation": {"mode": "orientation"},
    "axis_z": {"mode": "axis", "axis": "z"},
    "axis_x": {"mode": "axis", "axis": "x"},
    "free_depth": {"weights": [1.0, 1.0, 0.0, 1.0, 1.0, 1.0]},  # insertion along target z
    "weighted": {"weights": [2.0, 1.0, 0.5, 1.0, 3.0, 0.2]},
}
SHORT = 2
LONG = 25


@pytest.fixture(autouse=True, scope="module")
def _interpreted() -> Iterator[None]:
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("OPTIK_NO_CODEGEN", "1")
        yield


def _roll(k: int, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about coordinate axis ``k`` (numpy only)."""
    c, s = math.cos(angle), math.sin(angle)
    i, j = (k + 1) % 3, (k + 2) % 3
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def _angle(R: np.ndarray) -> float:
    """Rotation angle of ``R`` (atan2 of the skew part's norm and the trace)."""
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return math.atan2(float(np.linalg.norm(v)) / 2.0, (float(np.trace(R)) - 1.0) / 2.0)


def _task_weights(kw: dict[str, Any]) -> np.ndarray:
    """The weights a task keyword set means (the modes' shortcuts written out)."""
    if "weights" in kw:
        return np.asarray(kw["weights"], dtype=float)
    w = np.ones(6)
    mode = kw.get("mode", "pose")
    if mode == "position":
        w[3:] = 0.0
    elif mode == "orientation":
        w[:3] = 0.0
    elif mode == "axis":
        w[3 + "xyz".index(kw.get("axis", "z"))] = 0.0
    return w


def _target(robot: Robot, q: np.ndarray, kw: dict[str, Any], rng: np.random.Generator) -> Any:
    T = robot.fk(q)
    if kw.get("mode") == "axis":
        T = T.copy()
        T[:3, :3] = T[:3, :3] @ _roll("xyz".index(kw["axis"]), rng.uniform(-math.pi, math.pi))
    return T


def _check(
    robot: Robot,
    q: np.ndarray,
    T_target: np.ndarray,
    kw: dict[str, Any],
    lower: np.ndarray,
    upper: np.ndarray,
) -> None:
    """The answer ``q`` meets the task, from FK, inside ``[lower, upper]``."""
    assert q.shape == (robot.dof,) and np.all(np.isfinite(q))
    assert np.all(q >= lower) and np.all(q <= upper), (q - lower, upper - q)
    w = _task_weights(kw)
    T = robot.fk(q)
    R_t = T_target[:3, :3]
    d = R_t.T @ (T[:3, 3] - T_target[:3, 3])
    assert float(np.linalg.norm(d[w[:3] > 0.0])) <= TOL, d
    zeros = [i for i in range(3) if w[3 + i] == 0.0]
    if len(zeros) == 0:
        assert _angle(R_t.T @ T[:3, :3]) <= TOL
    elif len(zeros) == 1:
        a, b = T[:3, zeros[0]], R_t[:, zeros[0]]
        assert math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b)) <= TOL


def _run_tasks(name: str, solver: str, task: str, count: int) -> None:
    robot = robot_of(name)
    kw = TASKS[task]
    rng = np.random.default_rng([SEED, ROBOTS.index(name), list(TASKS).index(task)])
    for q_true in rng.uniform(robot.lower, robot.upper, (count, robot.dof)):
        T = _target(robot, q_true, kw, rng)
        res = optik.solve_ik(robot, T, solver=solver, tol=TOL, **kw)
        assert res.success, (name, solver, task, res.status, res.message)
        _check(robot, res.q, T, kw, robot.lower, robot.upper)


@pytest.mark.parametrize("task", list(TASKS))
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("name", ROBOTS)
def test_every_task_is_solved(name: str, solver: str, task: str) -> None:
    _run_tasks(name, solver, task, SHORT)


@pytest.mark.slow
@pytest.mark.parametrize("task", list(TASKS))
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("name", ROBOTS)
def test_every_task_is_solved_many_targets(name: str, solver: str, task: str) -> None:
    _run_tasks(name, solver, task, LONG)


def _run_bounds(name: str, solver: str, task: str, count: int) -> None:
    """Frozen joints (the second and the last) and a limit margin on the others."""
    robot = robot_of(name)
    kw = TASKS[task]
    rng = np.random.default_rng([SEED, 7, ROBOTS.index(name), list(TASKS).index(task)])
    margin = 0.05
    names = robot.joint_names
    for _ in range(count):
        lower, upper = robot.lower + margin, robot.upper - margin
        q_true = rng.uniform(lower, upper)
        frozen = {names[1]: float(q_true[1]), names[-1]: float(q_true[-1])}
        lower[[1, -1]] = upper[[1, -1]] = q_true[[1, -1]]
        T = _target(robot, q_true, kw, rng)
        res = optik.solve_ik(
            robot, T, solver=solver, tol=TOL, frozen=frozen, limit_margin=margin, **kw
        )
        assert res.success, (name, solver, task, res.status, res.message)
        assert res.q[1] == frozen[names[1]] and res.q[-1] == frozen[names[-1]]
        _check(robot, res.q, T, kw, lower, upper)


@pytest.mark.parametrize("task", ["pose", "position", "axis_z", "free_depth"])
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("name", ROBOTS)
def test_frozen_joints_and_limit_margin(name: str, solver: str, task: str) -> None:
    _run_bounds(name, solver, task, SHORT)


@pytest.mark.slow
@pytest.mark.parametrize("task", ["pose", "position", "axis_z", "free_depth"])
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("name", ROBOTS)
def test_frozen_joints_and_limit_margin_many_targets(name: str, solver: str, task: str) -> None:
    _run_bounds(name, solver, task, LONG)


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_margin_keeps_the_answer_off_a_limit_it_would_touch(solver: str) -> None:
    """A target reached with joint 1 at its upper limit: with a margin, q[0] stays inside."""
    robot = robot_of("puma560")
    q_true = robot.mid_limits + 0.2
    q_true[0] = robot.upper[0]
    T = robot.fk(q_true)
    margin = 0.1
    res = optik.solve_ik(robot, T, solver=solver, mode="position", limit_margin=margin)
    assert res.success, res.message
    _check(robot, res.q, T, {"mode": "position"}, robot.lower + margin, robot.upper - margin)
