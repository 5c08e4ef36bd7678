"""Summaries of the raw table, after ``qpsolvers/qpbenchmark``.

Success rate, shifted geometric mean of the time (failures counted at the time limit,
normalised so the best solver scores 1), error percentiles and accuracy levels per
(problem, solver); agreement per step-program backend; seed 001's table beside ours.
Every definition is in ``docs/report.md``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Final

import numpy as np

from optik.compare import CHAPTER_TABLE_2, ResultRow
from optik.limits import LIMIT_TOLERANCE

__all__ = [
    "ACCURACY_LEVELS",
    "CLOSED_FORM_KINDS",
    "SGM_SHIFT_S",
    "ChapterComparison",
    "ClosedFormSummary",
    "SolverSummary",
    "shifted_geometric_mean",
    "summarize_closed_form",
    "summarize_ik",
    "summarize_seed001",
]

#: Shift of the shifted geometric mean of times, s (10 ms: small against the time limits
#: used, large against the sub-millisecond closed forms, so those do not dominate).
SGM_SHIFT_S: Final[float] = 0.010

#: Tolerances of the accuracy profile: position (m) and orientation (rad) errors.
ACCURACY_LEVELS: Final[tuple[float, ...]] = (1e-3, 1e-6, 1e-9)


def shifted_geometric_mean(times_s: Sequence[float], shift_s: float = SGM_SHIFT_S) -> float:
    """``exp(mean(log(t + shift))) - shift``, s (nan for no times)."""
    t = np.asarray(times_s, dtype=float)
    if t.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(t + shift_s))) - shift_s)


def _percentile(values: Sequence[float], q: float) -> float:
    a = np.asarray([v for v in values if v is not None], dtype=float)
    return float(np.percentile(a, q)) if a.size else math.nan


def _worst_error(row: ResultRow) -> float:
    """``max(position error, orientation error)``; inf when the row has no errors."""
    if row.position_error is None or row.orientation_error is None:
        return math.inf
    return max(row.position_error, row.orientation_error)


def _within(row: ResultRow, level: float) -> bool:
    violation = row.limit_violation if row.limit_violation is not None else math.inf
    return _worst_error(row) <= level and violation <= LIMIT_TOLERANCE


@dataclass(frozen=True)
class SolverSummary:
    """The full-IK summary of one solver on one problem (``problem == "all"``: every problem).

    Attributes:
        problem: problem name, or ``"all"``.
        solver: solver name.
        n: targets run.
        success_rate: fraction verified successful by optik.
        claims: rows where the solver made a convergence claim.
        claims_disagree: rows where that claim differs from optik's verification.
        time_median_s: median wall time over every target, failures included, s.
        time_p95_s: 95th percentile of the same times (linear interpolation), s.
        sgm_s: shifted geometric mean of the time (shift :data:`SGM_SHIFT_S`), each failure
            counted at the time limit, s.
        sgm_normalised: ``sgm_s`` divided by the smallest ``sgm_s`` of the same problem (the
            best solver scores 1.0).
        position_error_p50: median position error, m.
        position_error_p95: 95th percentile of the position error, m.
        position_error_max: largest position error, m.
        orientation_error_p50: median orientation error, rad.
        orientation_error_p95: 95th percentile, rad.
        orientation_error_max: largest, rad.
        iterations_median: median iterations (all attempts) over the rows that report them
            (nan when none does: a backend without a count writes -1).
        iterations_p95: 95th percentile of the same iterations.
        accuracy: fraction of targets whose position (m) and orientation (rad) errors are
            both within each level of :data:`ACCURACY_LEVELS`, limits respected.
    """

    problem: str
    solver: str
    n: int
    success_rate: float
    claims: int
    claims_disagree: int
    time_median_s: float
    time_p95_s: float
    sgm_s: float
    sgm_normalised: float
    position_error_p50: float
    position_error_p95: float
    position_error_max: float
    orientation_error_p50: float
    orientation_error_p95: float
    orientation_error_max: float
    iterations_median: float
    iterations_p95: float
    accuracy: dict[str, float] = field(default_factory=dict)

    def flat(self) -> dict[str, Any]:
        """The summary as one flat record (``accuracy_1e-06`` etc.), for CSV and JSON."""
        data = asdict(self)
        accuracy = data.pop("accuracy")
        data.update({f"accuracy_{k}": v for k, v in accuracy.items()})
        return data


def _level_name(level: float) -> str:
    return f"{level:.0e}"


def _summary(problem: str, solver: str, rows: Sequence[ResultRow], time_limit_s: float) -> Any:
    times = [r.time_s for r in rows]
    charged = [r.time_s if r.success else time_limit_s for r in rows]
    claims = [r for r in rows if r.backend_converged is not None]
    position = [r.position_error for r in rows if r.position_error is not None]
    orientation = [r.orientation_error for r in rows if r.orientation_error is not None]
    # -1 means "not reported" (ikpy, EAIK, pybullet): a count, not a value to take a median of.
    counted = [r.iterations for r in rows if r.iterations is not None and r.iterations >= 0]
    iterations = [float(i) for i in counted]
    return {
        "problem": problem,
        "solver": solver,
        "n": len(rows),
        "success_rate": sum(r.success for r in rows) / len(rows),
        "claims": len(claims),
        "claims_disagree": sum(r.backend_converged != r.success for r in claims),
        "time_median_s": _percentile(times, 50),
        "time_p95_s": _percentile(times, 95),
        "sgm_s": shifted_geometric_mean(charged),
        "position_error_p50": _percentile(position, 50),
        "position_error_p95": _percentile(position, 95),
        "position_error_max": max(position, default=math.nan),
        "orientation_error_p50": _percentile(orientation, 50),
        "orientation_error_p95": _percentile(orientation, 95),
        "orientation_error_max": max(orientation, default=math.nan),
        "iterations_median": _percentile(iterations, 50),
        "iterations_p95": _percentile(iterations, 95),
        "accuracy": {
            _level_name(level): sum(_within(r, level) for r in rows) / len(rows)
            for level in ACCURACY_LEVELS
        },
    }


def summarize_ik(
    rows: Iterable[ResultRow], time_limit_s: float, *, overall: bool = True
) -> list[SolverSummary]:
    """Per (problem, solver) summaries of ``ik`` rows, then per solver over all problems.

    Args:
        rows: rows of the raw table (other kinds are ignored).
        time_limit_s: the time charged to a failure in the shifted geometric mean, s.
        overall: append one ``problem="all"`` summary per solver.

    Returns:
        Summaries in the order problems and solvers first appear in ``rows``.
    """
    groups: dict[tuple[str, str], list[ResultRow]] = {}
    for row in rows:
        if row.kind == "ik":
            groups.setdefault((row.problem, row.solver), []).append(row)
    records = [_summary(p, s, g, time_limit_s) for (p, s), g in groups.items()]
    if overall and groups:
        by_solver: dict[str, list[ResultRow]] = {}
        for (_, solver), group in groups.items():
            by_solver.setdefault(solver, []).extend(group)
        records += [_summary("all", s, g, time_limit_s) for s, g in by_solver.items()]
    best: dict[str, float] = {}
    for record in records:
        if math.isfinite(record["sgm_s"]):
            best[record["problem"]] = min(best.get(record["problem"], math.inf), record["sgm_s"])
    return [
        SolverSummary(**record, sgm_normalised=record["sgm_s"] / best[record["problem"]])
        for record in records
    ]


@dataclass(frozen=True)
class ClosedFormSummary:
    """How one step-program backend agrees with the closed forms.

    Attributes:
        backend: ``qp:<name>`` or ``casadi:<plugin>``.
        cases: programs solved.
        agree: programs whose answer is within :data:`~optik.compare.AGREEMENT_TOL`.
        max_deviation: largest ``max |dq - dq*|`` per program kind (``least_norm``,
            ``least_squares``, ``least_squares_damped``), rad or m; nan when none ran.
        claims_disagree: programs where the backend's "found" differs from the agreement.
        failures: programs without an answer (backend failure or error).
        time_median_s: median solve time, s.
    """

    backend: str
    cases: int
    agree: int
    max_deviation: dict[str, float]
    claims_disagree: int
    failures: int
    time_median_s: float


CLOSED_FORM_KINDS: Final[tuple[str, ...]] = (
    "least_norm",
    "least_squares",
    "least_squares_damped",
)


def _program_kind(row: ResultRow) -> str:
    settings = json.loads(row.settings)
    damped = "_damped" if settings.get("damping", 0.0) > 0 else ""
    return f"{settings['objective']}{damped}"


def summarize_closed_form(rows: Iterable[ResultRow]) -> list[ClosedFormSummary]:
    """One summary per backend of the ``closed_form`` rows, in order of appearance."""
    groups: dict[str, list[ResultRow]] = {}
    for row in rows:
        if row.kind == "closed_form":
            groups.setdefault(row.solver, []).append(row)
    out = []
    for backend, group in groups.items():
        worst: dict[str, float] = {}
        for kind in CLOSED_FORM_KINDS:
            values = [
                r.deviation if r.deviation is not None else math.inf
                for r in group
                if _program_kind(r) == kind
            ]
            worst[kind] = max(values) if values else math.nan
        claims = [r for r in group if r.backend_converged is not None]
        out.append(
            ClosedFormSummary(
                backend=backend,
                cases=len(group),
                agree=sum(r.success for r in group),
                max_deviation=worst,
                claims_disagree=sum(r.backend_converged != r.success for r in claims),
                failures=sum(r.deviation is None for r in group),
                time_median_s=_percentile([r.time_s for r in group], 50),
            )
        )
    return out


@dataclass(frozen=True)
class ChapterComparison:
    """Seed 001's Table 2 beside ours.

    Attributes:
        parts: ``{part: {"chapter_pinv", "chapter_transpose", <solver>: iterations}}``.
        finding_holds: the chapter's finding (the pseudoinverse needs fewer iterations than
            the transpose) holds in every part of our run.
        all_converged: every part of our run met the 0.2 mm tolerance.
    """

    parts: dict[str, dict[str, int]]
    finding_holds: bool
    all_converged: bool


def summarize_seed001(rows: Iterable[ResultRow]) -> ChapterComparison | None:
    """Our iterations per part and method beside the chapter's (None without rows)."""
    ours = [r for r in rows if r.kind == "seed001"]
    if not ours:
        return None
    parts: dict[str, dict[str, int]] = {}
    for part, (pinv, transpose) in CHAPTER_TABLE_2.items():
        parts[part] = {"chapter_pinv": pinv, "chapter_transpose": transpose}
    for row in ours:
        parts.setdefault(row.target, {})[row.solver] = int(row.iterations or 0)
    holds = all(
        "pinv" in p and "transpose" in p and p["pinv"] < p["transpose"] for p in parts.values()
    )
    return ChapterComparison(parts, holds, all(r.success for r in ours))
