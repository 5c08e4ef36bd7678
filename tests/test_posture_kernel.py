"""Posture: the compiled refinement and ``solve_ik(posture=...)``'s answers.

The program ``min 1/2 ||q - q_ref||_W^2 s.t. the task holds, limits (with limit_margin)
hard``. Every check here is independent of the code under test: the task is verified from
FK with numpy, and first-order optimality is the residual of projecting ``W (q - q_ref)``
onto the row space of the task's Jacobian, built from ``robot.jacobian`` (for a tool axis
``a = z*``: the position rows and the rotation rows ``x*^T J_w``, ``y*^T J_w``, since
``d(a . x*) = w . (a x x*) = w . y*``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import optik
from optik.posture import refine
from optik.problems import load_problem
from optik.solvers import IKQuery
from optik.spatial import rotation_angle
from optik.task import make_task

TOL = 1e-6

CASES = [
    ("panda", "pose", False, 0.0),
    ("panda", "axis", False, 0.0),
    ("panda", "pose", True, 0.1),
    ("panda", "axis", True, 0.0),
    ("ur5", "axis", False, 0.0),
]


def _weights(robot: optik.Robot, weighted: bool) -> np.ndarray:
    return np.linspace(0.5, 3.0, robot.dof) if weighted else np.ones(robot.dof)


def _task_verified(robot: optik.Robot, q: np.ndarray, T: np.ndarray, mode: str) -> bool:
    F = robot.fk(q)
    position = float(np.linalg.norm(F[:3, 3] - T[:3, 3]))
    if mode == "axis":
        a, b = F[:3, 2], T[:3, 2]
        orientation = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
    else:
        orientation = float(rotation_angle(F[:3, :3].T @ T[:3, :3]))
    return position <= TOL and orientation <= TOL


def _task_jacobian(robot: optik.Robot, q: np.ndarray, T: np.ndarray, mode: str) -> np.ndarray:
    J = robot.jacobian(q)
    if mode == "pose":
        return J
    x, y = T[:3, 0], T[:3, 1]
    return np.vstack([J[:3], x @ J[3:], y @ J[3:]])


def _optimality(
    robot: optik.Robot, q: np.ndarray, T: np.ndarray, mode: str, q_ref: np.ndarray, w: np.ndarray
) -> float:
    """``||g - A^T lam|| / ||g||``, ``g = W (q - q_ref)``, ``lam`` numpy's least squares."""
    A = _task_jacobian(robot, q, T, mode)
    g = w * (q - q_ref)
    lam = np.linalg.lstsq(A.T, g, rcond=None)[0]
    return float(np.linalg.norm(g - A.T @ lam) / np.linalg.norm(g))


def _band_slack(
    robot: optik.Robot,
    q: np.ndarray,
    T: np.ndarray,
    mode: str,
    q_ref: np.ndarray,
    w: np.ndarray,
    box: tuple[np.ndarray, np.ndarray] | None = None,
) -> float:
    """How much nearer ``q_ref`` a point of the tolerance band can be than ``q``.

    A plain answer lies anywhere within the tolerances (``TOL`` on each error), the refined
    one on the task (1e-9): moving across the band changes the residual by at most
    ``2 sqrt(2) TOL``, and the distance ``d = ||q - q_ref||_W`` to first order by
    ``lam^T de / d`` with ``lam`` the multipliers of ``W (q - q_ref) = A^T lam`` over the
    joints not on a bound of ``box`` (default: the limits).
    """
    lower, upper = (robot.lower, robot.upper) if box is None else box
    free = (q > lower + 1e-9) & (q < upper - 1e-9)
    A = _task_jacobian(robot, q, T, mode)[:, free]
    g = (w * (q - q_ref))[free]
    lam = np.linalg.lstsq(A.T, g, rcond=None)[0]
    d = math.sqrt(float((q - q_ref) @ (w * (q - q_ref))))
    return 3.0 * TOL * float(np.linalg.norm(lam)) / max(d, 1e-12) + 1e-9


