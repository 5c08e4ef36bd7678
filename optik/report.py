"""Comparison reports: summaries, plots and documents built from the raw table.

:func:`make_report` runs (or resumes) a comparison with :func:`optik.compare.run`, then
reads the long table back and writes, each file whole (a temporary file renamed with
``os.replace``, so a reader never sees a partial file):

* ``results.csv`` — the raw table (written row by row during the run);
* ``summary.csv`` — one row per (problem, solver) of the full-IK section;
* ``summary.json`` — the configuration, the environment and every summary;
* ``summary.md`` — the summaries as Markdown;
* ``index.html`` — one self-contained page (figures embedded as base64 PNG);
* ``figures/*.png`` — the figures.

The summaries follow ``qpsolvers/qpbenchmark``: success rate, shifted geometric mean of
the time with failures counted at the time limit, normalised so the best solver scores 1;
see ``docs/report.md`` for every definition. :func:`add_report_command` adds the
``optik report`` subcommand to the ``optik`` command.
"""

from __future__ import annotations

import argparse
import base64
import csv
import datetime as _dt
import html
import importlib.metadata
import io
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np

from optik._checks import FloatArray
from optik._files import write_atomic
from optik.compare import (
    AGREEMENT_TOL,
    CHAPTER_TABLE_2,
    DOBOT_HOME,
    ResultRow,
    RunConfig,
    RunStats,
    run,
)
from optik.errors import OptikError
from optik.limits import LIMIT_TOLERANCE
from optik.plots import plot_planar_trajectory, pyplot
from optik.problems import builtin_problems, load_problem
from optik.solvers import available_solvers

__all__ = [
    "ACCURACY_LEVELS",
    "QUICK_PROBLEMS",
    "QUICK_SOLVERS",
    "SGM_SHIFT_S",
    "ClosedFormSummary",
    "Report",
    "SolverSummary",
    "add_report_command",
    "default_solvers",
    "environment",
    "make_report",
    "quick_config",
    "shifted_geometric_mean",
    "summarize_closed_form",
    "summarize_ik",
    "write_atomic",
]

#: Shift of the shifted geometric mean of times, s (10 ms: small against the time limits
#: used, large against the sub-millisecond closed forms, so those do not dominate).
SGM_SHIFT_S: Final[float] = 0.010

#: Tolerances of the accuracy profile: position (m) and orientation (rad) errors.
ACCURACY_LEVELS: Final[tuple[float, ...]] = (1e-3, 1e-6, 1e-9)

#: Errors below this are drawn at it on log axes (exact answers have error 0).
_ERROR_FLOOR: Final[float] = 1e-16

#: ``--quick``: robots, solvers (those installed are used, in this order), targets per
#: robot, timeout, and caps on solvers that are slow when they fail.
QUICK_PROBLEMS: Final[tuple[str, ...]] = ("dobot_magician", "puma560", "ur5", "panda")
QUICK_SOLVERS: Final[tuple[str, ...]] = (
    "auto",
    "dls",
    "pinv",
    "transpose",
    "qp:daqp",
    "qp:proxqp",
    "casadi:sqpmethod",
    "casadi:ipopt",
)
QUICK_N: Final[int] = 5
QUICK_TIMEOUT_S: Final[float] = 0.1
QUICK_CAPS: Final[dict[str, int]] = {"transpose": 3, "casadi:ipopt": 3, "qp:osqp": 3}
QUICK_CLOSED_FORM_PROBLEMS: Final[tuple[str, ...]] = ("dobot_magician", "puma560", "panda")
QUICK_CLOSED_FORM_CONFIGS: Final[int] = 2

#: Default of ``-n`` and ``--timeout-ms`` without ``--quick``.
DEFAULT_N: Final[int] = 20
DEFAULT_TIMEOUT_S: Final[float] = 1.0

#: Distribution names of the ``qpsolvers`` backends whose module name differs.
_BACKEND_PACKAGES: Final[dict[str, str]] = {
    "gurobi": "gurobipy",
    "highs": "highspy",
    "hpipm": "hpipm_python",
    "jaxopt_osqp": "jaxopt",
    "proxqp": "proxsuite",
    "qpswift": "qpSWIFT",
    "sip": "sip_python",
}


# ---------------------------------------------------------------------------- summaries
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
        iterations_median: median iterations (all attempts).
        iterations_p95: 95th percentile of the iterations.
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
    iterations = [float(r.iterations) for r in rows if r.iterations is not None]
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


# ---------------------------------------------------------------------------- environment
def _version(distribution: str) -> str | None:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    if sys.platform == "darwin":
        try:
            out = subprocess.run(
                ["sysctl", "-n", "machdep.cpu.brand_string"],
                capture_output=True,
                text=True,
                timeout=2,
                check=False,
            )
            if out.stdout.strip():
                return out.stdout.strip()
        except (OSError, subprocess.SubprocessError):
            pass
    return platform.processor() or platform.machine() or "unknown"


