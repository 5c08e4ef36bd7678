"""Compiled posture refinement: a verified answer moved to the nearest point of the task.

The program, from a configuration ``q`` that solves the task::

    min  1/2 ||q - q_ref||_W^2   s.t.   e(q) = 0,   lower <= q <= upper

with ``W = diag(w)`` and ``e`` the task residual of :func:`optik.task.task_error` (its
rows ``J`` from :func:`optik.task.task_rows`; rows whose task weight is zero drop out).
Each iteration takes the quadratic program's step under the linearised task (sequential
quadratic programming). The first step is the weighted least-norm step towards ``q_ref``::

    d  = q_ref - q
    dq = d + W^-1 J^T (J W^-1 J^T + mu I)^-1 (e - J d)

later ones replace ``W`` by a damped BFGS model ``B`` of the Lagrangian's Hessian (``W``
plus the task's curvature times its multipliers), ``dq = B^-1 (J^T lam - W (q - q_ref))``
with ``J dq = e``: with ``W`` alone the iteration converges only linearly, at a rate set by
that curvature (measured from 30 random Panda answers: 13.5 iterations in the median and
up to 35, against 6.5 and 12). ``mu`` is 0 unless the small system is not positive
definite. Joints on a bound whose step points outward are held there (their columns
dropped, as in :mod:`optik.solvers._lm_kernel`), and so are frozen joints (lower =
upper); a first trial that would cross a bound stops on it. The trial ``q + s dq`` (``s``
halved from there) is brought back onto the task by Gauss–Newton least-norm steps
``W^-1 J^T (J W^-1 J^T)^-1 e`` until both errors are within :data:`TIGHTEN` of the
tolerances, and accepted if the Lagrangian ``1/2 ||q - q_ref||_W^2 + lam^T e`` fell (or,
in the last digits, see :data:`NOISE_REGIME`, if the optimality measure did). It stops
when the first-order optimality measure

    ||W (q - q_ref) - J^T lambda|| / ||W (q - q_ref)||     (least-squares lambda, free joints)

— the part of the gradient outside the row space of the task Jacobian — is at most
:data:`OPTIMALITY_TOL`, when no step is accepted, or after ``max_iter`` iterations.
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import cholesky_factor, cholesky_solve, cholesky_substitute
from optik._nrt import borrowed
from optik._numba import inline, jit
from optik.chain import KernelChain
from optik.solvers._lm_kernel import (
    QUICK_ATTEMPTS,
    QUICK_RATIO,
    QUICK_WINDOW,
    STALL_RATIO,
    STALL_WINDOW,
    _borrow_chain,
    _evaluate,
    lm_attempt,
    workspace,
)
from optik.solvers._starts import nearest_table, start_into
from optik.task import task_converged

# The helpers of the inner loops are inlined into their callers (numba IR): as calls, the
# reference counting of the scratch arrays they take made posture_refine 5-7 % slower
# (measured on the Panda, 100 pose and 100 axis targets, against the code they replaced,
# which repeated them in place; inlined, within 1 %).

TIGHTEN = 1e-3
"""The answer is kept on the task to this fraction of its tolerances: a descent inside the
tolerance band would stop at the band's edge, short of the optimum, and the optimality
measure at a point 1e-9 off the task is good to about 1e-9."""

OPTIMALITY_TOL = 1e-9
"""Stop when the first-order optimality measure (see the module) is at most this."""

RESTORE_STEPS = 10
"""Gauss–Newton steps that bring a trial point back onto the task."""

ACTIVE = 1e-10
"""A joint this close to a bound (rad / m) is on it: held there when a step points out."""

NOISE_REGIME = 1e-6
"""Below this optimality measure the distance's decrease along a step (about the measure
squared, relative) drowns in the rounding of forward kinematics (1e-16): there a restored
trial is also accepted when it lowers the measure itself."""

LINE_STEPS = 12
"""Halvings of the step before an iteration gives up."""

RIDGE = 1e-12
"""``mu`` relative to ``max(1, trace(J W^-1 J^T))``, added only when the small system is
not numerically positive definite (a singular configuration): a ridge everywhere would
move the iteration's fixed point off the optimum by about ``mu / sigma_min(J)^2``
(measured: an optimality floor near 1e-9 with this ridge always on)."""


@inline
def _row_space_step(
    J: np.ndarray,
    rows: np.ndarray,
    X: np.ndarray,
    free: np.ndarray,
    v: np.ndarray,
    A: np.ndarray,
    L: np.ndarray,
    lam: np.ndarray,
    out: np.ndarray,
) -> bool:
    """``out += X lam`` with ``(J X + mu I) lam = v``, over the free columns and the ``rows``.

    ``X`` (dof, m) is ``M^-1 J^T`` for a positive definite metric ``M`` of the free joints
    (column ``a`` for the row ``rows[a]``; held joints' entries are not read), so the step
    added is the one of least ``M``-norm that changes ``J out`` by ``v`` (m,): the
    least-norm step of :func:`_least_norm` (``M = W``) and the quadratic program's step of
    :func:`_sqp_step` (``M = B``). ``mu`` is 0 unless ``J X`` is not numerically positive
    definite (:data:`RIDGE`). ``lam`` (m,) receives the multipliers; ``A`` (m, m) and ``L``
    (m, m + 1) are scratch. Held joints get 0. False if the system is not positive
    definite even with the ridge (then ``out`` is not written).
    """
    m = rows.shape[0]
    dof = X.shape[0]
    trace = 0.0
    for a in range(m):
        ra = rows[a]
        for b in range(a + 1):
            s = 0.0
            for i in range(dof):
                if free[i]:
                    s += J[ra, i] * X[i, b]
            A[a, b] = s
            A[b, a] = s
        trace += A[a, a]
    if not cholesky_solve(A, v, lam, L):
        mu = RIDGE * max(1.0, trace)
        for a in range(m):
            A[a, a] += mu
        if not cholesky_solve(A, v, lam, L):
            return False
    for i in range(dof):
        if free[i]:
            s = out[i]
            for a in range(m):
                s += X[i, a] * lam[a]
            out[i] = s
        else:
            out[i] = 0.0
    return True


@inline
def _least_norm(
    J: np.ndarray,
    rows: np.ndarray,
    v: np.ndarray,
    w_inv: np.ndarray,
    free: np.ndarray,
    X: np.ndarray,
    A: np.ndarray,
    L: np.ndarray,
    lam: np.ndarray,
    out: np.ndarray,
) -> bool:
    """``out = W^-1 J^T (J W^-1 J^T + mu I)^-1 v`` over the free columns and the ``rows``.

    ``v`` (m,) is indexed like ``rows`` (m,); ``w_inv`` (dof,) holds ``1 / w``; ``X`` (dof,
    m), ``A`` (m, m), ``L`` (m, m + 1) and ``lam`` (m,) are scratch. Held joints get 0.
    False if the system is not positive definite (:func:`_row_space_step`).
    """
    for i in range(J.shape[1]):
        for a in range(rows.shape[0]):
            X[i, a] = w_inv[i] * J[rows[a], i]
        out[i] = 0.0
    return _row_space_step(J, rows, X, free, v, A, L, lam, out)


@inline
def _hold_outward(
    x: np.ndarray, step: np.ndarray, lower: np.ndarray, upper: np.ndarray, free: np.ndarray
) -> bool:
    """Hold the free joints of ``x`` that lie on a bound ``step`` points out through.

    A joint within :data:`ACTIVE` of a bound is on it; a held joint gets ``free[i] =
    False``. True if any joint was held (the step is then to be taken again).
    """
    blocked = False
    for i in range(x.shape[0]):
        if free[i] and (
            (x[i] <= lower[i] + ACTIVE and step[i] < 0.0)
            or (x[i] >= upper[i] - ACTIVE and step[i] > 0.0)
        ):
            free[i] = False
            blocked = True
    return blocked


@jit
def _optimality(
    J: np.ndarray,
    rows: np.ndarray,
    g: np.ndarray,
    free: np.ndarray,
    ones: np.ndarray,
    X: np.ndarray,
    A: np.ndarray,
    L: np.ndarray,
    lam: np.ndarray,
    v: np.ndarray,
    r: np.ndarray,
) -> float:
    """``||g - J^T lambda|| / ||g||`` over the free joints, ``lambda`` the least-squares fit.

    The part of the gradient ``g`` (dof,) outside the row space of the free columns of
    ``J``: 0 at a first-order optimum (0 also when ``g`` is 0). ``ones`` (dof,) is the unit
    metric; ``v`` (m,) and ``r`` (dof,) are scratch, the others as in :func:`_least_norm`.
    """
    m = rows.shape[0]
    dof = g.shape[0]
    norm = 0.0
    for i in range(dof):
        if free[i]:
            norm += g[i] * g[i]
    if norm == 0.0:
        return 0.0
    for a in range(m):
        s = 0.0
        for i in range(dof):
            if free[i]:
                s += J[rows[a], i] * g[i]
        v[a] = s
    if not _least_norm(J, rows, v, ones, free, X, A, L, lam, r):
        return math.inf
    res = 0.0
    for i in range(dof):
        if free[i]:
            res += (g[i] - r[i]) ** 2
    return math.sqrt(res / norm)


@jit
def _sqp_step(
    B: np.ndarray,
    J: np.ndarray,
    rows: np.ndarray,
    e: np.ndarray,
    g: np.ndarray,
    free: np.ndarray,
    Bf: np.ndarray,
    LB: np.ndarray,
    X: np.ndarray,
    A: np.ndarray,
    L: np.ndarray,
    lam: np.ndarray,
    v: np.ndarray,
    dq: np.ndarray,
) -> bool:
    """The quadratic program's step over the free joints: ``dq = B^-1 (J^T lam - g)``, ``J dq = e``.

    ``B`` (dof, dof) is the Hessian model, ``g`` (dof,) the cost's gradient, ``e`` (6,) the
    task residual; ``lam`` (m,) receives the multipliers. With ``B = W`` this is the step
    of the module. Held joints get 0. ``Bf`` (dof, dof), ``LB`` (dof, dof + 1), ``X`` (dof,
    m), ``A`` (m, m), ``L`` (m, m + 1) and ``v`` (m,) are scratch. False if a system is
    not positive definite.
    """
    m = rows.shape[0]
    dof = g.shape[0]
    for i in range(dof):
        for j in range(dof):
            Bf[i, j] = B[i, j] if (free[i] and free[j]) else 0.0
        if not free[i]:
            Bf[i, i] = 1.0
    if not cholesky_factor(Bf, LB):
        return False
    # X = B^-1 J^T (columns: the rows of J), dq = -B^-1 g to start with.
    for a in range(m):
        for i in range(dof):
            dq[i] = J[rows[a], i] if free[i] else 0.0
        cholesky_substitute(LB, dq, dq)
        for i in range(dof):
            X[i, a] = dq[i]
    for i in range(dof):
        dq[i] = -g[i] if free[i] else 0.0
    cholesky_substitute(LB, dq, dq)
    # Then the least-B-norm correction that brings J dq to e.
    for a in range(m):
        ra = rows[a]
        s = e[ra]
        for i in range(dof):
            if free[i]:
                s -= J[ra, i] * dq[i]
        v[a] = s
    return _row_space_step(J, rows, X, free, v, A, L, lam, dq)


@jit
def _bfgs_update(B: np.ndarray, s: np.ndarray, y: np.ndarray, Bs: np.ndarray) -> None:
    """Powell's damped BFGS update of ``B`` for the step ``s`` and gradient change ``y``.

    ``y`` is blended with ``B s`` where ``s^T y < 0.2 s^T B s``, so that ``B`` stays positive
    definite (the Lagrangian's Hessian need not be off the task's tangent space). ``Bs``
    (dof,) is scratch; ``y`` is overwritten.
    """
    n = s.shape[0]
    sBs = 0.0
    sy = 0.0
    for i in range(n):
        t = 0.0
        for j in range(n):
            t += B[i, j] * s[j]
        Bs[i] = t
        sBs += s[i] * t
        sy += s[i] * y[i]
    if not sBs > 0.0:
        return
    if sy < 0.2 * sBs:
        theta = 0.8 * sBs / (sBs - sy)
        sy = 0.0
        for i in range(n):
            y[i] = theta * y[i] + (1.0 - theta) * Bs[i]
            sy += s[i] * y[i]
    for i in range(n):
        for j in range(n):
            B[i, j] += y[i] * y[j] / sy - Bs[i] * Bs[j] / sBs


@jit
def _restore(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    tight_task: np.ndarray,
    rows: np.ndarray,
    w_inv: np.ndarray,
    allowed: np.ndarray,
    x: np.ndarray,
    evaluation: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    X: np.ndarray,
    A: np.ndarray,
    L: np.ndarray,
    lam: np.ndarray,
    v: np.ndarray,
    step: np.ndarray,
    hold: np.ndarray,
) -> bool:
    """Gauss–Newton least-norm steps on ``x`` until the tight task holds; True if it does.

    Only the ``allowed`` joints move, and of those not one on a bound that a step pushes
    outward (``hold`` is scratch). ``evaluation`` is ``(T, Jc, J, e, work, M)``, the
    arrays :func:`optik.solvers._lm_kernel._evaluate` fills: on return ``T``, ``J`` and
    ``e`` are ``x``'s.
    """
    T, Jc, J, e, work, M = evaluation
    lower, upper = chain[4], chain[5]
    m = rows.shape[0]
    dof = x.shape[0]
    k = 0
    while True:
        pos, rot = _evaluate(chain, x, target, task, T, Jc, J, e, work, M)
        if task_converged(pos, rot, tight_task):
            return True
        if k == RESTORE_STEPS:
            return False
        k += 1
        for a in range(m):
            v[a] = e[rows[a]]
        for i in range(dof):
            hold[i] = allowed[i]
        for _ in range(dof + 1):
            if not _least_norm(J, rows, v, w_inv, hold, X, A, L, lam, step):
                return False
            if not _hold_outward(x, step, lower, upper, hold):
                break
        for i in range(dof):
            x[i] = min(max(x[i] + step[i], lower[i]), upper[i])


@jit
def _task_rows_kept(task: np.ndarray) -> np.ndarray:
    """The residual's rows the program keeps (indices into the six, in order).

    Three for a plain point, else the six minus those whose task weight is zero
    (:mod:`optik.task`'s packed layout).
    """
    m_all = 3 if task[10] == 2.0 else 6
    rows = np.empty(m_all, dtype=np.int64)
    count = 0
    for r in range(m_all):
        if task[10] != 0.0 or task[r] > 0.0:
            rows[count] = r
            count += 1
    return rows[:count]


@jit
def posture_refine(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    q_inout: np.ndarray,
    q_ref: np.ndarray,
    weights: np.ndarray,
    max_iter: int,
) -> tuple[int, bool, float]:
    """Refine ``q_inout`` (dof,), which solves the task, towards ``q_ref`` (see the module).

    Args:
        chain: the chain (:meth:`optik.chain.Chain.kernel_args`), its limits the box:
            (dof,) lower and upper bounds (rad / m), margins and frozen joints included.
        target: (4, 4) target pose.
        task: the packed task (:attr:`optik.task.Task.packed`).
        q_inout: (dof,) the start, overwritten with the answer (left as it was, clipped
            into the bounds, when it cannot be brought within :data:`TIGHTEN` of the
            tolerances).
        q_ref: (dof,) the reference posture (rad / m).
        weights: (dof,) > 0, the joint weights ``W``.
        max_iter: most iterations.

    Returns:
        ``(iterations, converged, measure)``: ``converged`` when the optimality measure
        (see the module) is at most :data:`OPTIMALITY_TOL` at the answer, which is within
        :data:`TIGHTEN` of the tolerances; ``measure`` is ``inf`` when the start could not
        be tightened.
    """
    view = _borrow_chain(chain)
    prismatic, lower, upper = view[1], view[4], view[5]
    target = borrowed(target)
    task = borrowed(task)
    q_ref = borrowed(q_ref)
    weights = borrowed(weights)
    q_out = borrowed(q_inout)
    dof = q_out.shape[0]
    n = prismatic.shape[0]
    tight_task = task.copy()
    tight_task[8] *= TIGHTEN  # optik.task's layout: position then orientation tolerance
    tight_task[9] *= TIGHTEN
    rows = _task_rows_kept(task)
    m = rows.shape[0]
    J = np.empty((6, dof))
    e = np.empty(6)
    # T, Jc, J, e and the scratch of _evaluate (see _restore).
    evaluation = (np.empty((4, 4)), np.empty((6, n)), J, e, np.empty((n, 3)), np.empty((3, 4)))
    A = np.empty((m, m))
    L = np.empty((m, m + 1))
    lam = np.empty(m)
    v = np.empty(m)
    mult = np.zeros(m)
    e_q = np.empty(m)
    q = np.empty(dof)
    trial = np.empty(dof)
    dq = np.empty(dof)
    step = np.empty(dof)
    g = np.empty(dof)
    r_scratch = np.empty(dof)
    w_inv = np.empty(dof)
    ones = np.ones(dof)
    B = np.zeros((dof, dof))  # Hessian model of the Lagrangian, W to start with
    Bf = np.empty((dof, dof))
    LB = np.empty((dof, dof + 1))
    X = np.empty((dof, m))
    step_mult = np.zeros(m)
    J_q = np.empty((6, dof))
    y = np.empty(dof)
    Bs = np.empty(dof)
    movable = np.empty(dof, dtype=np.bool_)
    free = np.empty(dof, dtype=np.bool_)
    hold = np.empty(dof, dtype=np.bool_)
    for i in range(dof):
        w_inv[i] = 1.0 / weights[i]
        B[i, i] = weights[i]
        movable[i] = lower[i] < upper[i]
        q[i] = min(max(q_out[i], lower[i]), upper[i])
    # First onto the task, tightly: every movable joint may help.
    tight = _restore(
        view, target, task, tight_task, rows, w_inv, movable, q, evaluation, X, A, L, lam, v,
        step, hold,
    )  # fmt: skip
    if not tight:
        for i in range(dof):
            q_out[i] = min(max(q_out[i], lower[i]), upper[i])
        return 0, False, math.inf
    it = 0
    measure = math.inf
    while True:
        # The step, with the joints it pushes out through a bound held there.
        for i in range(dof):
            g[i] = weights[i] * (q[i] - q_ref[i])
            free[i] = movable[i]
        ok = False
        for _ in range(dof + 1):
            ok = _sqp_step(B, J, rows, e, g, free, Bf, LB, X, A, L, step_mult, v, dq)
            if not ok or not _hold_outward(q, dq, lower, upper, free):
                break
        measure = _optimality(J, rows, g, free, ones, X, A, L, lam, v, r_scratch)
        for a in range(m):
            mult[a] = lam[a]  # the multipliers of that fit, g = J^T mult
            e_q[a] = e[rows[a]]
        if not ok or measure <= OPTIMALITY_TOL or it >= max_iter:
            break
        it += 1
        J_q[:, :] = J
        # Backtrack until the trial, restored onto the task, is nearer q_ref; the first
        # trial stops where a joint meets its bound (next iteration holds it there).
        accepted = False
        s_len = 1.0
        for i in range(dof):
            if dq[i] < 0.0 and q[i] + s_len * dq[i] < lower[i]:
                s_len = (lower[i] - q[i]) / dq[i]
            elif dq[i] > 0.0 and q[i] + s_len * dq[i] > upper[i]:
                s_len = (upper[i] - q[i]) / dq[i]
        for _ in range(LINE_STEPS):
            for i in range(dof):
                trial[i] = min(max(q[i] + s_len * dq[i], lower[i]), upper[i])
            tight = _restore(
                view, target, task, tight_task, rows, w_inv, free, trial, evaluation, X, A, L,
                lam, v, step, hold,
            )  # fmt: skip
            if tight:
                # The change of the Lagrangian cost + mult^T e: within the tolerance band the
                # cost alone also changes with the residual (by about |g| tol), which would
                # drown the decrease of the last, small steps. The cost's change is summed
                # without the cancellation of two large costs.
                change = 0.0
                for i in range(dof):
                    change += weights[i] * (trial[i] - q[i]) * (trial[i] + q[i] - 2.0 * q_ref[i])
                change *= 0.5
                for a in range(m):
                    change += mult[a] * (e[rows[a]] - e_q[a])
                if change < 0.0:
                    accepted = True
                    break
                if measure < NOISE_REGIME:
                    for i in range(dof):
                        g[i] = weights[i] * (trial[i] - q_ref[i])
                    trial_measure = _optimality(J, rows, g, free, ones, X, A, L, lam, v, r_scratch)
                    if trial_measure < measure:
                        accepted = True
                        break
            s_len *= 0.5
        if not accepted:
            break  # the measure above is q's
        # BFGS on the Lagrangian's gradient W (q - q_ref) - J^T lam, lam the step's.
        for i in range(dof):
            step[i] = trial[i] - q[i]
            t = weights[i] * step[i]
            for a in range(m):
                t -= (J[rows[a], i] - J_q[rows[a], i]) * step_mult[a]
            y[i] = t
        _bfgs_update(B, step, y, Bs)
        q[:] = trial
    q_out[:] = q
    return it, measure <= OPTIMALITY_TOL, measure


@jit
def _distance(q: np.ndarray, q_ref: np.ndarray, weights: np.ndarray) -> float:
    """``||q - q_ref||_W^2``."""
    s = 0.0
    for i in range(q.shape[0]):
        s += weights[i] * (q[i] - q_ref[i]) ** 2
    return s


@jit
def posture_search(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    given: np.ndarray,
    table_q: np.ndarray,
    table_features: np.ndarray,
    table_centroids: np.ndarray,
    table_offsets: np.ndarray,
    mask: np.ndarray,
    max_iter: int,
    w_bias: float,
    last: int,
    seed: int,
    q_ref: np.ndarray,
    weights: np.ndarray,
    want: int,
    refine_iter: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int, int]:
    """Answers of attempts 0 to ``last`` (:func:`optik.solvers._lm_kernel.lm_attempt`), refined.

    The attempts take the starts of :func:`optik.solvers._starts.start_into` (``given``
    first, then the seed table ``table_*`` ranked by the feature weights ``mask``
    (:attr:`optik.solvers._starts.StartSequence.mask`) and seeded draws) with the stall
    rules of
    :func:`optik.solvers._lm_kernel.lm_solve_restarts`, and stop after ``want`` converged
    answers. The first answer is refined by :func:`posture_refine` (``refine_iter`` steps
    at most), and each later one only if it lies nearer ``q_ref`` (weighted) than the
    best refined so far: the refinement never moves away from ``q_ref``, so a farther
    answer can only end farther or equal.

    Returns:
        ``(answers (want, dof), refined (want, dof), kept (want,), converged (want,),
        measure (want,), count, iterations, attempts)``: the first ``count`` rows of
        ``answers`` are the LM answers, the rows of ``refined`` where ``kept`` their
        refinements (``converged`` and ``measure`` as :func:`posture_refine` returns
        them); ``iterations`` counts the LM iterations over all attempts, ``attempts``
        how many ran.
    """
    lower, upper = chain[4], chain[5]
    dof = lower.shape[0]
    scratch = workspace(chain[1].shape[0], dof)
    nearest = nearest_table(table_features, table_centroids, table_offsets, target, mask)
    answers = np.empty((want, dof))
    refined = np.empty((want, dof))
    converged = np.zeros(want, dtype=np.bool_)
    measure = np.full(want, np.inf)
    q = np.empty(dof)
    count = 0
    total = 0
    attempt = np.int64(0)  # not the literal 0: one signature of start_into
    while attempt <= last and count < want:
        start_into(attempt, given, nearest, table_q, lower, upper, seed, q)
        quick = attempt < QUICK_ATTEMPTS
        it, ok, _, _ = lm_attempt(
            chain, target, task, q, max_iter, w_bias, QUICK_WINDOW if quick else STALL_WINDOW,
            QUICK_RATIO if quick else STALL_RATIO, scratch,
        )  # fmt: skip
        total += it
        attempt += 1
        if ok:
            answers[count] = q
            count += 1
    # An answer farther from q_ref than a refined one cannot beat it: the refinement only
    # lowers the distance. So only answers nearer than the best so far are refined.
    best = np.inf
    kept = np.zeros(want, dtype=np.bool_)
    for k in range(count):
        if _distance(answers[k], q_ref, weights) >= best:
            continue
        refined[k] = answers[k]
        _, good, value = posture_refine(
            chain, target, task, refined[k], q_ref, weights, refine_iter
        )
        converged[k] = good
        measure[k] = value
        kept[k] = True
        best = min(best, _distance(refined[k], q_ref, weights))
    return answers, refined, kept, converged, measure, count, total, attempt
