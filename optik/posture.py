"""Posture: among the configurations that reach a target, one nearest a reference.

The least-norm IK program at position level, seed 000's minimum-norm idea (eq. 50)
applied to the whole configuration::

    min  1/2 ||q - q_ref||_W^2   s.t.   task(q) = target,   lower <= q <= upper

with ``W = diag(joint_weights)``. :func:`refine_posture` solves it from a verified answer
by sequential quadratic programming on the equality constraint: each step is the closed
form ``dq = d + W^-1 J^T (J W^-1 J^T)^-1 (e - J d)`` with ``d = q_ref - q`` (``J`` the task's
Jacobian rows, ``e`` its residual), followed by Gauss–Newton restoration onto the task and
accepted only if the task still holds within its tolerances and the weighted distance
fell. Joints on a bound whose step points outward are held there. At the end, with the
limits inactive, ``W (q - q_ref)`` lies in the row space of ``J`` (first-order
optimality): a local optimum, not a global one — :func:`optik.solve_ik` refines every
answer its restarts find and keeps the best.
"""

from __future__ import annotations

import numpy as np

from optik._checks import FloatArray, finite_array
from optik.errors import OptikError
from optik.solvers._base import IKQuery

POSTURE_STEPS = 200
"""Largest number of SQP steps of one refinement."""

RESTORE_STEPS = 10
"""Gauss–Newton steps that bring a trial point back onto the task."""


def check_joint_weights(weights: object, dof: int) -> FloatArray:
    """``joint_weights`` as a (dof,) array of positive finite numbers (ones for ``None``)."""
    if weights is None:
        return np.ones(dof)
    w = finite_array("joint_weights", weights, (dof,))
    if np.any(w <= 0.0):
        raise OptikError(f"joint_weights must be > 0, got {w.tolist()}")
    return w


TIGHTEN = 1e-3
"""Restoration aims at this fraction of the task's tolerances: steps taken inside the
tolerance band would stop the descent at the band's edge, short of the optimum."""


def _task_step(query: IKQuery, q: FloatArray) -> tuple[FloatArray, FloatArray, bool]:
    """Task rows ``J`` (m, dof), residual ``e`` (m,) and tight convergence at ``q``."""
    T, J = query.robot.fk_jacobian(q)
    position, orientation = query.errors(T)
    task = query.spec
    tight = position <= TIGHTEN * task.position_tol and (
        orientation <= TIGHTEN * task.orientation_tol
    )
    return query.task_rows(J), query.error_vector(T), tight


def _weighted_min_norm(J: FloatArray, v: FloatArray, w_inv: FloatArray) -> FloatArray:
    """``W^-1 J^T (J W^-1 J^T)^-1 v`` with a small ridge for rank-deficient ``J``."""
    A = (J * w_inv) @ J.T
    A[np.diag_indices_from(A)] += 1e-12 * max(1.0, float(np.trace(A)))
    return w_inv * (J.T @ np.linalg.solve(A, v))


def refine_posture(
    query: IKQuery, q: FloatArray, q_ref: FloatArray, weights: FloatArray
) -> FloatArray:
    """A verified answer ``q`` moved towards ``q_ref`` along the task's solutions.

    Args:
        query: the IK query (its task, tolerances and box ``query.lower/upper``).
        q: a configuration (dof,) that solves the query.
        q_ref: the reference posture (dof,), rad / m.
        weights: (dof,) > 0, the joint weights ``W``.

    Returns:
        A configuration that still solves the query (to :data:`TIGHTEN` of its
        tolerances), usually nearer ``q_ref``; ``q`` itself if it cannot be tightened.
    """
    lower, upper = query.lower, query.upper
    w_inv = 1.0 / weights
    q = np.array(q, dtype=np.float64)

    def cost(x: FloatArray) -> float:
        d = x - q_ref
        return float(d @ (weights * d))

    start = q.copy()
    for _ in range(RESTORE_STEPS):  # first onto the task, tightly
        J, e, tight = _task_step(query, q)
        if tight:
            break
        q = np.clip(q + _weighted_min_norm(J, e, w_inv), lower, upper)
    if not tight:
        return start
    best = cost(q)
    for _ in range(POSTURE_STEPS):
        J, e, _ = _task_step(query, q)
        d = q_ref - q
        free = np.ones(len(q), dtype=bool)
        for _ in range(2):  # hold joints on a bound whose step points outward
            Jf = J * free
            dq = np.where(free, d, 0.0) + _weighted_min_norm(Jf, e - Jf @ d, w_inv * free)
            blocked = ((q <= lower) & (dq < 0.0)) | ((q >= upper) & (dq > 0.0))
            if not np.any(blocked & free):
                break
            free &= ~blocked
        accepted = False
        step = 1.0
        for _ in range(8):
            trial = np.clip(q + step * dq, lower, upper)
            ok = False
            for _ in range(RESTORE_STEPS):
                Jt, et, ok = _task_step(query, trial)
                if ok:
                    break
                trial = np.clip(
                    trial + _weighted_min_norm(Jt * free, et, w_inv * free), lower, upper
                )
            if ok and cost(trial) < best:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            break
        moved = float(np.max(np.abs(trial - q)))
        q, best = trial, cost(trial)
        if moved < 1e-12:
            break
    return q