def _git_revision() -> str | None:
    root = Path(__file__).resolve().parent.parent
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def _load_average() -> list[float] | None:
    """The 1, 5 and 15 minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def environment(step_backends: Sequence[str] = ()) -> dict[str, Any]:
    """Where the run happened: Python, package versions, CPU, OS, load (for the report).

    Args:
        step_backends: the closed-form section's backends, recorded as they were used.

    Returns:
        A JSON-able mapping: ``python``, ``os``, ``cpu_model``, ``cpu_count`` (logical CPUs),
        ``cpu_affinity`` (CPUs this process may use), ``load_average`` (1, 5, 15 min),
        ``packages`` (name -> version, ``None`` when absent), ``qpsolvers_backends``,
        ``step_backends``, ``ik_solvers``, ``optik`` (version and git revision), ``date``.
    """
    from optik import __version__

    packages: dict[str, str | None] = {
        name: _version(name)
        for name in ("numpy", "scipy", "numba", "casadi", "qpsolvers", "matplotlib")
    }
    try:
        import qpsolvers

        backends = sorted(qpsolvers.available_solvers)
    except ImportError:
        backends = []
    for backend in backends:
        package = _BACKEND_PACKAGES.get(backend, backend)
        packages[package] = _version(package)
    sched_getaffinity = getattr(os, "sched_getaffinity", None)  # Linux only
    affinity = len(sched_getaffinity(0)) if sched_getaffinity is not None else None
    load = _load_average()
    return {
        "python": f"{platform.python_implementation()} {platform.python_version()}",
        "os": platform.platform(),
        "cpu_model": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "cpu_affinity": affinity,
        "load_average": load,
        "packages": packages,
        "qpsolvers_backends": backends,
        "step_backends": list(step_backends),
        "ik_solvers": available_solvers(),
        "optik": {"version": __version__, "git": _git_revision()},
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }


# ---------------------------------------------------------------------------- plots
def _png(fig: Any) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    pyplot().close(fig)
    return buffer.getvalue()


def _solver_colours(solvers: Sequence[str]) -> dict[str, Any]:
    cmap = pyplot().get_cmap("tab10")  # with _style(i), 20 solvers stay distinct
    return {s: cmap(i % cmap.N) for i, s in enumerate(solvers)}


_STYLES: Final[tuple[str, ...]] = ("-", "--", "-.", ":")


def _style(index: int) -> str:
    """Line style of the ``index``-th solver: cycles, so that equal curves stay visible."""
    return _STYLES[index % len(_STYLES)]


def _grid(plt: Any, panels: int, width: float, height: float) -> tuple[Any, list[Any]]:
    """A figure of ``panels`` axes, three per row, constrained layout; spare axes hidden."""
    cols = min(3, panels)
    rows = math.ceil(panels / cols)
    fig, axes = plt.subplots(
        rows,
        cols,
        figsize=(width * cols, height * rows + 0.9),
        squeeze=False,
        layout="constrained",
    )
    flat = [ax for row in axes for ax in row]
    for ax in flat[panels:]:
        ax.axis("off")
    return fig, flat[:panels]


def plot_performance_profile(
    rows: Sequence[ResultRow], time_limit_s: float, solvers: Sequence[str]
) -> bytes:
    """Fraction of targets solved within a time, per solver (log time axis), as PNG bytes.

    One panel for all problems, then one per problem; each curve ends at the solver's
    success rate at the time limit (dotted line).
    """
    plt = pyplot()
    ik = [r for r in rows if r.kind == "ik"]
    panels = ["all problems", *dict.fromkeys(r.problem for r in ik)]
    fig, axes = _grid(plt, len(panels), 4.0, 3.0)
    colours = _solver_colours(solvers)
    successful = [r.time_s for r in ik if r.success and r.time_s > 0]
    t_min = max(min(successful, default=1e-5) / 2, 1e-6)
    for ax, panel in zip(axes, panels, strict=True):
        subset = ik if panel == "all problems" else [r for r in ik if r.problem == panel]
        for i, solver in enumerate(solvers):
            mine = [r for r in subset if r.solver == solver]
            if not mine:
                continue
            times = np.sort([max(r.time_s, t_min) for r in mine if r.success])
            x = np.concatenate([[t_min], times, [time_limit_s]])
            y = np.concatenate([[0.0], np.arange(1, len(times) + 1), [len(times)]]) / len(mine)
            ax.step(x, y, where="post", color=colours[solver], ls=_style(i), lw=1.6, label=solver)
        ax.axvline(time_limit_s, color="gray", lw=1.0, ls=":")
        ax.set_xscale("log")
        ax.set_xlim(t_min, time_limit_s * 1.5)
        ax.set_ylim(-0.02, 1.04)
        ax.set_title(panel, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_xlabel("time per IK call (s)")
        ax.set_ylabel("fraction solved")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", frameon=False, fontsize=9)
    fig.suptitle(
        f"Performance profile: targets solved within a time (limit {time_limit_s * 1e3:g} ms, "
        "dotted)",
        fontsize=11,
    )
    return _png(fig)


def plot_error_distributions(
    rows: Sequence[ResultRow], tol: float, solvers: Sequence[str]
) -> bytes:
    """Cumulative distributions of the position and orientation errors, per solver (PNG)."""
    plt = pyplot()
    ik = [r for r in rows if r.kind == "ik" and r.position_error is not None]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True, layout="constrained")
    colours = _solver_colours(solvers)
    quantities = (
        ("position_error", "position error (m)"),
        ("orientation_error", "orientation error (rad)"),
    )
    for ax, (attr, label) in zip(axes, quantities, strict=True):
        for i, solver in enumerate(solvers):
            values = [getattr(r, attr) for r in ik if r.solver == solver]
            if not values:
                continue
            x = np.sort(np.maximum(np.asarray(values, dtype=float), _ERROR_FLOOR))
            y = np.arange(1, len(x) + 1) / len(x)
            ax.step(
                np.concatenate([[_ERROR_FLOOR / 10], x]),
                np.concatenate([[0.0], y]),
                where="post",
                color=colours[solver],
                ls=_style(i),
                lw=1.6,
                label=solver,
            )
        ax.axvline(tol, color="black", lw=1.0, ls="--", label=f"tolerance {tol:g}")
        ax.set_xscale("log")
        ax.set_xlim(_ERROR_FLOOR / 10, None)
        ax.set_xlabel(label)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("fraction of targets with error ≤ x")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", frameon=False, fontsize=9)
    fig.suptitle(
        f"Final errors, all problems (errors below {_ERROR_FLOOR:g} drawn at {_ERROR_FLOOR:g})",
        fontsize=11,
    )
    return _png(fig)


def plot_iteration_histograms(rows: Sequence[ResultRow], solvers: Sequence[str]) -> bytes:
    """One histogram of the iterations (all attempts) per solver, solved and failed stacked."""
    plt = pyplot()
    ik = [r for r in rows if r.kind == "ik" and r.iterations is not None]
    present = [s for s in solvers if any(r.solver == s for r in ik)] or list(solvers[:1])
    fig, axes = _grid(plt, len(present), 3.8, 2.4)
    top = max((int(r.iterations or 0) for r in ik), default=1)
    # Bin 0 alone, then log-spaced integer bins: [1, 2), [2, 3), ... up to the largest count.
    edges = np.unique(np.round(np.logspace(0, math.log10(top + 1) + 0.05, 24)))
    bins = np.concatenate([[-0.5, 0.5], edges[edges > 0.5] + 0.5])
    for ax, solver in zip(axes, present, strict=True):
        ok = [int(r.iterations or 0) for r in ik if r.solver == solver and r.success]
        bad = [int(r.iterations or 0) for r in ik if r.solver == solver and not r.success]
        ax.hist(
            [ok, bad],
            bins=bins,
            stacked=True,
            color=["tab:blue", "tab:red"],
            label=["solved", "failed"],
        )
        ax.set_xscale("symlog", linthresh=1.0)
        ax.set_xlim(-0.6, bins[-1] * 1.2)
        ax.set_title(solver, fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel("targets")
        ax.set_xlabel("iterations (all attempts)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", frameon=False, fontsize=9)
    fig.suptitle("Iterations per IK call, all problems (symmetric log scale)", fontsize=11)
    return _png(fig)


def plot_trajectory(trajectory: FloatArray, every: int = 500) -> bytes:
    """Seed 003's figure: the 2R arm drawn every ``every`` iterations, links and target."""
    problem = load_problem("planar_2r")
    target = problem.targets["seed003"].position
    with tempfile.TemporaryDirectory(prefix="optik-report-") as folder:
        path = plot_planar_trajectory(
            problem.robot, trajectory, target, Path(folder) / "trajectory.png", every=every
        )
        return path.read_bytes()


