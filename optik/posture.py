"""Posture: among the configurations that reach a target, one nearest a reference.

The least-norm IK program at position level, seed 000's minimum-norm idea (eq. 50)
applied to the whole configuration::

    min  1/2 ||q - q_ref||_W^2   s.t.   task(q) = target,   lower <= q <= upper

with ``W = diag(joint_weights)``. :func:`refine_posture` solves it from a verified answer
by sequential quadratic programming on the equality constraint, compiled
(:mod:`optik.solvers._posture_kernel`): the first step is the closed form ``dq = d + W^-1
J^T (J W^-1 J^T)^-1 (e - J d)`` with ``d = q_ref - q`` (``J`` the task's Jacobian rows,
``e`` its residual), later ones use a quasi-Newton model of the Lagrangian's curvature;
each is followed by Gauss–Newton restoration onto the task and accepted only if the task
still holds within its tolerances and the distance fell. Joints on a bound whose step
points outward are held there. At the end, with the limits inactive, ``W (q - q_ref)``
lies in the row space of ``J`` (first-order optimality): a local optimum, not a global one.

:func:`posture_candidates` chooses what to refine: the answer of a start at ``q_ref``
itself, then up to :data:`POSTURE_ANSWERS` - 1 more verified answers of the ordinary
start sequence within :data:`POSTURE_ATTEMPTS` attempts (more only while none is found);
:func:`optik.solve_ik` refines each and keeps the nearest.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray, finite_array, finite_length_array
from optik.analytic import wrap_into_limits
from optik.errors import OptikError
from optik.solvers._base import IKQuery, IKSolver, RunOutput, budget_now
from optik.solvers._posture_kernel import TIGHTEN, posture_refine, posture_search
from optik.solvers._seeds import start_sequence
from optik.solvers.iterative import DLSSolver
from optik.verify import verify_one

POSTURE_STEPS = 200
"""Largest number of SQP steps of one refinement."""

POSTURE_ANSWERS = 2
"""Verified answers that are refined: the one from ``q_ref``, then the first others."""

POSTURE_ATTEMPTS = 4
"""Attempts (after the start at ``q_ref``) within which the other answers are collected;
beyond them the search goes on only until a first answer is found."""

__all__ = [
    "POSTURE_ANSWERS",
    "POSTURE_ATTEMPTS",
    "POSTURE_STEPS",
    "TIGHTEN",
    "Refinement",
    "check_joint_weights",
    "check_posture",
    "nearest_turns",
    "posture_answers",
    "posture_candidates",
    "refine",
    "refine_posture",
]


JOINT_WEIGHT_RANGE = (1e-100, 1e100)
"""Smallest and largest joint weight accepted (no unit): the squares, which the steps'
normal equations form, stay finite and above float64's subnormals."""


def check_joint_weights(weights: object, dof: int) -> FloatArray:
    """``joint_weights`` as a (dof,) array of positive finite numbers (ones for ``None``)."""
    if weights is None:
        return np.ones(dof)
    w = finite_array("joint_weights", weights, (dof,))
    if np.any(w <= 0.0):
        raise OptikError(f"joint_weights must be > 0, got {w.tolist()}")
    if np.any(w < JOINT_WEIGHT_RANGE[0]) or np.any(w > JOINT_WEIGHT_RANGE[1]):
        low, high = JOINT_WEIGHT_RANGE
        raise OptikError(
            f"joint_weights must lie within [{low:g}, {high:g}] (their squares must stay "
            f"finite and normal in float64), got {w.tolist()}"
        )
    return w


def check_posture(
    posture: object, joint_weights: object, dof: int
) -> tuple[FloatArray | None, FloatArray | None]:
    """``(q_ref, weights)`` of the ``posture`` and ``joint_weights`` options (rad / m).

    ``(None, None)`` without a posture; the weights default to ones with one.

    Raises:
        OptikError: ``posture`` not a finite (dof,) array of entries of magnitude at
            most :data:`~optik._checks.MAX_LENGTH_M`, ``joint_weights`` invalid
            (:func:`check_joint_weights`), or given without ``posture`` (they are its
            norm, and would be ignored).
    """
    if posture is None:
        if joint_weights is not None:
            raise OptikError("joint_weights is the norm of posture: give posture too")
        return None, None
    q_ref = finite_length_array("posture", posture, (dof,), unit="rad or m")
    return q_ref, check_joint_weights(joint_weights, dof)


