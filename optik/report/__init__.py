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
see ``docs/report.md`` for every definition. The ``optik report`` command is in
:mod:`optik.cli`.

The package, one module per seam: :mod:`~optik.report.summaries`,
:mod:`~optik.report.environment`, :mod:`~optik.report.figures`,
:mod:`~optik.report.tables` and :mod:`~optik.report.rendering` (text, Markdown, HTML),
:mod:`~optik.report.outputs` (:class:`Report`) and :mod:`~optik.report.building`
(:func:`make_report`, :func:`quick_config`), :mod:`~optik.report.peers` (the peer
libraries' table).
"""

from optik._files import write_atomic
from optik.report.building import (
    DEFAULT_N,
    DEFAULT_TIMEOUT_S,
    QUICK_PROBLEMS,
    QUICK_SOLVERS,
    default_solvers,
    make_report,
    quick_config,
)
from optik.report.environment import environment
from optik.report.figures import (
    plot_error_distributions,
    plot_iteration_histograms,
    plot_performance_profile,
    plot_trajectory,
)
from optik.report.outputs import Report
from optik.report.peers import PEER_HEADER, PeerSummary, peer_cells, summarize_peers
from optik.report.summaries import (
    ACCURACY_LEVELS,
    SGM_SHIFT_S,
    ChapterComparison,
    ClosedFormSummary,
    SolverSummary,
    shifted_geometric_mean,
    summarize_closed_form,
    summarize_ik,
    summarize_seed001,
)
from optik.report.tables import (
    CLOSED_FORM_HEADER,
    SUMMARY_HEADER,
    TERMINAL_COLUMNS,
    closed_form_cells,
    markdown_table,
    protocol_text,
    seed001_table,
    summary_cells,
    text_table,
)

__all__ = [
    "ACCURACY_LEVELS",
    "CLOSED_FORM_HEADER",
    "DEFAULT_N",
    "DEFAULT_TIMEOUT_S",
    "PEER_HEADER",
    "QUICK_PROBLEMS",
    "QUICK_SOLVERS",
    "SGM_SHIFT_S",
    "SUMMARY_HEADER",
    "TERMINAL_COLUMNS",
    "ChapterComparison",
    "ClosedFormSummary",
    "PeerSummary",
    "Report",
    "SolverSummary",
    "closed_form_cells",
    "default_solvers",
    "environment",
    "make_report",
    "markdown_table",
    "peer_cells",
    "plot_error_distributions",
    "plot_iteration_histograms",
    "plot_performance_profile",
    "plot_trajectory",
    "protocol_text",
    "quick_config",
    "seed001_table",
    "shifted_geometric_mean",
    "summarize_closed_form",
    "summarize_ik",
    "summarize_peers",
    "summarize_seed001",
    "summary_cells",
    "text_table",
    "write_atomic",
]
