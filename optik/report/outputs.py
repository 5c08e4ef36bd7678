"""What :func:`optik.report.make_report` produced: the files and the summaries."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from optik.compare import ResultRow, RunConfig, RunStats
from optik.report.peers import PEER_HEADER, PeerSummary, peer_cells
from optik.report.summaries import ChapterComparison, ClosedFormSummary, SolverSummary
from optik.report.tables import SUMMARY_HEADER, TERMINAL_COLUMNS, summary_cells, text_table

__all__ = ["Report"]


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
        peers: one row per (problem, peer) asked for: its figures, or why it did not run.
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
    peers: list[PeerSummary] = field(default_factory=list)

    def summary_text(self) -> str:
        """The full-IK summary as a compact plain-text table (what ``optik report`` prints).

        The error percentiles are left to the HTML and Markdown files; the peers' table
        follows when peers were asked for.
        """
        keep = [SUMMARY_HEADER.index(h) for h in TERMINAL_COLUMNS]
        body = [[cells[i] for i in keep] for cells in map(summary_cells, self.ik)]
        text = text_table(TERMINAL_COLUMNS, body)
        if self.peers:
            peers = text_table(PEER_HEADER, [peer_cells(p) for p in self.peers])
            text += "\n\npeer libraries (verified by optik):\n" + peers
        return text.replace("≠", "!=").replace("–", "-")  # ASCII for any terminal


@dataclass
class _Context:
    config: RunConfig
    environment: dict[str, Any]
    command: str
    other_rows: int
    images: dict[str, bytes]
