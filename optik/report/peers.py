"""The peer libraries' table: one row per (problem, peer), run or not and why.

A peer that ran has its rows summarised like any solver's (:func:`summarize_ik`: success
verified by optik, median time); one that is not installed, or cannot model the robot,
has its reason in the row instead of figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from optik.compare import PeerStatus, peer_solver
from optik.report.summaries import SolverSummary

__all__ = ["PEER_HEADER", "PeerSummary", "peer_cells", "peers_intro", "summarize_peers"]


@dataclass(frozen=True)
class PeerSummary:
    """One peer on one problem.

    Attributes:
        peer: registry name (:mod:`optik.peers`).
        problem: problem name.
        title: what the method is.
        version: installed version ("" when not installed).
        ran: the peer modelled the robot and answered its targets.
        reason: why it did not run ("" when it ran).
        notes: the model check's notes (FK difference found...).
        n: targets answered (0 when it did not run).
        success_rate: fraction verified successful by optik (nan when it did not run).
        time_median_s: median wall time per call, failures included, s (nan likewise).
    """

    peer: str
    problem: str
    title: str
    version: str
    ran: bool
    reason: str
    notes: tuple[str, ...]
    n: int
    success_rate: float
    time_median_s: float


def summarize_peers(
    statuses: Sequence[PeerStatus], summaries: Sequence[SolverSummary]
) -> list[PeerSummary]:
    """One :class:`PeerSummary` per status, its figures from the matching summary."""
    by_key = {(s.problem, s.solver): s for s in summaries}
    out = []
    for status in statuses:
        summary = by_key.get((status.problem, peer_solver(status.peer)))
        ran = status.available and summary is not None
        reason = status.reason
        if status.available and summary is None:
            reason = "no row of this peer in the results (not planned, or capped to 0)"
        out.append(
            PeerSummary(
                peer=status.peer,
                problem=status.problem,
                title=status.title,
                version=status.version,
                ran=ran,
                reason=reason,
                notes=status.notes,
                n=summary.n if summary is not None else 0,
                success_rate=summary.success_rate if summary is not None else math.nan,
                time_median_s=summary.time_median_s if summary is not None else math.nan,
            )
        )
    return out


PEER_HEADER: Final[tuple[str, ...]] = (
    "problem",
    "peer",
    "version",
    "ran",
    "n",
    "success",
    "median ms",
    "model check, or why not run",
)


def peer_cells(s: PeerSummary) -> list[str]:
    """The cells of one peer row, matching :data:`PEER_HEADER`."""
    if not s.ran:
        return [s.problem, s.peer, s.version or "–", "no", "0", "–", "–", s.reason]
    return [
        s.problem,
        s.peer,
        s.version,
        "yes",
        str(s.n),
        f"{100 * s.success_rate:.0f}%",
        f"{s.time_median_s * 1e3:.3g}",
        "; ".join(s.notes),
    ]


def peers_intro() -> str:
    """What the peer rows are (stated above the table)."""
    return (
        "Peer libraries (optik.peers) answer the same targets under the same protocol: "
        "full pose, the same tolerance and time limit (no restart starts after it), start "
        "at mid-limits then the peer's own seeded restarts; every answer is verified by "
        "optik from FK and the limits, never by the peer. Each peer's model is built from "
        "optik's chain and its FK checked equal to optik's (1e-9; pybullet, single "
        "precision, 1e-6) before it runs. In the tables above a peer is the solver "
        "peer:<name>."
    )