# ---------------------------------------------------------------------------- text
def _ms(seconds: float) -> str:
    return "–" if not math.isfinite(seconds) else f"{seconds * 1e3:.3g}"


def _sci(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if value == 0:
        return "0"
    if math.isinf(value):
        return "inf"
    return f"{value:.1e}"


def _pct(value: float) -> str:
    return f"{100 * value:.0f}%"


def _num(value: float) -> str:
    return "–" if not math.isfinite(value) else f"{value:.3g}"


SUMMARY_HEADER: Final[tuple[str, ...]] = (
    "problem",
    "solver",
    "n",
    "success",
    "claims ≠",
    "median ms",
    "p95 ms",
    "SGM (norm.)",
    "pos. err p50 / p95 / max (m)",
    "ori. err p50 / p95 / max (rad)",
    "iter. p50 / p95",
    *(f"acc. {_level_name(level)}" for level in ACCURACY_LEVELS),
)


#: The columns of :data:`SUMMARY_HEADER` printed on the terminal.
TERMINAL_COLUMNS: Final[tuple[str, ...]] = tuple(
    h for h in SUMMARY_HEADER if not h.startswith(("pos. err", "ori. err"))
)


def summary_cells(s: SolverSummary) -> list[str]:
    """The cells of one summary row, matching :data:`SUMMARY_HEADER`."""
    return [
        s.problem,
        s.solver,
        str(s.n),
        _pct(s.success_rate),
        f"{s.claims_disagree}/{s.claims}",
        _ms(s.time_median_s),
        _ms(s.time_p95_s),
        f"{_num(s.sgm_normalised)} ({_ms(s.sgm_s)} ms)",
        " / ".join(
            _sci(v) for v in (s.position_error_p50, s.position_error_p95, s.position_error_max)
        ),
        " / ".join(
            _sci(v)
            for v in (s.orientation_error_p50, s.orientation_error_p95, s.orientation_error_max)
        ),
        f"{_num(s.iterations_median)} / {_num(s.iterations_p95)}",
        *(_pct(s.accuracy[_level_name(level)]) for level in ACCURACY_LEVELS),
    ]


CLOSED_FORM_HEADER: Final[tuple[str, ...]] = (
    "backend",
    "programs",
    "agree",
    "max dev. least norm",
    "max dev. least squares",
    "max dev. damped LS",
    "claims ≠",
    "failures",
    "median ms",
)


def closed_form_cells(s: ClosedFormSummary) -> list[str]:
    """The cells of one closed-form summary row, matching :data:`CLOSED_FORM_HEADER`."""
    return [
        s.backend,
        str(s.cases),
        f"{s.agree}/{s.cases}",
        *(_sci(s.max_deviation[k]) for k in CLOSED_FORM_KINDS),
        str(s.claims_disagree),
        str(s.failures),
        _ms(s.time_median_s),
    ]


def seed001_table(comparison: ChapterComparison) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the seed 001 table: the chapter's iterations beside ours."""
    extra = [
        s
        for s in dict.fromkeys(k for p in comparison.parts.values() for k in p)
        if not s.startswith("chapter_") and s not in ("pinv", "transpose")
    ]
    header = [
        "path part",
        "chapter pinv",
        "chapter transpose",
        "optik pinv",
        "optik transpose",
        *(f"optik {s} (beyond the chapter)" for s in extra),
        "pinv fewer?",
    ]
    body = []
    for part, counts in comparison.parts.items():
        ours = [counts.get(s) for s in ("pinv", "transpose", *extra)]
        fewer = counts.get("pinv", 0) < counts.get("transpose", 0)
        body.append(
            [
                part,
                str(counts["chapter_pinv"]),
                str(counts["chapter_transpose"]),
                *("–" if v is None else str(v) for v in ours),
                "yes" if fewer else "no",
            ]
        )
    return header, body


def text_table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    """A fixed-width plain-text table (for the terminal)."""
    widths = [max(len(str(c)) for c in column) for column in zip(header, *body, strict=True)]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(header, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)) for row in body]
    return "\n".join(line.rstrip() for line in lines)


