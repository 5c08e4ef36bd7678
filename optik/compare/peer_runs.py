"""Peer libraries in the full-IK section: the same targets and verification as optik's solvers.

For each problem and each requested peer (:mod:`optik.peers`), the adapter is loaded and
prepared (its model built from optik's chain and FK-checked); a peer that is not
installed or cannot model the robot becomes a :class:`PeerStatus` with the reason and
runs no row. A prepared peer answers the problem's targets (the same seeded FK poses as
the ``ik`` rows) from mid-limits, reseeded per target, and every answer is verified here
by :func:`optik.verify.verify_one` (optik's FK and limits), never by the peer: one ``ik``
row per target with solver ``peer:<name>``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, Final

import numpy as np

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt
from optik.compare.results import ResultRow, problem_row, settings_json
from optik.peers import Peer, PeerUnavailable, get_peer
from optik.problems import Problem
from optik.verify import verify_one

__all__ = ["PEER_PREFIX", "PeerStatus", "peer_settings", "peer_solver", "prepare_peer"]

#: Solver column of a peer's rows: ``peer:<name>``.
PEER_PREFIX: Final[str] = "peer:"

#: Statuses of a peer row (``ik`` rows of optik's solvers use :data:`optik.ik_result.STATUSES`).
PEER_STATUSES: Final[tuple[str, ...]] = ("converged", "rejected", "no_answer", "error")


def peer_solver(name: str) -> str:
    """The ``solver`` column of peer ``name``'s rows."""
    return PEER_PREFIX + name


@dataclass(frozen=True)
class PeerStatus:
    """Whether one peer ran on one problem, and why not.

    Attributes:
        peer: registry name.
        problem: problem name.
        title: what the method is.
        distribution: the pip name.
        version: installed version ("" when not installed).
        available: the peer was prepared for this robot and ran its targets.
        reason: why not (not installed, or cannot model the robot); "" when it ran.
        notes: the model check's notes (FK difference found, limits copied).
        settings: the adapter's options.
    """

    peer: str
    problem: str
    title: str
    distribution: str
    version: str
    available: bool
    reason: str = ""
    notes: tuple[str, ...] = ()
    settings: dict[str, Any] = field(default_factory=dict)


def prepare_peer(
    name: str, problem: Problem, mode: str, tol: float, timeout_s: float
) -> tuple[Peer, PeerStatus]:
    """A peer adapter prepared for ``problem``'s robot, and its status.

    Never raises for a peer that cannot run: the status says why (``available=False``).

    Args:
        name: a registry name of :mod:`optik.peers`.
        problem: the problem.
        mode: the run's mode; the adapters answer full-pose queries only.
        tol: the protocol's tolerance, m and rad.
        timeout_s: the run's time limit per call: no restart starts after it, s.
    """
    peer = get_peer(name, tol=tol, timeout_s=timeout_s)
    base: dict[str, Any] = {
        "peer": name,
        "problem": problem.name,
        "title": peer.title,
        "distribution": peer.distribution,
        "settings": peer.settings(),
    }
    if mode != "pose":
        reason = f"the adapters answer full-pose queries; mode {mode!r} is not run"
        return peer, PeerStatus(**base, version="", available=False, reason=reason)
    try:
        notes = peer.prepare(problem.robot)
    except PeerUnavailable as exc:
        return peer, PeerStatus(**base, version=peer.version, available=False, reason=exc.reason)
    except Exception as exc:  # a peer's own bug is reported, not raised
        reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
        reason = f"prepare failed: {type(exc).__name__}: {exc}"
        return peer, PeerStatus(**base, version=peer.version, available=False, reason=reason)
    return peer, PeerStatus(**base, version=peer.version, available=True, notes=tuple(notes))


def peer_settings(peer: Peer, mode: str, seed: int, timeout_s: float, tol: float) -> str:
    """The settings JSON of a peer row: the protocol's fields, the start, the adapter's."""
    return settings_json(
        {
            "mode": mode,
            "peer": peer.settings(),
            "q0": "mid_limits",
            "seed": seed,
            "timeout_s": timeout_s,
            "tol": tol,
        }
    )


def _peer_row(
    problem: Problem,
    target_id: str,
    pose: FloatArray,
    peer: Peer,
    settings: str,
    tol: float,
    solve_seed: int,
) -> tuple[ResultRow, FloatArray | None]:
    """One timed, verified query of ``peer``; the row and the answer's joint vector."""
    robot = problem.robot
    base = problem_row(
        "ik", problem, target_id, peer_solver(peer.name), settings, success=False, status="error"
    )
    method = f"{peer.distribution} {peer.version}"
    peer.reseed(solve_seed)
    q0 = robot.mid_limits
    start = time.perf_counter()
    try:
        answer = peer.solve(pose, q0)
    except Exception as exc:  # a crash is a row, not the end of the run
        reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
        elapsed = time.perf_counter() - start
        message = f"{type(exc).__name__}: {exc}"[:300]
        return replace(base, time_s=elapsed, method=method, message=message), None
    elapsed = time.perf_counter() - start
    common: dict[str, Any] = {
        "iterations": -1 if answer.iterations is None else int(answer.iterations),
        "time_s": elapsed,
        "backend_converged": answer.claimed,
        "method": method,
        "message": answer.note,
    }
    if answer.q is None or not _finite_shape(answer.q, robot.dof):
        if answer.q is not None:  # a vector of another shape or with NaN: no answer
            common["message"] = f"{answer.note} (not a finite ({robot.dof},) vector)".strip()
        return replace(base, status="no_answer", **common), None
    q = np.asarray(answer.q, dtype=float).reshape(-1)
    position, orientation, violation, success = verify_one(robot, q, pose, "pose", tol)
    row = replace(
        base,
        success=bool(success),
        status="converged" if success else "rejected",
        position_error=position,
        orientation_error=orientation,
        limit_violation=violation,
        **common,
    )
    return row, q


def _finite_shape(q: Any, dof: int) -> bool:
    """Whether a peer's ``q`` is a finite vector of ``dof`` entries (else: no answer)."""
    try:
        array = np.asarray(q, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return False
    return array.shape == (dof,) and bool(np.all(np.isfinite(array)))