def _inside(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> bool:
    return bool(np.all(q > lower + 1e-6) and np.all(q < upper - 1e-6))


def _box(robot: optik.Robot, margin: float) -> tuple[np.ndarray, np.ndarray]:
    return robot.lower + margin, robot.upper - margin


def _targets(robot: optik.Robot, n: int, seed: int, margin: float = 0.0) -> list[np.ndarray]:
    """FK poses of configurations drawn inside the limits less ``margin``: reachable."""
    rng = np.random.default_rng(seed)
    lower, upper = _box(robot, margin)
    return [robot.fk(rng.uniform(lower, upper)) for _ in range(n)]


@pytest.mark.parametrize(("name", "mode", "weighted", "margin"), CASES)
def test_refinement_reaches_first_order_optimality(
    name: str, mode: str, weighted: bool, margin: float
) -> None:
    """From verified plain answers the compiled refinement stops at an optimum (1e-9)."""
    robot = load_problem(name).robot
    w = _weights(robot, weighted)
    lower, upper = _box(robot, margin)
    rng = np.random.default_rng(5)
    task = make_task(mode, tol=TOL)
    inactive = 0
    for T in _targets(robot, 25, 6, margin):
        q_ref = rng.uniform(robot.lower, robot.upper)
        plain = optik.solve_ik(robot, T, mode=mode, limit_margin=margin)
        assert plain.success
        query = IKQuery(robot, T, mode, TOL, task, (lower, upper) if margin else None)
        out = refine(query, plain.q, q_ref, w)
        assert _task_verified(robot, out.q, T, mode)
        assert np.all(out.q >= lower) and np.all(out.q <= upper)
        d0, d1 = plain.q - q_ref, out.q - q_ref
        slack = _band_slack(robot, out.q, T, mode, q_ref, w, (lower, upper))
        assert math.sqrt(d1 @ (w * d1)) <= math.sqrt(d0 @ (w * d0)) + slack
        assert out.converged and out.measure <= 1e-9
        if _inside(out.q, lower, upper):
            inactive += 1
            assert _optimality(robot, out.q, T, mode, q_ref, w) <= 1e-6
    assert inactive >= 10


@pytest.mark.parametrize(("name", "mode", "weighted", "margin"), CASES)
def test_posture_answer_is_optimal_and_no_farther_than_100_solutions(
    name: str, mode: str, weighted: bool, margin: float
) -> None:
    robot = load_problem(name).robot
    w = _weights(robot, weighted)
    lower, upper = _box(robot, margin)
    rng = np.random.default_rng(17)
    for k, T in enumerate(_targets(robot, 8, 18, margin)):
        q_ref = robot.mid_limits if k % 2 else rng.uniform(lower, upper)
        res = optik.solve_ik(
            robot, T, mode=mode, posture=q_ref, joint_weights=w if weighted else None,
            limit_margin=margin,
        )  # fmt: skip
        assert res.success
        assert _task_verified(robot, res.q, T, mode)
        assert np.all(res.q >= lower) and np.all(res.q <= upper)
        if _inside(res.q, lower, upper):
            assert _optimality(robot, res.q, T, mode, q_ref, w) <= 1e-6
        distance = math.sqrt(float((res.q - q_ref) @ (w * (res.q - q_ref))))
        nearest = math.inf
        for seed in range(100):
            other = optik.solve_ik(robot, T, mode=mode, seed=seed, limit_margin=margin)
            if other.success and _task_verified(robot, other.q, T, mode):
                d = other.q - q_ref
                nearest = min(nearest, math.sqrt(float(d @ (w * d))))
        assert distance <= nearest + _band_slack(robot, res.q, T, mode, q_ref, w, (lower, upper))


def test_joints_pulled_past_a_limit_are_held_on_it() -> None:
    """A reference beyond the limits: the answer stops on them, still solving the task."""
    panda = load_problem("panda").robot
    w = np.ones(panda.dof)
    q_ref = panda.mid_limits.copy()
    q_ref[2] = panda.upper[2] + 1.0
    q_ref[4] = panda.lower[4] - 1.0
    on_bound = 0
    for T in _targets(panda, 8, 9):
        res = optik.solve_ik(panda, T, mode="axis", posture=q_ref)
        assert res.success and _task_verified(panda, res.q, T, "axis")
        assert np.all(res.q >= panda.lower) and np.all(res.q <= panda.upper)
        plain = optik.solve_ik(panda, T, mode="axis")
        d0, d1 = plain.q - q_ref, res.q - q_ref
        slack = _band_slack(panda, res.q, T, "axis", q_ref, w)
        assert math.sqrt(d1 @ (w * d1)) <= math.sqrt(d0 @ (w * d0)) + slack
        on_bound += bool(res.q[2] == panda.upper[2] or res.q[4] == panda.lower[4])
    assert on_bound >= 2


def test_frozen_joints_stay_and_the_rest_is_optimal() -> None:
    panda = load_problem("panda").robot
    name = panda.joint_names[6]
    rng = np.random.default_rng(23)
    for T in _targets(panda, 6, 24):
        frozen_q = rng.uniform(panda.lower, panda.upper)
        T = panda.fk(frozen_q)
        q_ref = rng.uniform(panda.lower, panda.upper)
        res = optik.solve_ik(
            panda, T, mode="axis", posture=q_ref, frozen={name: float(frozen_q[6])}
        )
        assert res.success and _task_verified(panda, res.q, T, "axis")
        assert res.q[6] == frozen_q[6]
        if _inside(res.q[:6], panda.lower[:6], panda.upper[:6]):
            A = _task_jacobian(panda, res.q, T, "axis")[:, :6]
            g = res.q[:6] - q_ref[:6]
            lam = np.linalg.lstsq(A.T, g, rcond=None)[0]
            assert np.linalg.norm(g - A.T @ lam) <= 1e-6 * np.linalg.norm(g)


def test_another_numeric_solver_gets_the_same_refinement() -> None:
    """``solver="pinv"`` collects its answers in Python; they are refined all the same."""
    panda = load_problem("panda").robot
    q_ref = panda.mid_limits
    w = np.ones(panda.dof)
    for T in _targets(panda, 4, 31):
        res = optik.solve_ik(panda, T, solver="pinv", posture=q_ref, restarts=30)
        assert res.success and res.solver == "pinv"
        assert _task_verified(panda, res.q, T, "pose")
        if _inside(res.q, panda.lower, panda.upper):
            assert _optimality(panda, res.q, T, "pose", q_ref, w) <= 1e-6
