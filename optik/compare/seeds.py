"""The seed papers' examples, computed once (the report, the examples and the tests call these).

* Seed 001, the DOBOT chapter's Table 2: pseudoinverse vs Jacobian transpose iterations on
  a three-part path (:func:`dobot_chapter_rows`).
* Seed 003, the two-link example: ``q <- q + alpha J^+ (x* - x)`` with step 0.001 and
  tolerance 0.01 (:func:`planar_2r_example`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

import numpy as np

from optik._checks import FloatArray
from optik.compare.backends import seed_solver
from optik.compare.results import ResultRow, problem_row, settings_json
from optik.errors import OptikError
from optik.problems import Problem, load_problem
from optik.solvers import IKQuery
from optik.solvers._base import now
from optik.verify import verify_one

__all__ = [
    "CHAPTER_TABLE_2",
    "DOBOT_HOME",
    "SEED001_MAX_ITER",
    "SEED001_SOLVERS",
    "SEED003_Q0",
    "SEED003_STEPS",
    "dobot_chapter_rows",
    "planar_2r_example",
]

#: Iteration counts of the DOBOT chapter (seed 001, Table 2): (pseudoinverse, transpose).
CHAPTER_TABLE_2: Final[dict[str, tuple[int, int]]] = {
    "part1": (22, 55),
    "part2": (5, 34),
    "part3": (6, 68),
}

#: Start of the chapter's path: motor angles J1..J4 = 0 (rad), i.e. the rear arm vertical
#: and the forearm horizontal (the chapter does not print its start; this is our choice).
DOBOT_HOME: Final[tuple[float, ...]] = (0.0, 0.0, 0.0, 0.0)

#: Methods of the seed 001 section: the chapter's two, then damped least squares.
SEED001_SOLVERS: Final[tuple[str, ...]] = ("pinv", "transpose", "dls")

#: Iteration cap per part in the seed 001 section.
SEED001_MAX_ITER: Final[int] = 10_000

#: Seed 003's start (rad) and step sizes: the seed's 0.001, then the full step 1.
SEED003_Q0: Final[tuple[float, float]] = (0.5, 0.5)
SEED003_STEPS: Final[tuple[float, ...]] = (0.001, 1.0)


def _seed001_settings(tol: float, max_iter: int) -> str:
    return settings_json(
        {
            "chain": "part1>part2>part3",
            "max_iter": max_iter,
            "mode": "position",
            "start_rad": list(DOBOT_HOME),
            "tol": tol,
        }
    )


def _seed003_settings(alpha: float, q0: FloatArray, tol: float) -> str:
    return settings_json({"mode": "position", "q0": q0.tolist(), "step": alpha, "tol": tol})


def _position_row(
    kind: str,
    problem: Problem,
    target_id: str,
    solver: str,
    settings: str,
    q: FloatArray,
    *,
    iterations: int,
    time_s: float,
    converged: bool,
    method: str,
    message: str = "",
    check_limits: bool = False,
) -> ResultRow:
    """A position-only row verified from FK: success is ``||p(q) - p*|| <= tol`` (m).

    With ``check_limits`` the limits must also hold (violation at most 1e-12); the
    backend's ``message`` is kept only for a failure.
    """
    robot = problem.robot
    target = problem.targets[target_id]
    position, _, violation, within = verify_one(robot, q, target.pose, "position", target.tolerance)
    ok = within or (not check_limits and position <= target.tolerance)
    return problem_row(
        kind,
        problem,
        target_id,
        solver,
        settings,
        success=ok,
        status="converged" if ok else "max_iter",
        position_error=position,
        orientation_error=0.0,
        limit_violation=violation,
        iterations=iterations,
        restarts=0,
        time_s=time_s,
        backend_converged=converged,
        method=method,
        message=message if not ok else "",
    )


def dobot_chapter_rows(
    problem: Problem | None = None,
    solvers: Sequence[str] = SEED001_SOLVERS,
    max_iter: int = SEED001_MAX_ITER,
) -> list[ResultRow]:
    """Seed 001's Table 2 rebuilt: iterations per method along the three-part path.

    Each method starts at :data:`DOBOT_HOME` and goes through the targets ``part1``,
    ``part2``, ``part3`` of ``problems/dobot_magician.toml`` in sequence, each part
    starting where the previous one ended; position only, accepted error 0.2 mm (the
    targets' tolerance). ``pinv`` is :class:`~optik.solvers.iterative.PinvSolver` (unit
    step), ``transpose`` is :class:`~optik.solvers.iterative.TransposeSolver` (the optimal
    scalar step); ``dls`` (damped least squares, which the chapter names as its next step)
    is added beyond the chapter.

    Args:
        problem: the DOBOT problem (default: the built-in one).
        solvers: methods, among ``pinv``, ``transpose``, ``dls``.
        max_iter: iteration cap per part.

    Returns:
        One ``seed001`` row per (part, method), ``iterations`` being the exact count.
    """
    problem = problem or load_problem("dobot_magician")
    robot = problem.robot
    rows: list[ResultRow] = []
    for name in solvers:
        solver = seed_solver(name)
        q = np.array(DOBOT_HOME, dtype=float)
        for part in CHAPTER_TABLE_2:
            target = problem.targets[part]
            query = IKQuery(robot, target.pose, "position", target.tolerance)
            settings = _seed001_settings(target.tolerance, max_iter)
            start = now()
            out = solver.solve(query, q, max_iter, math.inf)
            elapsed = now() - start
            rows.append(
                _position_row(
                    "seed001",
                    problem,
                    part,
                    name,
                    settings,
                    out.q,
                    iterations=int(out.iterations),
                    time_s=elapsed,
                    converged=bool(out.converged),
                    method=name,
                    message=out.message,
                    check_limits=True,
                )
            )
            q = out.q
    return rows


def planar_2r_example(
    problem: Problem | None = None,
    steps: Sequence[float] = SEED003_STEPS,
    max_iter: int = 100_000,
) -> tuple[list[ResultRow], FloatArray]:
    """Seed 003's two-link example: ``q <- q + alpha J^+ (x* - x)`` from q = (0.5, 0.5) rad.

    Unit links, target (1.2, 1.3) m, stop when ``||x* - x|| < 0.01`` m. The seed's step
    ``alpha = 0.001`` is run one step at a time to record the trajectory; ``alpha = 1``
    (the full pseudoinverse step) is run beside it for contrast.

    Args:
        problem: the planar 2R problem (default: the built-in ``planar_2r``).
        steps: the values of ``alpha``; the first one's trajectory is returned.
        max_iter: iteration cap.

    Returns:
        The ``seed003`` rows (one per step size) and the first step's trajectory (K, 2),
        rad: ``q0`` then the joint vector after every iteration.
    """
    if not steps:
        raise OptikError("planar_2r_example needs at least one step size")
    problem = problem or load_problem("planar_2r")
    robot = problem.robot
    target = problem.targets["seed003"]
    q0 = np.array(SEED003_Q0)
    rows: list[ResultRow] = []
    first: FloatArray | None = None
    for alpha in steps:
        solver = seed_solver("pinv", step=alpha)
        query = IKQuery(robot, target.pose, "position", target.tolerance)
        trajectory = [q0]
        q = q0
        iterations = 0
        start = now()
        converged = False
        while iterations < max_iter:
            out = solver.solve(query, q, 1, math.inf)
            iterations += out.iterations
            q = out.q
            if out.iterations:
                trajectory.append(q)
            if out.converged:
                converged = True
                break
        elapsed = now() - start
        settings = _seed003_settings(alpha, q0, target.tolerance)
        rows.append(
            _position_row(
                "seed003",
                problem,
                "seed003",
                "pinv",
                settings,
                q,
                iterations=iterations,
                time_s=elapsed,
                converged=converged,
                method=f"pinv, step {alpha:g}",
            )
        )
        if first is None:
            first = np.array(trajectory)
    return rows, first if first is not None else np.array([q0])
