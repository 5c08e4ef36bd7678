"""Jacobian iterations: pseudoinverse, transpose, and damped least squares.

All three respect the joint limits by projection: after each step, ``q`` is clamped to
``[lower, upper]`` (the box is convex, so the clamp is the Euclidean projection).
"""

from __future__ import annotations

import math
from abc import abstractmethod

import numpy as np

from optik._checks import FloatArray
from optik.solvers._base import (
    IKQuery,
    IKSolver,
    RunOutput,
    SolverOutput,
    budget_now,
    register,
    run_lm,
)
from optik.solvers._lm_kernel import STALL_RATIO, STALL_WINDOW, lm_solve_restarts
from optik.solvers._starts import StartSequence


class _JacobianIteration(IKSolver):
    """Shared loop: ``q <- clip(q + step(J, e))`` until both errors are within ``tol``."""

    default_max_iter = 1000

    def __init__(self, step: float = 1.0) -> None:
        self.step = float(step)

    @abstractmethod
    def direction(self, J: FloatArray, e: FloatArray) -> FloatArray:
        """The joint step (dof,) for task Jacobian rows ``J`` and task error ``e``."""

    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Iterate the Jacobian update from ``q0`` (see the class docstring)."""
        robot = query.robot
        lower, upper = query.lower, query.upper
        # A frozen joint (its bounds one value) has no column: the step of the others must
        # not count on it moving (clipped back after the step, it left them short).
        held = np.flatnonzero(lower == upper)
        q = np.clip(q0, lower, upper)
        for it in range(max_iter + 1):
            T, J = robot.fk_jacobian(q)
            e = query.error_vector(T)
            if query.converged(T):
                return SolverOutput(q, it, True, "converged")
            if it == max_iter:
                return SolverOutput(q, it, False, "max_iter")
            if budget_now() > deadline:
                return SolverOutput(q, it, False, "timeout")
            rows = query.task_rows(J)
            if held.size:
                rows = rows.copy()
                rows[:, held] = 0.0
            dq = self.direction(rows, e)
            if not np.all(np.isfinite(dq)):
                return SolverOutput(q, it, False, "non-finite step", failed=True)
            q = np.clip(q + self.step * dq, lower, upper)
        return SolverOutput(q, max_iter, False, "max_iter")  # pragma: no cover


@register
class PinvSolver(_JacobianIteration):
    """Pseudoinverse iteration (seed 003 Algorithm 1, seed 001 §5).

    ``dq = step * J^+ e`` with ``J^+`` the Moore–Penrose pseudoinverse (SVD, as in seed
    001), which also handles rank-deficient task Jacobians (e.g. a planar arm's zero rows).
    """

    name = "pinv"
    default_max_iter = 100  # full Newton steps: converges in a few, or not at all

    def direction(self, J: FloatArray, e: FloatArray) -> FloatArray:
        """``J^+ e``."""
        return np.linalg.pinv(J, rcond=1e-10) @ e


@register
class TransposeSolver(_JacobianIteration):
    """Jacobian-transpose iteration (seed 001 §6).

    ``dq = alpha J^T e`` with the step ``alpha = <e, J J^T e> / ||J J^T e||^2``, the
    minimiser of ``||e - alpha J J^T e||`` along the transpose direction.
    """

    name = "transpose"

    def direction(self, J: FloatArray, e: FloatArray) -> FloatArray:
        """``alpha J^T e`` with the optimal scalar step."""
        g = J.T @ e
        Jg = J @ g
        denominator = float(Jg @ Jg)
        if denominator == 0.0:
            return np.zeros_like(g)
        return (float(e @ Jg) / denominator) * g


@register
class DLSSolver(IKSolver):
    """Damped least squares (Levenberg–Marquardt) with adaptive damping, compiled.

    Each iteration solves ``min ||J dq - e||^2 + lambda ||dq||^2``, i.e.
    ``(J^T J + lambda I) dq = J^T e`` with ``lambda = s (e^T e / 2 + w)`` (Sugihara's
    damping, with the scale ``s`` adapted by Marquardt's accept/reject rule), then projects
    ``q + dq`` onto the joint limits. See :mod:`optik.solvers._lm_kernel`.
    """

    name = "dls"
    default_max_iter = 100
    balanced = True
    w_bias = 1e-3

    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Run the compiled projected LM from ``q0``."""
        q, it, ok = run_lm(query, q0, max_iter, self.w_bias, STALL_WINDOW, STALL_RATIO)
        return SolverOutput(q, it, ok, "converged" if ok else "stalled or max_iter")

    def attempts(
        self,
        query: IKQuery,
        starts: StartSequence,
        max_iter: int,
        last: int,
        deadline: float,
        start: int = 0,
    ) -> RunOutput:
        """:meth:`IKSolver.attempts` in the compiled kernel, in slices of attempts.

        The attempts run inside :func:`optik.solvers._lm_kernel.lm_solve_restarts`, a slice
        at a time: between slices Python checks the deadline and lets a ``KeyboardInterrupt``
        through. Start ``k`` does not depend on the slicing, so the answer is the same with
        and without a deadline (until the deadline cuts the run short). With a deadline the
        slices start at one attempt and double up to :data:`TIMED_SLICE`; without one they
        hold :data:`UNTIMED_SLICE` attempts.
        """
        chain = query.robot.chain.kernel_args(query.bounds)
        timed = math.isfinite(deadline)
        size = 1 if timed else UNTIMED_SLICE
        first = start
        total = 0
        best_q: FloatArray | None = None
        best_error = math.inf
        while True:
            hi = min(first + size - 1, last)
            q, it, ran, ok, pos, rot = lm_solve_restarts(
                chain, query.target, query.spec.packed, starts.given, starts.table, int(max_iter),
                self.w_bias, first, hi, starts.seed,
            )  # fmt: skip
            total += int(it)
            if ok:
                used = first + int(ran) - 1 - start
                return RunOutput(q, total, used, True, "converged", "max_iter")
            if best_q is None or pos + rot < best_error:
                best_q, best_error = q, pos + rot
            first = hi + 1
            if first > last:
                used = last - start
                return RunOutput(best_q, total, used, False, "stalled or max_iter", "max_iter")
            if budget_now() > deadline:
                message = "stalled or max_iter"
                return RunOutput(best_q, total, first - 1 - start, False, message, "timeout")
            if timed:
                size = min(2 * size, TIMED_SLICE)


UNTIMED_SLICE = 256
"""Attempts per compiled call without a deadline: a call returns to Python (and so to
Ctrl-C) at least every 256 attempts, a few milliseconds."""

TIMED_SLICE = 16
"""Largest slice with a deadline: the deadline is checked at least every 16 attempts
(under a millisecond on a 7-dof arm)."""
