"""The closed-form section: differential-IK step programs against the closed forms.

Each :class:`StepCase` is one step program (least norm, least squares, damped least
squares) at an in-limit configuration, with the answer of :func:`optik.min_norm` /
:func:`optik.least_squares`; a backend (:mod:`optik.compare.backends`) solves the program
and the row records how far its answer is from the closed form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Final

import numpy as np

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt
from optik.compare.backends import solve_step
from optik.compare.results import ResultRow, problem_row, settings_json
from optik.compare.targets import _stable_id, random_configurations
from optik.linalg import least_squares, min_norm
from optik.model import Robot
from optik.problems import Problem
from optik.solvers._base import now

__all__ = ["AGREEMENT_TOL", "StepCase", "closed_form_cases"]

#: Largest deviation ``max |dq - dq*|`` (rad or m) of a step program's answer from the
#: closed form for the row to count as agreeing (design.md §5: "to 1e-8").
AGREEMENT_TOL: Final[float] = 1e-8


@dataclass(frozen=True)
class StepCase:
    """One differential-IK step program with its closed-form answer.

    Attributes:
        target: row id, ``c{config}-{task}-{objective}[-damped]``.
        q: configuration (dof,), rad / m.
        task: ``"position"`` (Jacobian rows 0-2) or ``"pose"`` (all six rows).
        objective: ``"least_norm"`` or ``"least_squares"``.
        damping: ``lambda`` of least squares (0: undamped).
        v: task displacement (m,), scaled so that the answer stays at most half way to
            every bound (the limits are in the program but inactive).
        reference: the closed form's answer ``dq*`` (dof,).
        method: ``"min_norm"`` or ``"least_squares"``.
    """

    target: str
    q: FloatArray
    task: str
    objective: str
    damping: float
    v: FloatArray
    reference: FloatArray
    method: str

    @property
    def rows(self) -> tuple[int, ...]:
        """Indices of the Jacobian rows of the task."""
        return (0, 1, 2) if self.task == "position" else (0, 1, 2, 3, 4, 5)

    def settings(self, seed: int) -> str:
        """The settings JSON of the case's rows."""
        return settings_json(
            {
                "damping": self.damping,
                "limits": "inactive",
                "objective": self.objective,
                "seed": seed,
                "task": self.task,
            }
        )

    def program(self, robot: Robot) -> Any:
        """The step program (:class:`optik.programs.diff_qp.DiffIKProgram`)."""
        from optik.programs.diff_qp import build_program

        return build_program(
            robot,
            self.q,
            self.v,
            objective=self.objective,  # type: ignore[arg-type]
            damping=self.damping if self.objective == "least_squares" else None,
            rows=self.rows,
        )


#: Largest 2-norm condition number of a configuration's task Jacobian in the closed-form
#: section (configurations near a singularity are redrawn: the comparison is about the
#: backends, not about ill-conditioning).
_MAX_CONDITION: Final[float] = 1e4

#: Size of the closed form's answer before the scaling that keeps the bounds inactive.
_STEP_SIZE: Final[float] = 0.05