class Refinement(NamedTuple):
    """The outcome of :func:`refine`.

    Attributes:
        q: (dof,) the refined configuration (rad / m).
        converged: the first-order optimality measure is at most
            :data:`optik.solvers._posture_kernel.OPTIMALITY_TOL`.
        measure: ``||g - J^T lambda|| / ||g||`` with ``g = W (q - q_ref)`` over the joints
            not held on a bound, ``lambda`` its least-squares fit (no unit); ``inf`` when
            ``q`` could not be brought within :data:`TIGHTEN` of the tolerances.
        iterations: SQP steps taken.
    """

    q: FloatArray
    converged: bool
    measure: float
    iterations: int


def refine(
    query: IKQuery,
    q: FloatArray,
    q_ref: FloatArray,
    weights: FloatArray,
    max_iter: int = POSTURE_STEPS,
) -> Refinement:
    """:func:`refine_posture` with its convergence report.

    Args:
        query: the IK query (its task, tolerances and box ``query.lower/upper``).
        q: a configuration (dof,) that solves the query.
        q_ref: the reference posture (dof,), rad / m.
        weights: (dof,) > 0, the joint weights ``W``.
        max_iter: most SQP steps.
    """
    out = np.array(q, dtype=np.float64)
    # The task's search twin: graded weights (1e-100 on a row) do not loosen what the
    # refinement keeps solved (optik.task.Task.search: the same success).
    task = query.spec.search
    iterations, converged, measure = posture_refine(
        query.robot.chain.kernel_args(query.bounds), query.target, task.packed, out,
        np.ascontiguousarray(q_ref, dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64), int(max_iter),
    )  # fmt: skip
    return Refinement(out, bool(converged), float(measure), int(iterations))


def nearest_turns(query: IKQuery, Q: FloatArray, q_ref: FloatArray) -> FloatArray:
    """The rows of ``Q`` (k, dof), each revolute angle turned by whole turns nearest ``q_ref``.

    The same poses. Where a joint's range spans more than a turn (a UR's +-2 pi, a
    continuous joint), an answer can sit a turn or more from ``q_ref`` (a closed form's
    branch is wrapped nearest ``q0``), and the refinement, which is local, never crosses
    it. A turn that would leave the query's box (a margin, a frozen joint) is not taken.
    """
    turned = wrap_into_limits(Q, query.robot, q_ref)
    inside = (turned >= query.lower) & (turned <= query.upper)
    return np.where(inside, turned, Q)


def _turned_and_refined(
    query: IKQuery, q: FloatArray, q_ref: FloatArray, weights: FloatArray
) -> FloatArray:
    """``q`` (refined from its own start) turned nearest ``q_ref``, refined again if turned."""
    turned = nearest_turns(query, q[None], q_ref)[0]
    return q if np.array_equal(turned, q) else refine_posture(query, turned, q_ref, weights)


def refine_posture(
    query: IKQuery, q: FloatArray, q_ref: FloatArray, weights: FloatArray
) -> FloatArray:
    """A verified answer ``q`` moved towards ``q_ref`` along the task's solutions.

    The arguments are those of :func:`refine`, without its step budget.

    Returns:
        A configuration that still solves the query (to :data:`TIGHTEN` of its
        tolerances), a local optimum of the distance to ``q_ref`` within
        :data:`POSTURE_STEPS` steps; ``q`` itself (clipped into the box) if it cannot be
        tightened.
    """
    return refine(query, q, q_ref, weights).q


