"""The full-IK section: one :func:`optik.solve_ik` call per (problem, target, solver)."""

from __future__ import annotations

from dataclasses import replace

from optik._checks import FloatArray
from optik.compare.config import RunConfig, ik_settings
from optik.compare.results import ResultRow, problem_row
from optik.ik import solve_ik
from optik.problems import Problem

__all__: list[str] = []


def _ik_row(
    problem: Problem,
    target_id: str,
    pose: FloatArray,
    solver: str,
    config: RunConfig,
    solve_seed: int,
) -> ResultRow:
    base = problem_row(
        "ik", problem, target_id, solver, ik_settings(config, solver), success=False, status="error"
    )
    try:
        result = solve_ik(
            problem.robot,
            pose,
            mode=config.mode,
            solver=solver,
            warm_start="analytic" if solver == "auto" else "q0",
            tol=config.tol,
            timeout_s=config.timeout_s,
            seed=solve_seed,
        )
    except Exception as exc:  # a crash is a row, not the end of the run
        return replace(base, message=f"{type(exc).__name__}: {exc}")
    return replace(
        base,
        success=bool(result.success),
        status=result.status,
        position_error=float(result.position_error),
        orientation_error=float(result.orientation_error),
        limit_violation=float(result.limit_violation),
        iterations=int(result.iterations),
        restarts=int(result.restarts),
        time_s=float(result.time_s),
        backend_converged=result.backend_converged,
        method=result.solver,
        message=result.message,
    )