def markdown_table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    """A GitHub-flavoured Markdown table."""
    escape = str.maketrans({"|": "\\|"})
    lines = ["| " + " | ".join(str(h).translate(escape) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(str(c).translate(escape) for c in row) + " |" for row in body]
    return "\n".join(lines)


def protocol_text(config: RunConfig, step: bool = False) -> str:
    """The protocol of the full-IK section in one paragraph (stated above every table)."""
    caps = ", ".join(
        f"{s}: {n}" for s, n in config.caps.items() if n < config.n and s in config.solvers
    )
    text = (
        f"Protocol: {config.n} targets per robot, the FK poses of configurations drawn "
        f"uniformly inside the joint limits (seed {config.seed}); mode {config.mode}; "
        f"success = position error ≤ {config.tol:g} m and orientation error ≤ "
        f"{config.tol:g} rad and every joint inside its limits, verified by optik from FK; "
        f"timeout {config.timeout_s * 1e3:g} ms per call (restarts within it); named solvers "
        "start from the seed table then seeded random restarts, auto uses the closed form "
        "where the robot has one; one untimed warm-up per (problem, solver). Times are wall "
        "times per call and include failures (a failure usually runs to the timeout); the "
        f"SGM (shift {SGM_SHIFT_S * 1e3:g} ms) counts each failure at the timeout and is "
        "normalised to the best solver of the problem (1.0)."
    )
    if caps:
        text += f" Capped solvers (targets per robot): {caps}."
    return text


# ---------------------------------------------------------------------------- report
@dataclass
class Report:
    """What :func:`make_report` produced.

    Attributes:
        out_dir: the output folder.
        results: the raw table file.
        index: the HTML page.
        markdown: ``summary.md``.
        summary_csv: ``summary.csv``.
        summary_json: ``summary.json``.
        figures: PNG files written, by name.
        ik: full-IK summaries (per problem and solver, then ``"all"``).
        closed_form: closed-form summaries per backend.
        seed001: seed 001's comparison (None when the seeds did not run).
        seed003: seed 003's rows.
        stats: the run's statistics.
        elapsed_s: wall time of :func:`make_report`, s.
    """

    out_dir: Path
    results: Path
    index: Path
    markdown: Path
    summary_csv: Path
    summary_json: Path
    figures: dict[str, Path]
    ik: list[SolverSummary]
    closed_form: list[ClosedFormSummary]
    seed001: ChapterComparison | None
    seed003: list[ResultRow]
    stats: RunStats
    elapsed_s: float = 0.0

    def summary_text(self) -> str:
        """The full-IK summary as a compact plain-text table (what ``optik report`` prints).

        The error percentiles are left to the HTML and Markdown files.
        """
        keep = [SUMMARY_HEADER.index(h) for h in TERMINAL_COLUMNS]
        body = [[cells[i] for i in keep] for cells in map(summary_cells, self.ik)]
        text = text_table(TERMINAL_COLUMNS, body)
        return text.replace("≠", "!=").replace("–", "-")  # ASCII for any terminal


def quick_config(**overrides: Any) -> RunConfig:
    """The ``--quick`` configuration (under a minute on two cores), with overrides."""
    installed = {"auto", *available_solvers()}
    values: dict[str, Any] = {
        "problems": QUICK_PROBLEMS,
        "solvers": tuple(s for s in QUICK_SOLVERS if s in installed),
        "n": QUICK_N,
        "timeout_s": QUICK_TIMEOUT_S,
        "caps": dict(QUICK_CAPS),
        "closed_form_problems": QUICK_CLOSED_FORM_PROBLEMS,
        "closed_form_configs": QUICK_CLOSED_FORM_CONFIGS,
    }
    values.update({k: v for k, v in overrides.items() if v is not None})
    return RunConfig(**values)


def make_report(
    config: RunConfig,
    out_dir: str | Path,
    *,
    resume: bool = False,
    progress: bool | None = None,
    on_row: Callable[[ResultRow], None] | None = None,
    command: str = "",
) -> Report:
    """Run (or resume) the comparison and write the report into ``out_dir``.

    Args:
        config: what to run.
        out_dir: output folder (created).
        resume: continue ``out_dir/results.csv``, skipping rows already present.
        progress: progress bar on stderr (``None``: only on a terminal).
        on_row: called after each row is written (tests use it to interrupt a run).
        command: the command line, recorded in the report.

    Returns:
        A :class:`Report` with the paths and summaries.
    """
    start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results_path = out / "results.csv"
    load_before = _load_average()
    stats = run(config, results_path, resume=resume, progress=progress, on_row=on_row)
    rows = [r for r in stats.rows if r.key() in stats.planned]
    ik_rows = [r for r in rows if r.kind == "ik"]
    ik = summarize_ik(ik_rows, config.timeout_s)
    closed = summarize_closed_form(rows)
    seed001 = summarize_seed001(rows)
    seed003 = [r for r in rows if r.kind == "seed003"]
    env = environment(stats.step_backends)
    env["load_average_before"] = load_before

    solvers = [s for s in config.solvers if any(r.solver == s for r in ik_rows)]
    images: dict[str, bytes] = {}
    if ik_rows:
        images["performance_profile"] = plot_performance_profile(ik_rows, config.timeout_s, solvers)
        images["error_distributions"] = plot_error_distributions(ik_rows, config.tol, solvers)
        images["iteration_histograms"] = plot_iteration_histograms(ik_rows, solvers)
    if stats.trajectory is not None:
        images["planar_2r_trajectory"] = plot_trajectory(stats.trajectory)
    figures = {
        name: write_atomic(out / "figures" / f"{name}.png", data) for name, data in images.items()
    }

    report = Report(
        out_dir=out,
        results=results_path,
        index=out / "index.html",
        markdown=out / "summary.md",
        summary_csv=out / "summary.csv",
        summary_json=out / "summary.json",
        figures=figures,
        ik=ik,
        closed_form=closed,
        seed001=seed001,
        seed003=seed003,
        stats=stats,
    )
    other = len(stats.rows) - len(rows)
    context = _Context(config, env, command, other, images)
    write_atomic(report.summary_csv, _summary_csv(ik))
    write_atomic(report.markdown, _markdown(report, context))
    report.elapsed_s = time.perf_counter() - start
    write_atomic(report.summary_json, _json(report, context))
    write_atomic(report.index, _html(report, context))
    return report


@dataclass
class _Context:
    config: RunConfig
    environment: dict[str, Any]
    command: str
    other_rows: int
    images: dict[str, bytes]


def _summary_csv(summaries: Sequence[SolverSummary]) -> str:
    buffer = io.StringIO()
    records = [s.flat() for s in summaries]
    if not records:
        return ""
    writer = csv.DictWriter(buffer, fieldnames=list(records[0]), lineterminator="\n")
    writer.writeheader()
    for record in records:
        writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in record.items()})
    return buffer.getvalue()


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def _json(report: Report, context: _Context) -> str:
    data = {
        "config": context.config.to_dict(),
        "command": context.command,
        "environment": context.environment,
        "rows": {"written": report.stats.written, "skipped": report.stats.skipped},
        "ik": [s.flat() for s in report.ik],
        "closed_form": [asdict(s) for s in report.closed_form],
        "agreement_tol": AGREEMENT_TOL,
        "seed001": None if report.seed001 is None else asdict(report.seed001),
        "seed003": [
            {
                "settings": json.loads(r.settings),
                "iterations": r.iterations,
                "position_error": r.position_error,
                "success": r.success,
            }
            for r in report.seed003
        ],
        "elapsed_s": report.elapsed_s,
    }
    return json.dumps(_json_safe(data), indent=2) + "\n"


