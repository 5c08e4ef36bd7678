"""The least-squares step solved again in square-root form.

A backend solves the least-squares step program as a QP whose Hessian
``P = J^T Wt J + lambda^2 W`` squares the condition number of the stacked rows
``[Wt^(1/2) J; lambda W^(1/2)]``. :func:`resolve_least_squares` takes a verified point's
active set and solves the step again by ``lstsq`` on those rows, whose condition number is
the square root of the QP's; :func:`optik.diff_ik` applies it to every accepted
least-squares step with a bound active (both the fast path and :func:`optik.diffik.verify_step`).
"""

from __future__ import annotations

import numpy as np

from optik._checks import FloatArray
from optik.programs.diff_qp import DiffIKProgram

__all__ = ["bounded_least_squares", "polish_least_squares", "resolve_least_squares"]


def resolve_least_squares(
    program: DiffIKProgram, dq: FloatArray, tol: float, kkt_rtol: float, kkt_atol: float
) -> FloatArray:
    """A verified least-squares step ``dq`` (inside the bounds) solved again in square-root form.

    The unconstrained minimiser if it lies within ``tol`` of the bounds (the problem is
    convex: it is then the answer, whatever bounds the backend took as active); else the
    minimiser with the bounds within ``tol`` of ``dq`` held (:func:`polish_least_squares`)
    if the gradient there pushes each of them outwards to ``kkt_rtol`` times the KKT scale
    of ``dq`` plus ``kkt_atol`` (the KKT signs: the free joints' gradient is zero by
    construction); else scipy's bounded least squares (BVLS) on the same rows; ``dq``
    itself if none lies in the bounds. The active set and the scale are those of
    :meth:`~optik.programs.diff_qp.DiffIKProgram.kkt` with ``active_tol = tol``.
    """
    rows = _stacked_rows(program)  # built once for both solves
    free = polish_least_squares(program, dq, np.zeros(program.dof, dtype=bool), rows)
    if free is not None and program.bound_violation(free) <= tol:
        return program.clip(free)
    lower = np.isfinite(program.lower) & (dq - program.lower <= tol)
    upper = np.isfinite(program.upper) & (program.upper - dq <= tol)
    held = polish_least_squares(program, dq, lower | upper, rows)
    if held is not None and program.bound_violation(held) <= tol:
        g = program.gradient(held)
        scale = float(
            np.max(np.abs(program.P)) * np.max(np.abs(dq), initial=0.0)
            + np.max(np.abs(program.c), initial=0.0)
        )
        slack = kkt_rtol * scale + kkt_atol
        if np.all(g[lower] >= -slack) and np.all(g[upper] <= slack):
            return program.clip(held)
    exact = bounded_least_squares(program)
    if exact is not None and program.bound_violation(exact) <= tol:
        return program.clip(exact)
    return dq


def polish_least_squares(
    program: DiffIKProgram,
    dq: FloatArray,
    active: np.ndarray,
    rows: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray | None:
    """The least-squares step on the backend's active set, solved in square-root form.

    With the joints of ``active`` (dof,) held on the bound nearer ``dq``, the others
    minimise ``||Wt^(1/2) (J dq - v)||^2 + lambda^2 ||W^(1/2) (dq - d)||^2`` exactly:
    one ``lstsq`` of the stacked rows, whose condition number is the square root of the
    QP's (a backend solving ``P = J^T Wt J + lambda^2 W`` loses twice the digits: with
    one weight 1e12 times the others, every backend's step was off by 1e-3 to 3 rad and
    the KKT test, relative to that weight, passed it). ``rows`` is ``(A, b)`` of the
    program's stacked rows when the caller has them. ``None`` with no free joint.
    """
    free = ~active
    if not np.any(free):
        return None
    A, b = _stacked_rows(program) if rows is None else rows
    # On the bound itself, not where the backend left the joint (it may stop 1e-7 short).
    with np.errstate(invalid="ignore"):
        nearer = np.where(dq - program.lower <= program.upper - dq, program.lower, program.upper)
    held = np.where(active, nearer, 0.0)
    x, *_ = np.linalg.lstsq(A[:, free], b - A @ held, rcond=None)
    out = held.copy()
    out[free] = x
    return out if np.all(np.isfinite(out)) else None


def _stacked_rows(program: DiffIKProgram) -> tuple[FloatArray, FloatArray]:
    """``(A, b)`` with ``||A dq - b||^2`` twice the least-squares objective."""
    offset = np.zeros(program.dof) if program.offset is None else program.offset
    lam = program.damping
    A = np.vstack([_root_times(program.Wt, program.J), lam * _root_times(program.W, None)])
    b = np.concatenate([_root_times(program.Wt, program.v), lam * _root_times(program.W, offset)])
    return A, b


def _root_times(M: FloatArray, X: FloatArray | None) -> FloatArray:
    """``M^(1/2) X`` for a symmetric positive semidefinite ``M`` (``X = None``: ``I``).

    A diagonal ``M`` (the weights of ``diff_ik``) scales rows; another one is rooted by
    its eigendecomposition.
    """
    d = np.diagonal(M)
    if np.array_equal(M, np.diag(d)):
        root = np.sqrt(np.maximum(d, 0.0))
        if X is None:
            return np.diag(root)
        return root[:, None] * X if X.ndim == 2 else root * X
    values, vectors = np.linalg.eigh(M)
    full = (vectors * np.sqrt(np.maximum(values, 0.0))) @ vectors.T
    return np.asarray(full if X is None else full @ X)


def bounded_least_squares(program: DiffIKProgram) -> FloatArray | None:
    """The least-squares step by scipy's BVLS on the square-root rows (about 0.2 ms)."""
    from scipy.optimize import lsq_linear

    A, b = _stacked_rows(program)
    try:
        result = lsq_linear(A, b, bounds=(program.lower, program.upper), method="bvls", tol=1e-15)
    except (ValueError, np.linalg.LinAlgError):  # pragma: no cover - bounds checked before
        return None
    x = np.asarray(result.x, dtype=np.float64)
    return x if np.all(np.isfinite(x)) else None
