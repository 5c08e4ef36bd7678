"""The report's figures (matplotlib, the ``report`` extra), each returned as PNG bytes."""

from __future__ import annotations

import io
import math
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np

from optik._checks import FloatArray
from optik.compare import ResultRow
from optik.plots import plot_planar_trajectory, pyplot
from optik.problems import load_problem

__all__ = [
    "plot_error_distributions",
    "plot_iteration_histograms",
    "plot_performance_profile",
    "plot_trajectory",
]

#: Errors below this are drawn at it on log axes (exact answers have error 0).
_ERROR_FLOOR: Final[float] = 1e-16


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
    # -1 is a backend without an iteration count: nothing to draw for it.
    ik = [r for r in rows if r.kind == "ik" and r.iterations is not None and r.iterations >= 0]
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