def _seed003_table(rows: Sequence[ResultRow]) -> tuple[list[str], list[list[str]]]:
    header = ["step alpha", "iterations", "final error (m)", "time (ms)", "within 0.01 m"]
    body = []
    for r in rows:
        alpha = json.loads(r.settings)["step"]
        body.append(
            [
                f"{alpha:g}",
                str(r.iterations),
                f"{r.position_error:.6f}" if r.position_error is not None else "–",
                _ms(r.time_s),
                "yes" if r.success else "no",
            ]
        )
    return header, body


def _load_text(load: Sequence[float] | None) -> str:
    return ", ".join(map(str, load)) if load else "unknown"


def _environment_rows(env: dict[str, Any]) -> list[list[str]]:
    cpu = f"{env['cpu_model']} ({env['cpu_count']} logical CPUs, "
    cpu += f"{env['cpu_affinity'] or '?'} usable by this process)"
    rows = [
        ["Python", env["python"]],
        ["OS", env["os"]],
        ["CPU", cpu],
        ["load average (1, 5, 15 min) before the run", _load_text(env.get("load_average_before"))],
        ["load average (1, 5, 15 min) after the run", _load_text(env["load_average"])],
        ["optik", f"{env['optik']['version']} (git {env['optik']['git'] or 'unknown'})"],
    ]
    rows += [[name, version or "not installed"] for name, version in env["packages"].items()]
    rows.append(["qpsolvers backends", ", ".join(env["qpsolvers_backends"]) or "none"])
    rows.append(["step-program backends", ", ".join(env["step_backends"]) or "none"])
    rows.append(["IK solvers", ", ".join(env["ik_solvers"])])
    rows.append(["date (UTC)", env["date"]])
    return rows