def posture_candidates(
    query: IKQuery,
    numeric: IKSolver,
    given: list[FloatArray],
    q_ref: FloatArray,
    seed: int,
    max_iter: int,
    last: int,
    deadline: float,
) -> tuple[list[tuple[FloatArray, int, int]], RunOutput]:
    """The verified answers worth refining, from starts at ``q_ref`` then the usual ones.

    The start sequence is ``q_ref`` clipped into the box, then ``given`` and the ordinary
    sequence (:mod:`optik.solvers._starts`). Answers are collected until
    :data:`POSTURE_ANSWERS` are found, or :data:`POSTURE_ATTEMPTS` attempts after the
    first have run and at least one was found, or ``last`` / ``deadline`` runs out.

    Returns:
        The answers ``(q, iterations so far, restarts so far)`` and the last run's output.
    """
    start = np.clip(q_ref, query.lower, query.upper)
    starts = start_sequence(
        query.robot, query.target, query.spec, [start, *given], seed, query.bounds
    )
    found: list[tuple[FloatArray, int, int]] = []
    first = 0
    iterations = 0
    run: RunOutput | None = None
    while first <= last:
        # Within the small budget, stop at its end; beyond it, at the first answer.
        stop = min(last, POSTURE_ATTEMPTS) if first <= POSTURE_ATTEMPTS else last
        run = numeric.run(query, starts, max_iter, stop, deadline, start=first)
        iterations += run.iterations
        first += run.restarts + 1
        if run.converged and verify_one(query.robot, run.q, query.target, query.spec)[3]:
            found.append((run.q, iterations, first - 1))
            if len(found) >= POSTURE_ANSWERS:
                break
        if found and first > POSTURE_ATTEMPTS:
            break
        if budget_now() > deadline:
            break
    if run is None:  # pragma: no cover - the budget always admits one attempt
        raise OptikError("no IK attempt ran")
    return found, run


def posture_answers(
    query: IKQuery,
    numeric: IKSolver,
    given: list[FloatArray],
    q_ref: FloatArray,
    weights: FloatArray,
    seed: int,
    max_iter: int,
    last: int,
    deadline: float,
) -> tuple[list[tuple[FloatArray, int, int]], RunOutput]:
    """The refined answers of :func:`posture_candidates`, nearest ``q_ref`` first.

    With the compiled ``dls`` the first :data:`POSTURE_ATTEMPTS` + 1 attempts and the
    refinements run in one compiled call (:func:`optik.solvers._posture_kernel.
    posture_search`, which does not look at the clock: a few hundred microseconds on a
    7-dof arm); only when they find no answer do further attempts run, within ``last``
    and ``deadline``. Other solvers collect with :func:`posture_candidates`.

    Returns:
        The refined answers ``(q, iterations so far, restarts so far)``, each within
        :data:`TIGHTEN` of the tolerances (they are to be verified), sorted by their
        weighted distance to ``q_ref``, and the last run's output.
    """

    def cost(q: FloatArray) -> float:
        d = q - q_ref
        return float(d @ (weights * d))

    if not isinstance(numeric, DLSSolver):
        found, run = posture_candidates(
            query, numeric, given, q_ref, seed, max_iter, last, deadline
        )
        turned = nearest_turns(
            query, np.array([q for q, _, _ in found]).reshape(-1, query.robot.dof), q_ref
        )
        refined = [
            (refine_posture(query, q, q_ref, weights), it, r)
            for q, (_, it, r) in zip(turned, found, strict=True)
        ]
        return sorted(refined, key=lambda f: cost(f[0])), run
    robot = query.robot
    start = np.clip(q_ref, query.lower, query.upper)
    starts = start_sequence(robot, query.target, query.spec, [start, *given], seed, query.bounds)
    stop = min(last, POSTURE_ATTEMPTS)
    _, refined_q, kept, _, _, count, iterations, attempts = posture_search(
        robot.chain.kernel_args(query.bounds), query.target, query.spec.search.packed,
        starts.given, *starts.table, starts.mask, int(max_iter), numeric.w_bias, stop,
        starts.seed,
        np.ascontiguousarray(q_ref, dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64), POSTURE_ANSWERS, POSTURE_STEPS,
    )  # fmt: skip
    used = int(attempts) - 1
    found = [
        (_turned_and_refined(query, refined_q[k].copy(), q_ref, weights), int(iterations), used)
        for k in range(int(count))
        if kept[k]
    ]
    if found:
        run = RunOutput(found[0][0], int(iterations), used, True, "converged", "max_iter")
        return sorted(found, key=lambda f: cost(f[0])), run
    run = RunOutput(start, int(iterations), used, False, "stalled or max_iter", "max_iter")
    if stop >= last:
        return [], run
    run = numeric.run(query, starts, max_iter, last, deadline, start=stop + 1)
    total = int(iterations) + run.iterations
    used = stop + 1 + run.restarts
    if not run.converged:
        return [], RunOutput(run.q, total, used, False, run.message, run.status_if_failed)
    q = refine_posture(query, nearest_turns(query, run.q[None], q_ref)[0], q_ref, weights)
    return [(q, total, used)], RunOutput(run.q, total, used, True, "converged", "max_iter")
