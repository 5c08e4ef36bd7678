"""Solver comparison runs: one long table of results, appended row by row.

A run (:func:`run`) produces the raw table of ``optik report``: one row per (section,
problem, target, solver, settings), written to a CSV file as soon as it is produced
(one ``write`` and a ``flush`` per row), so an interrupted run loses nothing and
``resume=True`` continues it, skipping the rows already present (keyed by
:meth:`ResultRow.key`). Summaries, plots and documents are built from this table by
:mod:`optik.report`; the schema is documented in ``docs/report.md``.

Four kinds of rows (column ``kind``):

* ``ik`` — full IK (:func:`optik.solve_ik`) on random in-limit configurations' FK poses,
  per robot, seeded: deterministic for a seed except the timings.
* ``closed_form`` — one differential-IK step program (least norm, least squares, damped
  least squares) solved by a QP backend (``qp:<name>``) or a CasADi conic plugin
  (``casadi:<plugin>``), compared with the closed forms :func:`optik.min_norm` /
  :func:`optik.least_squares`; the limits are in the program but inactive.
* ``seed001`` — the DOBOT chapter's comparison (its Table 2): pseudoinverse vs Jacobian
  transpose iterations on a three-part path.
* ``seed003`` — the two-link example of seed 003 (step 0.001, tolerance 0.01).

The package, one module per seam: :mod:`~optik.compare.results` (the table on disk),
:mod:`~optik.compare.config` (what a run covers), :mod:`~optik.compare.targets`,
:mod:`~optik.compare.ik_runs`, :mod:`~optik.compare.steps` and
:mod:`~optik.compare.seeds` (the sections), :mod:`~optik.compare.peer_runs` (the peer
libraries of :mod:`optik.peers` on the full-IK targets), :mod:`~optik.compare.backends`
(every solver name the sections resolve) and :mod:`~optik.compare.runner` (the run).
"""

from optik.compare.backends import seed_solver, solve_step, step_backends
from optik.compare.config import RunConfig, RunStats, ik_settings
from optik.compare.peer_runs import PEER_PREFIX, PeerStatus, peer_solver
from optik.compare.results import (
    COLUMNS,
    KINDS,
    Key,
    ResultRow,
    ResultsFile,
    read_results,
    rows_of,
    settings_json,
    write_rows,
)
from optik.compare.runner import run
from optik.compare.seeds import (
    CHAPTER_TABLE_2,
    DOBOT_HOME,
    SEED001_MAX_ITER,
    SEED001_SOLVERS,
    SEED003_Q0,
    SEED003_STEPS,
    dobot_chapter_rows,
    planar_2r_example,
)
from optik.compare.steps import AGREEMENT_TOL, StepCase, closed_form_cases
from optik.compare.targets import random_configurations

__all__ = [
    "AGREEMENT_TOL",
    "CHAPTER_TABLE_2",
    "COLUMNS",
    "DOBOT_HOME",
    "KINDS",
    "PEER_PREFIX",
    "SEED001_MAX_ITER",
    "SEED001_SOLVERS",
    "SEED003_Q0",
    "SEED003_STEPS",
    "Key",
    "PeerStatus",
    "ResultRow",
    "ResultsFile",
    "RunConfig",
    "RunStats",
    "StepCase",
    "closed_form_cases",
    "dobot_chapter_rows",
    "ik_settings",
    "peer_solver",
    "planar_2r_example",
    "random_configurations",
    "read_results",
    "rows_of",
    "run",
    "seed_solver",
    "settings_json",
    "solve_step",
    "step_backends",
    "write_rows",
]