def _per_problem(summaries: Sequence[SolverSummary]) -> dict[str, list[SolverSummary]]:
    groups: dict[str, list[SolverSummary]] = {}
    for s in summaries:
        groups.setdefault(s.problem, []).append(s)
    overall = groups.pop("all", None)
    return {"all": overall, **groups} if overall else groups


def _markdown(report: Report, context: _Context) -> str:
    config = context.config
    parts = ["# optik solver comparison", ""]
    if context.command:
        parts += [f"Command: `{context.command}`", ""]
    parts += ["## 1. Closed-form agreement", ""]
    if report.closed_form:
        parts += [
            _closed_form_intro(),
            "",
            markdown_table(CLOSED_FORM_HEADER, [closed_form_cells(s) for s in report.closed_form]),
            "",
        ]
    else:
        parts += [_no_backends_text(), ""]
    parts += ["## 2. Full IK per robot", "", protocol_text(config), ""]
    for problem, group in _per_problem(report.ik).items():
        parts += [f"### {problem}", "", _short_protocol(config), ""]
        parts += [markdown_table(SUMMARY_HEADER, [summary_cells(s) for s in group]), ""]
    parts += ["## 3. Seed 001: pseudoinverse vs transpose on the DOBOT", ""]
    if report.seed001 is not None:
        header, body = seed001_table(report.seed001)
        parts += [
            _seed001_intro(),
            "",
            markdown_table(header, body),
            "",
            _finding(report.seed001),
            "",
        ]
    parts += ["## 4. Seed 003: the two-link example", ""]
    if report.seed003:
        header, body = _seed003_table(report.seed003)
        parts += [markdown_table(header, body), "", "Figure: `figures/planar_2r_trajectory.png`."]
        parts += [""]
    parts += ["## 5. Environment", ""]
    parts += [markdown_table(["item", "value"], _environment_rows(context.environment)), ""]
    parts += [f"Raw table: `results.csv` ({len(report.stats.rows)} rows)."]
    return "\n".join(parts) + "\n"


def _short_protocol(config: RunConfig) -> str:
    return (
        f"tol {config.tol:g} m / rad, timeout {config.timeout_s * 1e3:g} ms, seed "
        f"{config.seed}, mode {config.mode}; times include failures; SGM counts failures "
        "at the timeout."
    )


def _closed_form_intro() -> str:
    return (
        "Each backend solves differential-IK step programs (least norm, undamped least "
        "squares, damped least squares with the programs' default lambda) at random in-limit "
        "configurations away from singularities; the joint limits are in each program but "
        "inactive (the step is scaled to at most half the distance to every bound). "
        "Deviation = max |dq - dq*| (rad or m) from optik.min_norm / optik.least_squares; a "
        f"program agrees when the deviation is at most {AGREEMENT_TOL:g}."
    )


def _no_backends_text() -> str:
    return (
        "No step-program backend was found (optik.solvers.qp / optik.programs.casadi_qp "
        "missing, or no qpsolvers backend / CasADi conic plugin installed): nothing to compare."
    )


def _seed001_intro() -> str:
    home = ", ".join(f"{v:g}" for v in DOBOT_HOME)
    return (
        f"From the home configuration J = ({home}) (rear arm vertical, forearm horizontal; "
        "the chapter does not print its start, this is our choice) through the three targets "
        "of the chapter's Table 2 in sequence, each part starting where the previous one "
        "ended; position only, accepted error 0.2 mm. pinv: unit step with the SVD "
        "pseudoinverse; transpose: the step alpha = <e, J J^T e> / ||J J^T e||^2."
    )


def _finding(comparison: ChapterComparison) -> str:
    verdict = "holds" if comparison.finding_holds else "does not hold"
    return (
        "The chapter's finding (the pseudoinverse needs fewer iterations than the transpose) "
        f"{verdict} in our run"
        + ("" if comparison.all_converged else " (some parts did not converge)")
        + "."
    )


