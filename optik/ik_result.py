"""The result of one IK query: :class:`IKResult`, its statuses, and how it is made.

Every result is verified here, from forward kinematics and the limits
(:func:`optik.verify.verify_one`), never copied from a backend's claim:
:func:`verified_result` turns a run's (or a proof's) outcome into one.
"""

from __future__ import annotations

from dataclasses import dataclass

from optik._checks import FloatArray
from optik.limits import LIMIT_TOLERANCE, limit_violation
from optik.solvers._base import IKQuery, RunOutput, now
from optik.verify import verify_one

STATUSES = ("converged", "unreachable", "outside_limits", "max_iter", "timeout", "solver_failed")


@dataclass
class IKResult:
    """The outcome of one IK query, verified by optik.

    Attributes:
        q: joint vector (dof,), rad / m (the best attempt when unsuccessful; for
            ``outside_limits`` with unit weights, the closed-form branch that reaches
            the target beyond the limits; ``limit_violation`` says by how much).
        success: both errors within the task's tolerances and every joint inside its
            limits.
        status: one of :data:`STATUSES`.
        position_error: the task's position error from forward kinematics (m): ``||p(q) -
            p*||``, over the constrained target axes when weights free some
            (:mod:`optik.task`).
        orientation_error: the task's orientation error (rad): the angle of ``R*^T R(q)``,
            the angle between the tool axis and the target's in ``axis`` mode, 0 without
            orientation.
        limit_violation: largest excursion beyond a limit (rad or m); 0 inside.
        iterations: solver iterations over all attempts.
        restarts: attempts after the first.
        time_s: wall time of the call (``time.perf_counter``).
        solver: the method that produced ``q``: ``"analytic"`` for a closed-form branch
            (or its proof), ``"reach"`` for the reach sphere's proof (``q`` is the start,
            no search ran; with graded weights, the compromise), ``"frozen"`` when every
            joint is frozen (``q`` is that configuration, judged), else the numeric
            solver's name.
        message: backend text or the reason for the status.
        backend_converged: the backend's own convergence claim for ``q`` (``None`` for the
            closed form).
    """

    q: FloatArray
    success: bool
    status: str
    position_error: float
    orientation_error: float
    limit_violation: float
    iterations: int = 0
    restarts: int = 0
    time_s: float = 0.0
    solver: str = ""
    message: str = ""
    backend_converged: bool | None = None


def verified_result(
    query: IKQuery, start_time: float, solver: str, outcome: RunOutput, claim: bool | None
) -> IKResult:
    """The result for ``outcome.q``, verified here from FK, the limits and the query's box.

    ``outcome`` gives what a failed verification reports (its ``status_if_failed`` and
    ``message``) and the counts; ``claim`` is the backend's own claim (``None`` for a
    closed form or a proof). A configuration off a frozen joint's value or inside a
    ``limit_margin`` (the query's box, beyond :data:`~optik.limits.LIMIT_TOLERANCE`) is no
    success, whatever produced it.
    """
    q = outcome.q
    position, orientation, violation, success = verify_one(query.robot, q, query.target, query.spec)
    message = outcome.message
    if success and query.bounds is not None:
        off_box = float(limit_violation(q, query.lower, query.upper))
        if not off_box <= LIMIT_TOLERANCE:
            success = False
            message = (
                f"the answer leaves the query's box (frozen joints, limit margin) by "
                f"{off_box:.3g} rad or m"
            )
    return IKResult(
        q=q,
        success=success,
        status="converged" if success else outcome.status_if_failed,
        position_error=position,
        orientation_error=orientation,
        limit_violation=violation,
        iterations=outcome.iterations,
        restarts=outcome.restarts,
        time_s=now() - start_time,
        solver=solver,
        message=message if not success else "",
        backend_converged=claim,
    )


def without_run(
    q: FloatArray, status: str, message: str = "", iterations: int = 0, restarts: int = 0
) -> RunOutput:
    """The outcome of a closed form or a proof, in a run's terms (no backend claim)."""
    return RunOutput(q, iterations, restarts, False, message, status)


def from_run(query: IKQuery, start_time: float, solver: str, run: RunOutput) -> IKResult:
    """The result of a numeric run: its answer, or its best attempt and why it failed."""
    return verified_result(query, start_time, solver, run, run.converged)


__all__ = ["STATUSES", "IKResult", "from_run", "verified_result", "without_run"]
