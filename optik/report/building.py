"""Building a report: run (or resume) the comparison, summarise, draw, write every file."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from optik._files import prepare_folder, write_atomic
from optik.compare import ResultRow, RunConfig, peer_solver, run
from optik.report.environment import _load_average, environment
from optik.report.figures import (
    plot_error_distributions,
    plot_iteration_histograms,
    plot_performance_profile,
    plot_trajectory,
)
from optik.report.outputs import Report, _Context
from optik.report.peers import summarize_peers
from optik.report.rendering import _html, _json, _markdown, _summary_csv
from optik.report.summaries import summarize_closed_form, summarize_ik, summarize_seed001
from optik.solvers import available_solvers

__all__ = [
    "DEFAULT_N",
    "DEFAULT_TIMEOUT_S",
    "QUICK_PROBLEMS",
    "QUICK_SOLVERS",
    "default_solvers",
    "make_report",
    "quick_config",
]

#: ``--quick``: robots, solvers (those installed are used, in this order), targets per
#: robot, timeout, and caps on solvers that are slow when they fail.
QUICK_PROBLEMS: Final[tuple[str, ...]] = ("dobot_magician", "puma560", "ur5", "panda")
QUICK_SOLVERS: Final[tuple[str, ...]] = (  # by family: iterative, qpsolvers, CasADi
    *("auto", "dls", "pinv", "transpose"),
    *("qp:daqp", "qp:proxqp"),
    *("casadi:sqpmethod", "casadi:ipopt"),
)
QUICK_N: Final[int] = 5
QUICK_TIMEOUT_S: Final[float] = 0.1
QUICK_CAPS: Final[dict[str, int]] = {"transpose": 3, "casadi:ipopt": 3, "qp:osqp": 3}
QUICK_CLOSED_FORM_PROBLEMS: Final[tuple[str, ...]] = ("dobot_magician", "puma560", "panda")
QUICK_CLOSED_FORM_CONFIGS: Final[int] = 2

#: Default of ``-n`` and ``--timeout-ms`` without ``--quick``.
DEFAULT_N: Final[int] = 20
DEFAULT_TIMEOUT_S: Final[float] = 1.0


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

    Raises:
        OutputFileError: ``out_dir`` is a file, or a place that cannot be written.
        ResultsFileError: with ``resume``, ``results.csv`` holds a corrupted or a
            duplicated row (the message names the line).
    """
    start = time.perf_counter()
    out = prepare_folder(out_dir)
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

    names = (*config.solvers, *(peer_solver(p) for p in config.peers))
    solvers = [s for s in names if any(r.solver == s for r in ik_rows)]
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
        peers=summarize_peers(stats.peers, ik),
    )
    other = len(stats.rows) - len(rows)
    context = _Context(config, env, command, other, images)
    write_atomic(report.summary_csv, _summary_csv(ik))
    write_atomic(report.markdown, _markdown(report, context))
    report.elapsed_s = time.perf_counter() - start
    write_atomic(report.summary_json, _json(report, context))
    write_atomic(report.index, _html(report, context))
    return report


def default_solvers() -> tuple[str, ...]:
    """``auto`` and every installed solver, by family: iterative, ``qp:*``, ``casadi:*``."""

    def family(name: str) -> tuple[int, str]:
        prefix = name.split(":", 1)[0] if ":" in name else ""
        return ({"": 0, "qp": 1, "casadi": 2}.get(prefix, 3), name)

    return ("auto", *sorted(available_solvers(), key=family))