# ---------------------------------------------------------------------------- HTML
_CSS: Final[str] = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;
max-width:1200px;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em}h2{margin-top:2em;border-bottom:1px solid #ccc;padding-bottom:.2em}
table{border-collapse:collapse;font-size:.85em;margin:.6em 0 1.2em}
th,td{border:1px solid #ddd;padding:.25em .5em;text-align:right;white-space:nowrap}
th{background:#f3f3f3}td:first-child,th:first-child,td:nth-child(2){text-align:left}
.wide{overflow-x:auto}.protocol{font-size:.9em;color:#444;background:#f8f8f4;
padding:.4em .7em;border-left:3px solid #cc9}img{max-width:100%;height:auto}
figure{margin:1em 0}figcaption{font-size:.9em;color:#555}code{font-size:.95em}
"""


def _html_table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    rows = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in body
    )
    table = f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>"
    return f'<div class="wide">{table}</div>'


def _img(images: dict[str, bytes], name: str, caption: str) -> str:
    if name not in images:
        return ""
    data = base64.b64encode(images[name]).decode("ascii")
    return (
        f'<figure id="fig-{name}"><img alt="{html.escape(caption)}" '
        f'src="data:image/png;base64,{data}"><figcaption>{html.escape(caption)}</figcaption>'
        "</figure>"
    )


def _p(text: str, cls: str = "") -> str:
    attr = f' class="{cls}"' if cls else ""
    return f"<p{attr}>{html.escape(text)}</p>"


def _html(report: Report, context: _Context) -> str:
    config = context.config
    e = html.escape
    body: list[str] = ["<h1>optik solver comparison</h1>"]
    meta = (
        f"Generated {context.environment['date']} in {report.elapsed_s:.1f} s; "
        f"{report.stats.written} rows run, {report.stats.skipped} resumed from the file."
    )
    body.append(_p(meta))
    if context.command:
        body.append(f"<p>Command: <code>{e(context.command)}</code></p>")
    if context.other_rows:
        body.append(
            _p(
                f"{context.other_rows} rows of results.csv belong to other settings and are "
                "not summarised here."
            )
        )
    body.append(
        "<nav><ol>"
        '<li><a href="#closed-form">Closed-form agreement</a></li>'
        '<li><a href="#full-ik">Full IK per robot</a></li>'
        '<li><a href="#seed001">Seed 001: pseudoinverse vs transpose</a></li>'
        '<li><a href="#seed003">Seed 003: the two-link example</a></li>'
        '<li><a href="#environment">Environment</a></li>'
        "</ol></nav>"
    )

    body.append('<section id="closed-form"><h2>1. Closed-form agreement</h2>')
    if report.closed_form:
        body.append(_p(_closed_form_intro()))
        body.append(
            _html_table(CLOSED_FORM_HEADER, [closed_form_cells(s) for s in report.closed_form])
        )
    else:
        body.append(_p(_no_backends_text()))
    body.append("</section>")

    body.append('<section id="full-ik"><h2>2. Full IK per robot</h2>')
    body.append(_p(protocol_text(config), "protocol"))
    body.append(
        _p(
            "Columns: success = verified by optik; claims ≠ = rows where the solver's own "
            "convergence flag disagreed with optik's verification / rows with a flag; SGM = "
            "shifted geometric mean of the time, normalised (best = 1.0) with its value in ms; "
            "acc. = fraction of targets with both errors within the level and the limits "
            "respected."
        )
    )
    for problem, group in _per_problem(report.ik).items():
        title = "All problems" if problem == "all" else problem
        body.append(f"<h3>{e(title)}</h3>")
        body.append(_p(_short_protocol(config), "protocol"))
        body.append(_html_table(SUMMARY_HEADER, [summary_cells(s) for s in group]))
    body.append(
        _img(
            context.images,
            "performance_profile",
            "Performance profile: fraction of targets solved within a time per call "
            "(log scale); the dotted line is the time limit.",
        )
    )
    body.append(
        _img(
            context.images,
            "error_distributions",
            "Cumulative distributions of the final position and orientation errors, all "
            "problems; dashed: the tolerance.",
        )
    )
    body.append(
        _img(
            context.images,
            "iteration_histograms",
            "Iterations per IK call (all attempts, symmetric-log scale), solved and failed.",
        )
    )
    body.append("</section>")

    body.append('<section id="seed001"><h2>3. Seed 001: pseudoinverse vs transpose</h2>')
    if report.seed001 is not None:
        header, rows = seed001_table(report.seed001)
        body.append(_p(_seed001_intro()))
        body.append(_html_table(header, rows))
        body.append(_p(_finding(report.seed001)))
    else:
        body.append(_p("Not run."))
    body.append("</section>")

    body.append('<section id="seed003"><h2>4. Seed 003: the two-link example</h2>')
    if report.seed003:
        body.append(
            _p(
                "Unit links, target (1.2, 1.3) m, start q = (0.5, 0.5) rad, update "
                "q <- q + alpha J^+ (x* - x) until ||x* - x|| < 0.01 m; the seed's alpha is "
                "0.001, the full step alpha = 1 is shown for contrast."
            )
        )
        header, rows = _seed003_table(report.seed003)
        body.append(_html_table(header, rows))
        body.append(
            _img(
                context.images,
                "planar_2r_trajectory",
                "Seed 003: the arm every 500 iterations (grey), the final links, the tool "
                "path and the target (alpha = 0.001).",
            )
        )
    else:
        body.append(_p("Not run."))
    body.append("</section>")

    body.append('<section id="environment"><h2>5. Environment</h2>')
    body.append(_html_table(["item", "value"], _environment_rows(context.environment)))
    body.append(
        _p(
            f"Raw table: results.csv ({len(report.stats.rows)} rows); summaries: summary.csv, "
            "summary.json, summary.md."
        )
    )
    body.append("</section>")
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        "<title>optik solver comparison</title>\n"
        f"<style>{_CSS}</style>\n</head>\n<body>\n" + "\n".join(body) + "\n</body>\n</html>\n"
    )


# ---------------------------------------------------------------------------- CLI
def _caps(values: Sequence[str] | None) -> dict[str, int]:
    caps: dict[str, int] = {}
    for value in values or ():
        name, sep, count = value.rpartition("=")
        if not sep or not name or not count.isdigit():
            raise OptikError(f"--cap expects SOLVER=N, got {value!r}")
        caps[name] = int(count)
    return caps


def default_solvers() -> tuple[str, ...]:
    """``auto`` and every installed solver, by family: iterative, ``qp:*``, ``casadi:*``."""

    def family(name: str) -> tuple[int, str]:
        prefix = name.split(":", 1)[0] if ":" in name else ""
        return ({"": 0, "qp": 1, "casadi": 2}.get(prefix, 3), name)

    return ("auto", *sorted(available_solvers(), key=family))


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The :class:`~optik.compare.RunConfig` of ``optik report``'s arguments."""
    timeout = None if args.timeout_ms is None else args.timeout_ms / 1000.0
    problems = tuple(args.problems) if args.problems else None
    solvers = tuple(args.solvers) if args.solvers else None
    caps = _caps(args.cap)
    if args.quick:
        quick = quick_config()
        return quick_config(
            problems=problems,
            solvers=solvers,
            n=args.n,
            seed=args.seed,
            tol=args.tol,
            timeout_s=timeout,
            caps={**quick.caps, **caps},
            closed_form_problems=problems,
        )
    return RunConfig(
        problems=problems or tuple(p.stem for p in builtin_problems()),
        solvers=solvers or default_solvers(),
        n=DEFAULT_N if args.n is None else args.n,
        seed=args.seed,
        tol=args.tol,
        timeout_s=DEFAULT_TIMEOUT_S if timeout is None else timeout,
        caps=caps,
    )


def _cmd_report(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    command = "optik " + " ".join(sys.argv[1:]) if sys.argv and sys.argv[0] else ""
    report = make_report(config, args.out, resume=args.resume, command=command)
    print(report.summary_text())
    if report.seed001 is not None:
        verdict = "holds" if report.seed001.finding_holds else "does not hold"
        print(f"\nseed 001: the chapter's finding (pinv needs fewer iterations) {verdict}")
    agree = sum(s.agree for s in report.closed_form)
    total = sum(s.cases for s in report.closed_form)
    if total:
        print(f"closed forms: {agree}/{total} step programs agree to {AGREEMENT_TOL:g}")
    print(f"\nreport written in {report.elapsed_s:.1f} s: {report.index.resolve()}")
    return 0


def add_report_command(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``optik report`` to the ``optik`` command's subparsers.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers``.

    Returns:
        The ``report`` subparser (its handler is set as ``func``).
    """
    p = subparsers.add_parser(
        "report",
        help="compare the IK solvers and write an HTML / Markdown report",
        description=(
            "Run the solver comparison (closed-form agreement, full IK per robot, the seeds' "
            "examples), append every result to OUT/results.csv and write OUT/index.html, "
            "OUT/summary.md, OUT/summary.csv and OUT/summary.json."
        ),
    )
    p.add_argument(
        "--problems", nargs="+", metavar="PROBLEM", help="problem names or files (default: all)"
    )
    names = list(default_solvers())
    p.add_argument(
        "--solvers",
        nargs="+",
        metavar="SOLVER",
        choices=names,
        help="solvers (default: all of them); choices: " + ", ".join(names),
    )
    p.add_argument(
        "-n", type=int, default=None, help=f"targets per robot (default {DEFAULT_N}; quick 5)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the targets (default 0)")
    p.add_argument(
        "--timeout-ms",
        type=float,
        default=None,
        help=f"time limit per IK call, ms (default {DEFAULT_TIMEOUT_S * 1e3:g}; quick 100)",
    )
    p.add_argument("--tol", type=float, default=1e-6, help="m and rad (default 1e-6)")
    p.add_argument(
        "--cap",
        action="append",
        metavar="SOLVER=N",
        help="run SOLVER on at most N targets per robot (repeatable)",
    )
    p.add_argument("--out", default="optik-report", help="output folder (default optik-report)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="a small run (4 robots, 5 targets, fast solvers, 100 ms): under a minute",
    )
    p.add_argument(
        "--resume", action="store_true", help="continue OUT/results.csv, skipping rows present"
    )
    p.set_defaults(func=_cmd_report)
    return p