def closed_form_cases(
    robot: Robot, name: str, count: int, seed: int, damping: float | None = None
) -> list[StepCase]:
    """The closed-form section's programs for one robot.

    For ``count`` configurations drawn inside the limits (10 % away from each limit, task
    Jacobians with condition number at most 1e4) and each task (position, pose) with
    Jacobian rows ``J`` (m, dof): least norm against :func:`optik.min_norm` when
    ``m <= dof``; undamped least squares against :func:`optik.least_squares` when
    ``m >= dof``; always damped least squares (``lambda`` = the programs' default) against
    ``least_squares(J, v, damping=lambda)``. ``v`` is random and scaled so that
    ``max |dq*| = 0.05`` and then to at most half the distance to every bound.

    Args:
        robot: the robot.
        name: its problem name (part of the seed).
        count: number of configurations.
        seed: the run's seed.
        damping: ``lambda`` of the damped case (default: the programs' default).
    """
    if damping is None:
        try:
            from optik.programs.diff_qp import DEFAULT_DAMPING
        except ImportError:
            return []
        damping = DEFAULT_DAMPING
    from optik.programs.diff_qp import step_bounds

    cases: list[StepCase] = []
    draws = random_configurations(robot, f"{name}/closed_form", 50 * max(count, 1), seed, 0.1)
    rng = np.random.default_rng([seed, _stable_id(name), 7])
    used = 0
    for q in draws:
        if used == count:
            break
        J6 = robot.jacobian(q)
        tasks = [("position", J6[:3]), ("pose", J6)]
        if any(np.linalg.cond(_nonzero_rows(J)) > _MAX_CONDITION for _, J in tasks):
            continue
        lower, upper = step_bounds(robot, q)
        for task, J in tasks:
            m, n = J.shape
            specs: list[tuple[str, float, str]] = []
            if m <= n:
                specs.append(("least_norm", 0.0, "min_norm"))
            if m >= n:
                specs.append(("least_squares", 0.0, "least_squares"))
            specs.append(("least_squares", float(damping), "least_squares"))
            for objective, lam, method in specs:
                if objective == "least_norm" and len(_nonzero_rows(J)) < m:
                    continue  # a zero row makes J dq = v infeasible for random v
                v = rng.normal(size=m)
                reference = _closed_form(J, v, method, lam)
                scale = _STEP_SIZE / max(float(np.max(np.abs(reference))), 1e-300)
                scale *= min(1.0, 0.5 * _room(reference * scale, lower, upper))
                v, reference = v * scale, _closed_form(J, v * scale, method, lam)
                suffix = "-damped" if lam > 0 else ""
                cases.append(
                    StepCase(
                        f"c{used:02d}-{task}-{objective}{suffix}",
                        q.copy(),
                        task,
                        objective,
                        lam,
                        v,
                        reference,
                        method,
                    )
                )
        used += 1
    return cases


def _nonzero_rows(J: FloatArray) -> FloatArray:
    """``J`` without its identically zero rows (a planar arm's out-of-plane rows)."""
    keep = np.any(np.abs(J) > 1e-12, axis=1)
    return J[keep]


def _closed_form(J: FloatArray, v: FloatArray, method: str, damping: float) -> FloatArray:
    if method == "min_norm":
        return np.asarray(min_norm(J, v), dtype=float)
    if damping > 0:
        return np.asarray(least_squares(J, v, damping=damping), dtype=float)
    return np.asarray(least_squares(_nonzero_rows(J), v[np.any(np.abs(J) > 1e-12, axis=1)]))


def _room(dq: FloatArray, lower: FloatArray, upper: FloatArray) -> float:
    """Largest factor ``s`` with ``lower <= s dq <= upper`` (bounds contain 0; may be inf)."""
    ratios = [math.inf]
    for d, lo, hi in zip(dq, lower, upper, strict=True):
        if d > 0 and math.isfinite(hi):
            ratios.append(hi / d)
        elif d < 0 and math.isfinite(lo):
            ratios.append(lo / d)
    return max(min(ratios), 0.0)


def _closed_form_row(
    problem: Problem, case: StepCase, backend: str, seed: int, program: Any
) -> ResultRow:
    settings = case.settings(seed)
    base = problem_row(
        "closed_form", problem, case.target, backend, settings, success=False, status="error"
    )
    base = replace(base, method=case.method)
    start = now()
    try:
        solution = solve_step(program, backend)
    except Exception as exc:  # a crash is a row, not the end of the run
        reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
        return replace(base, time_s=now() - start, message=f"{type(exc).__name__}: {exc}")
    elapsed = now() - start
    if solution.x is None or not np.all(np.isfinite(solution.x)):
        return replace(
            base,
            status="solver_failed",
            iterations=int(solution.iterations),
            time_s=elapsed,
            backend_converged=bool(solution.found),
            message=str(solution.status),
        )
    x = np.asarray(solution.x, dtype=float)
    deviation = float(np.max(np.abs(x - case.reference)))
    agrees = deviation <= AGREEMENT_TOL
    return replace(
        base,
        success=agrees,
        status="agrees" if agrees else "deviates",
        limit_violation=float(program.bound_violation(x)),
        iterations=int(solution.iterations),
        time_s=elapsed,
        backend_converged=bool(solution.found),
        deviation=deviation,
        message="" if solution.found else str(solution.status),
    )
