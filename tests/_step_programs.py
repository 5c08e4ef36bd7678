"""Step programs with known answers, shared by the QP and CasADi conic backend tests.

With the limits inactive the answers equal the closed forms (optik.linalg and
numpy.linalg.pinv); with limits active the bounds and the KKT conditions (multipliers
computed here from the active set) decide.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from conftest import SEED, assert_close, random_q, robot_of

from optik.linalg import least_squares, min_norm
from optik.model import Robot
from optik.programs.diff_qp import DEFAULT_DAMPING, DiffIKProgram, QPSolution, build_program
from optik.solvers import IKQuery, get_solver
from optik.spatial import rotation_angle

#: Accuracy each backend reaches against the closed forms (docs/programs.md, measured);
#: every installed backend reaches the 1e-8 that design.md asks for.
ACCURACY = 1e-8

#: Task rows for the least-norm program: full row rank at generic q.
LEAST_NORM_ROWS: dict[str, tuple[int, ...] | None] = {
    "planar_2r": (0, 1),  # a planar arm: rows 2-4 of its 6x2 Jacobian are zero
    "jumbo_spherical_arm": (0, 1, 2),  # 3 joints: position only
    "dobot_magician": (0, 1, 2, 5),  # 4 joints: position and yaw (the tool stays level)
}
#: Arms whose 6xdof Jacobian is tall with full column rank: undamped least squares.
TALL = ("planar_2r", "jumbo_spherical_arm", "dobot_magician")


# ---------------------------------------------------------------------- shared helpers
@dataclass(frozen=True)
class Case:
    """A robot, a configuration and a small task displacement."""

    name: str
    robot: Robot
    q: np.ndarray
    v6: np.ndarray


def well_conditioned_q(robot: Robot, rows: tuple[int, ...] | None, rng: np.random.Generator):
    """A configuration in the middle 40% of each range where ``J[rows]`` has cond < 50."""
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    for _ in range(1000):
        q = lo + (hi - lo) * rng.uniform(0.3, 0.7, robot.dof)
        J = robot.jacobian(q)[list(rows) if rows else slice(None)]
        if np.linalg.cond(J) < 50.0:
            return q
    raise AssertionError("no well-conditioned configuration found")


def inactive_cases(name: str, count: int = 3) -> list[Case]:
    """Configurations and displacements (1e-3 m / rad) far from every limit."""
    robot = robot_of(name)
    rng = np.random.default_rng(SEED)
    rows = LEAST_NORM_ROWS.get(name)
    return [
        Case(name, robot, well_conditioned_q(robot, rows, rng), 1e-3 * rng.normal(size=6))
        for _ in range(count)
    ]


def least_norm_program(case: Case) -> DiffIKProgram:
    rows = LEAST_NORM_ROWS.get(case.name)
    return build_program(case.robot, case.q, case.v6, rows=rows)


def least_squares_program(case: Case) -> tuple[DiffIKProgram, np.ndarray]:
    """The least-squares program on all six rows and its closed-form answer."""
    damping = 0.0 if case.name in TALL else DEFAULT_DAMPING
    prog = build_program(case.robot, case.q, case.v6, objective="least_squares", damping=damping)
    return prog, least_squares(prog.J, case.v6, damping=damping)


def assert_inactive(prog: DiffIKProgram, dq: np.ndarray) -> None:
    """The reference answer is well inside the bounds (so the limits are inactive)."""
    assert np.all(dq > prog.lower + 1e-3) and np.all(dq < prog.upper - 1e-3)


def check_least_norm(solve: Callable[[DiffIKProgram], QPSolution], case: Case) -> None:
    prog = least_norm_program(case)
    reference = min_norm(prog.J, prog.v)
    assert_close(reference, np.linalg.pinv(prog.J) @ prog.v, atol=1e-14, what="closed forms")
    assert_inactive(prog, reference)
    result = solve(prog)
    assert result.found, result.status
    assert_close(result.x, reference, atol=ACCURACY, what=f"{result.backend} least norm")


def check_least_squares(solve: Callable[[DiffIKProgram], QPSolution], case: Case) -> None:
    prog, reference = least_squares_program(case)
    if prog.damping == 0.0:
        expected = np.linalg.lstsq(prog.J, prog.v, rcond=None)[0]
    else:  # the damped closed form, by an orthogonal method: lstsq of [J; lambda I]
        n = prog.dof
        stacked = np.vstack([prog.J, prog.damping * np.eye(n)])
        expected = np.linalg.lstsq(stacked, np.concatenate([prog.v, np.zeros(n)]), rcond=None)[0]
    assert_close(reference, expected, atol=1e-12, what="closed forms")
    assert_inactive(prog, reference)
    result = solve(prog)
    assert result.found, result.status
    assert_close(result.x, reference, atol=ACCURACY, what=f"{result.backend} least squares")


def active_case(name: str, objective: str) -> tuple[DiffIKProgram, int]:
    """A program whose answer must stop at joint k's upper limit (k returned).

    ``q_k`` sits 1e-4 below its upper limit and ``v`` asks for a 1e-2 motion along joint
    k's column. Least norm uses task rows the other joints can still produce (``J``
    without column k of full row rank, and the program feasible by an LP), so the bound
    is active at a feasible answer: all six rows for the 7-joint arm, else the first of
    position, orientation, or position-and-yaw rows that allows it.
    """
    robot = robot_of(name)
    rng = np.random.default_rng(SEED + 1)
    if objective == "least_squares":
        candidates: list[tuple[int, ...] | None] = [None]
    elif robot.dof > 6:
        candidates = [(0, 1, 2, 3, 4, 5)]
    else:
        candidates = [(0, 1, 2), (3, 4, 5), (0, 1, 5)]
    for rows in candidates:
        pick = list(rows) if rows else slice(None)
        for _ in range(200):
            q = well_conditioned_q(robot, (0, 1, 2), rng)
            k = int(rng.integers(robot.dof))
            J = robot.jacobian(q)[pick]
            if not np.isfinite(robot.upper[k]) or np.linalg.norm(J[:, k]) < 0.1:
                continue
            if rows is not None and np.linalg.cond(np.delete(J, k, axis=1)) > 1e3:
                continue
            q[k] = robot.upper[k] - 1e-4
            J = robot.jacobian(q)[pick]
            v = 1e-2 * J[:, k] / np.linalg.norm(J[:, k]) + 1e-4 * rng.normal(size=J.shape[0])
            prog = build_program(robot, q, v, objective=objective, rows=rows)  # type: ignore[arg-type]
            if rows is not None and prog.min_task_violation() > 1e-12:
                continue  # the other joints cannot make up for joint k inside their bounds
            return prog, k
    raise AssertionError("no active-limit case found")


def own_kkt(prog: DiffIKProgram, dq: np.ndarray, tol: float = 1e-8) -> dict[str, float]:
    """KKT residuals at dq with multipliers computed here from the active set.

    Stationarity ``P dq + c + J^T y - z_l + z_u = 0``: ``y`` from the free rows (least
    norm: ``J_F^T y = -g_F``, unique because ``J_F`` has full row rank), then
    ``z_l = (g + J^T y)_i`` on the lower-active and ``z_u = -(g + J^T y)_i`` on the
    upper-active joints; signs must be >= 0 and ``z * slack = 0``. A bound is active within
    ``tol`` (1e-8: interior-point backends stop a few 1e-9 short of an active bound).
    Residuals are relative to the size of the gradient terms.
    """
    g = prog.P @ dq + prog.c
    at_lower = dq - prog.lower <= tol
    at_upper = prog.upper - dq <= tol
    free = ~(at_lower | at_upper)
    r = g.copy()
    if prog.objective == "least_norm":
        JF = prog.J[:, free]
        assert np.linalg.matrix_rank(JF) == prog.task_dim, "multipliers would not be unique"
        y = np.linalg.lstsq(JF.T, -g[free], rcond=None)[0]
        r = g + prog.J.T @ y
    z_lower = np.where(at_lower, r, 0.0)
    z_upper = np.where(at_upper, -r, 0.0)
    scale = (
        np.max(np.abs(prog.P)) * np.max(np.abs(dq))
        + np.max(np.abs(prog.c))
        + np.max(np.abs(prog.J)) * np.max(np.abs(prog.v))
    )
    residual = r - z_lower + z_upper
    slack_lower = np.where(np.isfinite(prog.lower), dq - prog.lower, 0.0)
    slack_upper = np.where(np.isfinite(prog.upper), prog.upper - dq, 0.0)
    return {
        "stationarity": float(np.max(np.abs(residual))) / scale,
        "sign": float(max(0.0, -z_lower.min(), -z_upper.min())) / scale,
        "complementarity": float(
            np.max(np.abs(z_lower * slack_lower) + np.abs(z_upper * slack_upper))
        )
        / scale,
        "active": float(at_lower.sum() + at_upper.sum()),
        "primal": float(
            max(
                prog.bound_violation(dq),
                np.max(np.abs(prog.task_residual(dq))) if prog.objective == "least_norm" else 0,
            )
        ),
    }


def check_active(solve: Callable[[DiffIKProgram], QPSolution], name: str, objective: str) -> None:
    prog, k = active_case(name, objective)
    result = solve(prog)
    assert result.found, result.status
    dq = result.x
    assert dq is not None
    assert prog.bound_violation(dq) <= 1e-9
    kkt = own_kkt(prog, dq)
    assert kkt["active"] >= 1, "the test case should hit a bound"
    assert abs(dq[k] - prog.upper[k]) <= 1e-8
    assert kkt["primal"] <= 1e-9, kkt
    assert kkt["stationarity"] <= 1e-6, kkt
    assert kkt["sign"] <= 1e-6, kkt
    assert kkt["complementarity"] <= 1e-8, kkt


# ---------------------------------------------------------------------- backends vs closed forms


#: Robots whose active-limit programs are checked against the KKT conditions.
KKT_ROBOTS = ("puma560", "panda", "ur5", "stanford_arm", "jumbo_drill_6dof", "dobot_magician")


def reach(solver_name: str, name: str, mode: str, count: int, spread: float = 0.1) -> None:
    """The solver reaches FK targets of random in-limit q from starts ``spread`` away."""
    robot = robot_of(name)
    rng = np.random.default_rng(SEED + 2)
    solver = get_solver(solver_name)
    for q_true in random_q(robot, rng, count):
        T = robot.fk(q_true)
        q0 = np.clip(q_true + spread * rng.normal(size=robot.dof), robot.lower, robot.upper)
        out = solver.solve(
            IKQuery(robot, T, mode, 1e-6), q0, solver.default_max_iter, time.perf_counter() + 30
        )
        assert not out.failed, out.message
        T_out = robot.fk(out.q)
        assert robot.within_limits(out.q, tol=0.0), "q left the limits"
        assert np.linalg.norm(T_out[:3, 3] - T[:3, 3]) <= 1e-6, out.message
        if mode == "pose":
            assert rotation_angle(T[:3, :3].T @ T_out[:3, :3]) <= 1e-6, out.message
        assert out.converged, out.message


# ---------------------------------------------------------------------- DOBOT least squares
#: A DOBOT least-squares step (dt = 1, default damping) where Clarabel once stopped 1.3e-8
#: (1.1e-7 relative) from the closed form: draw 790 of the sampler below with seed 5.
DOBOT_HARD_STEP = (
    np.array([0.8927700129576785, 0.01422893420122294, 1.5516780005398902, 1.2270455102847282]),
    np.array(
        [
            -0.00016017657841678598,
            -0.0003464764725530579,
            -0.0005587448433720898,
            0.0004134462134701967,
            -0.00015733765932735748,
            0.0010818338856911772,
        ]
    ),
)


def dobot_least_squares_steps(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """DOBOT steps: q uniform inside the limits, a 6-D twist of 1e-4 to 1e-2 (dt = 1).

    4 joints against 6 rows, so the twist is mostly outside the range of J; only steps
    whose damped closed form stays inside the limits are kept. The hard step above first.
    """
    robot = robot_of("dobot_magician")
    rng = np.random.default_rng(SEED + 5)
    steps = [DOBOT_HARD_STEP]
    while len(steps) < count:
        q = rng.uniform(robot.lower, robot.upper)
        twist = 10 ** rng.uniform(-4, -2) * rng.normal(size=6)
        dq = least_squares(robot.jacobian(q), twist, damping=DEFAULT_DAMPING)
        if np.all(q + dq > robot.lower) and np.all(q + dq < robot.upper):
            steps.append((q, twist))
    return steps


def check_dobot_least_squares(solve: Callable[[DiffIKProgram], QPSolution], count: int) -> None:
    """Every sampled DOBOT least-squares step equals its damped closed form to ACCURACY."""
    robot = robot_of("dobot_magician")
    for q, twist in dobot_least_squares_steps(count):
        prog = build_program(robot, q, twist, objective="least_squares", dt=1.0)
        reference = least_squares(prog.J, prog.v, damping=DEFAULT_DAMPING)
        n = prog.dof
        stacked = np.vstack([prog.J, DEFAULT_DAMPING * np.eye(n)])
        expected = np.linalg.lstsq(stacked, np.concatenate([prog.v, np.zeros(n)]), rcond=None)[0]
        assert_close(reference, expected, atol=1e-12, what="closed forms")
        result = solve(prog)
        assert result.found, result.status
        assert_close(result.x, reference, atol=ACCURACY, what=f"{result.backend} DOBOT step")
