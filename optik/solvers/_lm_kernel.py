"""Compiled damped-least-squares (Levenberg–Marquardt) IK with box limits.

Each iteration solves ``(J^T J + lambda I) dq = J^T e`` for the task error ``e`` (position,
and the rotation vector ``log(R* R^T)`` in pose mode), projects ``q + dq`` onto the joint
limits (a clamp: the box is the feasible set, so this is a projected step), and accepts
it only if the error norm decreases; otherwise the damping grows (Marquardt's rule).
The damping follows Sugihara's choice ``lambda = E + w`` with ``E = e^T e / 2``, which is
large far from the target (gradient-like steps) and vanishes near it (Gauss–Newton
steps, quadratic convergence).

FK and the Jacobian come from :mod:`optik._kernels`, the same code as ``Robot.fk``.
"""

from __future__ import annotations

import math

import numpy as np

from optik._kernels import drives_slide, fk_jacobian_work
from optik._math import cholesky_solve
from optik._nrt import borrowed
from optik._numba import inline, jit
from optik.chain import KernelChain
from optik.solvers._starts import nearest_table, start_into
from optik.task import task_converged, task_error, task_features, task_rows

KernelTable = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""A seed table as the solvers take it: :meth:`optik.solvers._seeds.SeedTable.kernel_args`."""

BatchJob = tuple[
    np.ndarray, np.ndarray, np.ndarray, KernelTable, tuple[int, float, int], np.ndarray
]
"""A batch's targets and settings: ``(targets (N, 4, 4), task (packed, :mod:`optik.task`),
given starts (P, G, dof), seed table, (max_iter, w_bias, restarts), seeds (N,))``; target
``k`` starts from ``given[k]`` when ``P == N`` (its own starts), else from ``given[0]``
(shared), and uses the random stream ``seeds[k]``."""

BatchOutput = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""A batch's answers: ``(q (N, dof), iterations (N,), restarts (N,), ok (N,))``."""


@inline
def _borrow_chain(chain: KernelChain) -> KernelChain:
    """Borrowed views (:mod:`optik._nrt`) of the chain's arrays; the caller owns ``chain``."""
    K, prismatic, C, identity, lower, upper = chain
    return borrowed(K), borrowed(prismatic), borrowed(C), identity, borrowed(lower), borrowed(upper)


@jit
def _evaluate(
    chain: KernelChain,
    q: np.ndarray,
    target: np.ndarray,
    task: np.ndarray,
    T: np.ndarray,
    Jc: np.ndarray,
    J: np.ndarray,
    e: np.ndarray,
    work: np.ndarray,
    M: np.ndarray,
) -> tuple[float, float]:
    """FK, the task's Jacobian rows (in q) and residual at ``q``.

    Returns the judged (position, orientation) errors (:mod:`optik.task`).
    """
    K, prismatic, C, identity, _, _ = chain
    if identity:
        fk_jacobian_work(K, prismatic, q, T, J, work)
    else:
        theta = C @ q
        fk_jacobian_work(K, prismatic, theta, T, Jc, work)
        J[:, :] = Jc @ C
    errors = task_error(T, target, task, e, M)
    # optik.task: a full rotation (_KIND 1) in the target frame (_FAST 0) whose weights
    # differ between the rotation rows needs the rotation vector's own derivative; so
    # does a tool axis (_KIND 2, axis _AXIS) whose two constrained rotation rows differ.
    if task[6] == 1.0 and task[10] == 0.0 and (task[3] != task[4] or task[4] != task[5]):
        _log_derivative_rows(J, M)
    elif task[6] == 2.0:
        k = int(task[7])
        if task[3 + (k + 1) % 3] != task[3 + (k + 2) % 3]:
            _axis_derivative_rows(J, T, target, k)
    task_rows(J, target, task)
    return errors


@jit
def _log_derivative_rows(J: np.ndarray, M: np.ndarray) -> None:
    """``J[3:6] <- Jr^-1(r) J[3:6]``: the derivative of the rotation error ``r``.

    ``r = log(R* R^T)`` is in ``M[:, 3]`` (:func:`optik.task.task_error`). Turning the tool
    by ``w dt`` (world frame) changes ``r`` by ``-Jr^-1(r) w dt`` (``Jr`` the right
    Jacobian of SO(3)), not by ``-w dt``: the two agree at ``r = 0`` and their squared
    norms' gradients agree whatever ``r`` (``r^T Jr^-1(r) = r^T``), so equal rotational
    weights need no correction, unequal ones do (without it the compromise of a UR5
    target was 5 % above the weighted minimum).
    ``Jr^-1(r) v = v + r x v / 2 + c (r x (r x v))``, ``c = 1/t^2 - cot(t/2) / (2 t)``.
    """
    r0, r1, r2 = M[0, 3], M[1, 3], M[2, 3]
    t2 = r0 * r0 + r1 * r1 + r2 * r2
    if t2 < 1e-4:  # the series: no cancellation of two large terms
        c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    else:
        t = math.sqrt(t2)
        c = 1.0 / t2 - math.cos(0.5 * t) / (math.sin(0.5 * t) * 2.0 * t)
    for a in range(J.shape[1]):
        v0, v1, v2 = J[3, a], J[4, a], J[5, a]
        x0 = r1 * v2 - r2 * v1
        x1 = r2 * v0 - r0 * v2
        x2 = r0 * v1 - r1 * v0
        y0 = r1 * x2 - r2 * x1
        y1 = r2 * x0 - r0 * x2
        y2 = r0 * x1 - r1 * x0
        J[3, a] = v0 + 0.5 * x0 + c * y0
        J[4, a] = v1 + 0.5 * x1 + c * y1
        J[5, a] = v2 + 0.5 * x2 + c * y2


AXIS_SERIES_ANGLE = 1e-4
"""Angle (rad) between the tool axis and its target below which
:func:`_axis_derivative_rows` takes the series of its ``g(theta)`` (no cancellation)."""

OPPOSITE_AXIS_SINE = 1e-9
"""Sine of the angle between an axis pointing away from its target (``a . a* < 0``) and
that target below which :func:`_axis_derivative_rows` leaves the rows as they are: the
residual's direction is a convention there (:func:`optik.task._axis_rotation`), not a
derivative."""


@jit
def _axis_derivative_rows(J: np.ndarray, T: np.ndarray, target: np.ndarray, k: int) -> None:
    """``J[3:6] <- -D J[3:6]``: the derivative of a tool axis's rotation error ``r``.

    ``r = theta v / s`` (:func:`optik.task.task_error`) with ``a`` the tool's
    axis ``k`` (``T[:3, k]``), ``b`` the target's, ``v = a x b``, ``s = |v|``, ``c = a . b``
    and ``theta = atan2(s, c)``. Turning the tool by ``w dt`` (world frame) turns ``a`` by
    ``w x a dt`` and changes ``r`` by ``D w dt``,
    ``D = (theta / s) (a b^T - c I) + g v v^T``, ``g = (theta c / s - 1) / s^2``.
    At ``a = b``, ``-D`` is the projection off ``a``: the angular velocity's rows, whose
    spin about ``a`` the zero weight of the free row drops there, and only there (checked
    against finite differences in the tests). Equal weights on the two constrained rows need no
    correction (the gradient of ``theta^2 / 2`` is the same either way), unequal ones do:
    without it a narrowed Panda's compromise with weights ``[1, 1, 1, 1, 3, 0]`` stopped
    18 % above the weighted minimum.
    """
    ax, ay, az = T[0, k], T[1, k], T[2, k]
    bx, by, bz = target[0, k], target[1, k], target[2, k]
    c = ax * bx + ay * by + az * bz
    vx, vy, vz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    if c < 0.0 and s < OPPOSITE_AXIS_SINE:
        return
    theta = math.atan2(s, c)
    if theta < AXIS_SERIES_ANGLE:
        f = 1.0 + theta * theta / 6.0  # theta / sin(theta)
        g = -1.0 / 3.0 - 2.0 * theta * theta / 15.0
    else:
        f = theta / s
        g = (theta * c / s - 1.0) / (s * s)
    for col in range(J.shape[1]):
        w0, w1, w2 = J[3, col], J[4, col], J[5, col]
        bw = bx * w0 + by * w1 + bz * w2
        vw = g * (vx * w0 + vy * w1 + vz * w2)
        J[3, col] = -(f * (ax * bw - c * w0) + vx * vw)
        J[4, col] = -(f * (ay * bw - c * w1) + vy * vw)
        J[5, col] = -(f * (az * bw - c * w2) + vz * vw)


MIN_DAMPING_SCALE = 1e-6
"""Floor of Marquardt's scale on ``lambda`` after accepted steps. With ``w = 1e-3`` the
damping can fall to 1e-9, below the squared smallest singular value of a Jacobian
1e-4 rad from a singularity, so steps there stay Gauss–Newton steps. A floor of 1e-3
(damping >= 1e-6) left targets next to a folded elbow crawling (measured: a planar 2R
attempt from 0.01 rad away still short of 1e-9 after 100 iterations, 19 with this floor;
1 in 5,000 planar 2R and DOBOT targets failed after 100 restarts, none with it)."""

STALL_WINDOW = 8
STALL_RATIO = 0.5
"""An attempt stops when ``STALL_WINDOW`` iterations did not cut the squared error
``e^T e`` to ``STALL_RATIO`` of what it was: restarting beats crawling."""

STALL_FLOOR = 1e-8
"""No stall stop once ``e^T e`` is below this (errors of about 1e-4 m or rad): next to a
singularity the last digits converge linearly, slower than any stall rule allows, but
they do converge (measured: the 2 failures in 20,000 random Panda targets, both with
``sigma_min(J) < 1e-3`` at the answer, converge with this floor, at no cost in
iterations)."""

QUICK_ATTEMPTS = 4
QUICK_WINDOW = 3
QUICK_RATIO = 0.7
"""The first ``QUICK_ATTEMPTS`` attempts of :func:`lm_solve_restarts` (the nearest
starts) give up sooner, after ``QUICK_WINDOW`` iterations without a cut to
``QUICK_RATIO``. Measured on 4,000 random Panda targets (with a 256-entry seed table, before
the clustered one): a third of the attempts from the nearest table entries fail, and they
ran 17.6 iterations before the rule above stopped them, more than half of all iterations;
the quick rule cut the iterations per target by a quarter (18.6 to 14.0) at the price of
more restarts (0.57 to 0.71). Later attempts keep the patient rule, so targets that need
a slow start still converge."""


WIDE_CHAIN_DOF = 32
"""Chains with more inputs than this solve each step in the task's space
(:func:`_wide_step`: a 6 x 6 system, work linear in ``dof``) instead of the joints'
(a ``dof x dof`` Cholesky factorisation, work cubic in ``dof``). The two steps are equal
in exact arithmetic; robot arms (at most a few dozen joints) keep the joints' system,
whose rounding their tests and seed tables were measured with. Measured on a chain of
2,000 revolute joints: one iteration took about 0.5 s with the joints' system."""


@jit
def workspace(n_chain: int, dof: int) -> tuple[np.ndarray, ...]:
    """Scratch arrays of :func:`lm_attempt` for a chain of ``n_chain`` joints, ``dof`` inputs."""
    n = 6 if dof > WIDE_CHAIN_DOF else dof  # the step's system (_wide_step: 6 x 6)
    return (
        np.empty((4, 4)),  # T: pose at q
        np.empty((6, dof)),  # J: Jacobian at q
        np.empty(6),  # e: task error at q
        np.empty((4, 4)),  # T_new, J_new, e_new, q_new: at the trial point
        np.empty((6, dof)),
        np.empty(6),
        np.empty(dof),
        np.empty((6, n_chain)),  # Jc: chain Jacobian (coupled robots)
        np.empty((n_chain, 3)),  # joint origins
        np.empty((3, 4)),  # relative rotation and rotation vector
        np.empty((n, n)),  # A = J^T J + lambda I (wide chains: J D^-1 J^T + I)
        np.empty(dof),  # g = J^T e (wide chains: the damping's reciprocals)
        np.empty(dof),  # dq
        np.empty((n, n + 1)),  # Cholesky factor and reciprocal diagonal
        np.empty(16),  # error history (a ring of the last 16 iterations)
        np.empty(6),  # the wide step's multipliers
    )


@inline
def _slides(view: KernelChain, a: int) -> bool:
    """Whether joint ``a`` drives a prismatic joint of the chain ``view``."""
    return drives_slide(view[1], view[2], view[3], a)


@jit
def lm_attempt(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    q_inout: np.ndarray,
    max_iter: int,
    w_bias: float,
    window: int,
    ratio: float,
    scratch: tuple[np.ndarray, ...],
) -> tuple[int, bool, float, float]:
    """Projected Levenberg–Marquardt from ``q_inout`` (dof,), which it overwrites.

    ``scratch`` comes from :func:`workspace`. The attempt stops when converged, after
    ``max_iter`` iterations, or when ``window`` iterations did not cut ``e^T e`` to
    ``ratio`` of its value (``window`` <= 16) while it is above :data:`STALL_FLOOR`.

    Returns:
        ``(iterations, converged, position_error, orientation_error)``; ``converged``
        means both judged errors are within the task's tolerances (:mod:`optik.task`),
        with ``q`` inside the limits.
    """
    # Borrowed views (optik._nrt): the iteration passes these arrays to helpers many
    # times; their owners are this call's arguments.
    view = _borrow_chain(chain)
    lower = view[4]
    upper = view[5]
    target = borrowed(target)
    task = borrowed(task)
    q = borrowed(q_inout)
    T = borrowed(scratch[0])
    J = borrowed(scratch[1])
    e = borrowed(scratch[2])
    T_new = borrowed(scratch[3])
    J_new = borrowed(scratch[4])
    e_new = borrowed(scratch[5])
    q_new = borrowed(scratch[6])
    Jc = borrowed(scratch[7])
    work = borrowed(scratch[8])
    M = borrowed(scratch[9])
    A = borrowed(scratch[10])
    g = borrowed(scratch[11])
    dq = borrowed(scratch[12])
    L = borrowed(scratch[13])
    history = borrowed(scratch[14])
    multipliers = borrowed(scratch[15])
    dof = q.shape[0]
    wide = dof > WIDE_CHAIN_DOF
    m = 3 if task[10] == 2.0 else 6  # optik.task: a plain point uses three rows
    for i in range(dof):
        q[i] = min(max(q[i], lower[i]), upper[i])
    pos, rot = _evaluate(view, q, target, task, T, Jc, J, e, work, M)
    E = 0.0
    for r in range(m):
        E += e[r] * e[r]
    scale = 1.0
    # A balanced search (optik.task._LENGTH) measures a slide's travel in the arm's size.
    slide_damping = 1.0 / (task[12] * task[12]) if task[12] > 0.0 else 1.0
    it = 0
    while it < max_iter:
        if task_converged(pos, rot, task):
            return it, True, pos, rot
        if it >= window and E > STALL_FLOOR and ratio * history[(it - window) % 16] < E:
            break
        history[it % 16] = E
        it += 1
        lam = scale * (0.5 * E + w_bias * task[11])  # optik.task._BIAS: a search's factor
        if wide:
            if not _wide_step(view, J, e, m, q, lam, slide_damping, g, A, L, multipliers, dq):
                scale *= 10.0
                continue
        else:
            for a in range(dof):
                if lower[a] == upper[a]:
                    # A frozen joint (a zero-width box): its column is out of the step.
                    g[a] = 0.0
                    for b in range(a):
                        A[a, b] = 0.0
                        A[b, a] = 0.0
                    A[a, a] = 1.0
                    continue
                s = 0.0
                for r in range(m):
                    s += J[r, a] * e[r]
                g[a] = s
                for b in range(a):
                    s = 0.0
                    if lower[b] != upper[b]:
                        for r in range(m):
                            s += J[r, a] * J[r, b]
                    A[a, b] = s
                    A[b, a] = s
                s = lam
                if slide_damping != 1.0 and _slides(view, a):
                    s = lam * slide_damping
                for r in range(m):
                    s += J[r, a] * J[r, a]
                A[a, a] = s
            # Joints resting on a bound that the descent direction g pushes outward stay on
            # it (projected Newton's active set): their columns leave the step. Chosen by
            # the step instead, a joint that g moves inward could be held by the coupling
            # of a weakly damped step, and the compromise stalled short of its minimum.
            for i in range(dof):
                if (q[i] <= lower[i] and g[i] < 0.0) or (q[i] >= upper[i] and g[i] > 0.0):
                    _hold(A, g, i, dof)
            if not cholesky_solve(A, g, dq, L):
                scale *= 10.0
                continue
            # Joints on a bound whose step still points outward would be clamped back: hold
            # them too and re-solve for the others, so the step still helps.
            blocked = False
            for i in range(dof):
                if (q[i] <= lower[i] and dq[i] < 0.0) or (q[i] >= upper[i] and dq[i] > 0.0):
                    blocked = True
                    _hold(A, g, i, dof)
            if blocked and not cholesky_solve(A, g, dq, L):
                scale *= 10.0
                continue
        for i in range(dof):
            q_new[i] = min(max(q[i] + dq[i], lower[i]), upper[i])
        pos_n, rot_n = _evaluate(view, q_new, target, task, T_new, Jc, J_new, e_new, work, M)
        E_new = 0.0
        for r in range(m):
            E_new += e_new[r] * e_new[r]
        if E_new < E:
            q[:] = q_new
            T[:, :] = T_new
            J[:, :] = J_new
            e[:] = e_new
            E = E_new
            pos = pos_n
            rot = rot_n
            scale = max(scale * 0.5, MIN_DAMPING_SCALE)
        else:
            scale *= 4.0
            if scale > 1e12:
                break
    return it, task_converged(pos, rot, task), pos, rot


@jit
def _wide_step(
    view: KernelChain,
    J: np.ndarray,
    e: np.ndarray,
    m: int,
    q: np.ndarray,
    lam: float,
    slide_damping: float,
    d_inv: np.ndarray,
    S: np.ndarray,
    L: np.ndarray,
    y: np.ndarray,
    dq: np.ndarray,
) -> bool:
    """:func:`lm_attempt`'s step of a chain wider than :data:`WIDE_CHAIN_DOF`, into ``dq``.

    The same step as the joints' system ``(D + J^T J) dq = J^T e`` over the free joints
    (``D`` the damping, ``lam`` or a slide's ``lam * slide_damping``; held and frozen
    joints step 0), by the identity ``(D + J^T J)^-1 J^T = D^-1 J^T (I + J D^-1 J^T)^-1``:
    ``dq = D^-1 J^T y`` with ``(I + J D^-1 J^T) y = e``, a system of the task's ``m <= 6``
    rows. ``d_inv`` (dof,) receives ``D^-1`` (0 for a held joint); ``S`` (6, 6), ``L``
    (6, 7) and ``y`` (6,) are scratch. The same joints are held as by the joints' system:
    those on a bound that the gradient ``J^T e``, then the step, pushes outward. False if
    the damping is not positive (the step is then undefined, as the joints' system's).
    """
    lower, upper = view[4], view[5]
    dof = q.shape[0]
    if not lam > 0.0:
        return False
    for a in range(dof):
        d_inv[a] = 0.0
        if lower[a] == upper[a]:
            continue  # a frozen joint (a zero-width box)
        s = 0.0
        for r in range(m):
            s += J[r, a] * e[r]
        if (q[a] <= lower[a] and s < 0.0) or (q[a] >= upper[a] and s > 0.0):
            continue
        d = lam * slide_damping if slide_damping != 1.0 and _slides(view, a) else lam
        d_inv[a] = 1.0 / d
    if not _task_space_solve(J, e, m, d_inv, S, L, y, dq):
        return False
    blocked = False
    for a in range(dof):
        if d_inv[a] != 0.0 and (
            (q[a] <= lower[a] and dq[a] < 0.0) or (q[a] >= upper[a] and dq[a] > 0.0)
        ):
            d_inv[a] = 0.0
            blocked = True
    return not blocked or _task_space_solve(J, e, m, d_inv, S, L, y, dq)


@inline
def _task_space_solve(
    J: np.ndarray,
    e: np.ndarray,
    m: int,
    d_inv: np.ndarray,
    S: np.ndarray,
    L: np.ndarray,
    y: np.ndarray,
    dq: np.ndarray,
) -> bool:
    """``dq = D^-1 J^T y`` with ``(I + J D^-1 J^T) y = e`` (rows beyond ``m``: identity, 0)."""
    dof = d_inv.shape[0]
    for r in range(6):
        for c in range(r + 1):
            s = 1.0 if r == c else 0.0
            if r < m:
                for a in range(dof):
                    s += d_inv[a] * J[r, a] * J[c, a]
            S[r, c] = s
            S[c, r] = s
        y[r] = e[r] if r < m else 0.0
    if not cholesky_solve(S, y, y, L):
        return False
    for a in range(dof):
        s = 0.0
        for r in range(m):
            s += J[r, a] * y[r]
        dq[a] = d_inv[a] * s
    return True


@inline
def _hold(A: np.ndarray, g: np.ndarray, i: int, dof: int) -> None:
    """Take joint ``i`` out of the step ``A dq = g``: its row and column become ``e_i``."""
    for b in range(dof):
        A[i, b] = 0.0
        A[b, i] = 0.0
    A[i, i] = 1.0
    g[i] = 0.0


@jit
def lm_solve(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    q0: np.ndarray,
    max_iter: int,
    w_bias: float,
    window: int,
    ratio: float,
) -> tuple[np.ndarray, int, bool, float, float]:
    """Projected Levenberg–Marquardt from ``q0``: one attempt, stall rule ``(window, ratio)``.

    A search's rule is ``(STALL_WINDOW, STALL_RATIO)``; a compromise's (the weighted
    cost's minimum of a target that cannot be met, :mod:`optik.task`) is
    ``(COMPROMISE_WINDOW, COMPROMISE_RATIO)``, which waits for no progress at all. One
    kernel for both: a second would compile :func:`lm_attempt` into itself again.

    Returns:
        ``(q, iterations, converged, position_error, orientation_error)``; ``converged``
        means both errors are at most ``tol`` (m, rad) with ``q`` inside the limits.
    """
    q = q0.copy()
    scratch = workspace(chain[1].shape[0], q0.shape[0])
    it, ok, pos, rot = lm_attempt(chain, target, task, q, max_iter, w_bias, window, ratio, scratch)
    return q, it, ok, pos, rot


COMPROMISE_WINDOW = np.int64(16)
COMPROMISE_RATIO = 1.0 - 1e-12
"""The stall rule of a compromise (:func:`lm_solve`): stop when 16 iterations cut
``e^T e`` by less than a relative 1e-12 (its minimum reached to rounding), not by half."""

COMPROMISE_MAX_ITER = 1000
"""The iterations a compromise may run, whatever the caller's ``max_iter`` (a search's,
per attempt): it runs after the search, and a timeout's deadline cannot stop a compiled
loop (1,000 iterations take a few milliseconds)."""


@jit
def lm_solve_restarts(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    given: np.ndarray,
    table: KernelTable,
    max_iter: int,
    w_bias: float,
    first: int,
    last: int,
    seed: int,
) -> tuple[np.ndarray, int, int, bool, float, float]:
    """:func:`lm_attempt` from starts ``first`` to ``last`` (inclusive) until one converges.

    Start ``k`` is :func:`optik.solvers._starts.start_into`'s: the ``given`` starts (closed
    -form branches nearest ``q0``, or ``q0``), then the seed table's entries (``table``:
    :class:`optik.solvers._seeds.SeedTable`) nearest the target first and seeded uniform
    draws inside the limits in turn. Start
    ``k`` depends on ``k`` and ``seed`` only, so a caller may run the attempts in slices
    (for a deadline, or to stay interruptible) and get the same answer. The first
    :data:`QUICK_ATTEMPTS` attempts use the quick stall rule.

    Returns:
        ``(q, total_iterations, attempts_run, converged, position_error,
        orientation_error)`` of the first converged attempt, else of the best one (the
        smallest sum of both errors; the earliest among equals).
    """
    scratch = workspace(chain[1].shape[0], chain[4].shape[0])
    mask = task_features(task)
    starts = (given, table, first, last, seed)
    return _restarts(chain, target, task, mask, starts, max_iter, w_bias, scratch)


@jit
def _restarts(
    chain: KernelChain,
    target: np.ndarray,
    task: np.ndarray,
    mask: np.ndarray,
    starts: tuple[np.ndarray, KernelTable, int, int, int],
    max_iter: int,
    w_bias: float,
    scratch: tuple[np.ndarray, ...],
) -> tuple[np.ndarray, int, int, bool, float, float]:
    """:func:`lm_solve_restarts` in the caller's ``scratch`` (:func:`workspace`).

    ``mask`` is :func:`optik.task.task_features` of ``task``; ``starts`` is
    ``(given, table, first, last, seed)``.
    """
    given, table, first, last, seed = starts
    table_q, table_features, table_centroids, table_offsets = table
    lower, upper = chain[4], chain[5]
    dof = lower.shape[0]
    nearest = nearest_table(table_features, table_centroids, table_offsets, target, mask)
    q = np.empty(dof)
    best_q = np.empty(dof)
    best_q[:] = np.nan
    best_err = np.inf
    best_pos = np.inf
    best_rot = np.inf
    total = 0
    attempt = first
    while attempt <= last:
        start_into(attempt, given, nearest, table_q, lower, upper, seed, q)
        quick = attempt < QUICK_ATTEMPTS
        window = QUICK_WINDOW if quick else STALL_WINDOW
        ratio = QUICK_RATIO if quick else STALL_RATIO
        it, ok, pos, rot = lm_attempt(
            chain, target, task, q, max_iter, w_bias, window, ratio, scratch
        )
        total += it
        if ok or pos + rot < best_err or attempt == first:
            best_q[:] = q
            best_err, best_pos, best_rot = pos + rot, pos, rot
        if ok:
            return best_q, total, attempt - first + 1, True, best_pos, best_rot
        attempt += 1
    return best_q, total, last - first + 1, False, best_pos, best_rot


BATCH_CHUNK = 32
"""Targets per unit of a batch's work: one scratch workspace (15 arrays) serves them all."""


@inline  # its one caller's compile links _restarts anyway: a kernel of its own costs 3 s more
def _solve_chunk(c: int, chain: KernelChain, batch: BatchJob, out: BatchOutput) -> None:
    """Chunk ``c`` of a batch (:data:`BATCH_CHUNK` targets) in one scratch workspace.

    Target ``k`` is :func:`lm_solve_restarts` with the random stream ``seeds[k]``. Every
    attempt overwrites the scratch before it reads it, so sharing it changes no answer.
    """
    targets, task, given, table, settings, seeds = batch
    max_iter, w_bias, restarts = settings
    Q, iters, used, ok = out
    scratch = workspace(chain[1].shape[0], chain[4].shape[0])
    mask = task_features(task)
    for k in range(c * BATCH_CHUNK, min((c + 1) * BATCH_CHUNK, targets.shape[0])):
        own = given[k] if given.shape[0] == targets.shape[0] else given[0]
        starts = (own, table, np.int64(0), restarts, seeds[k])  # 0 as a value: one _restarts
        q, it, u, good, _, _ = _restarts(
            chain, targets[k], task, mask, starts, max_iter, w_bias, scratch
        )
        Q[k] = q
        iters[k] = it
        used[k] = u - 1
        ok[k] = good


@jit
def _batch_output(N: int, dof: int) -> BatchOutput:
    """``(q (N, dof), iterations (N,), restarts (N,), ok (N,))``, to be filled."""
    return (
        np.empty((N, dof)),
        np.empty(N, dtype=np.int64),
        np.empty(N, dtype=np.int64),
        np.empty(N, dtype=np.bool_),
    )


@jit
def lm_solve_batch_serial(chain: KernelChain, batch: BatchJob) -> BatchOutput:
    """:func:`lm_solve_restarts` for every target of ``batch``, on the calling thread.

    Target ``k`` uses the random stream ``seeds[k]``, so a batch split into pieces
    (:mod:`optik.solvers._batch_threads`) gets the same answers. Returns ``(q (N, dof),
    iterations (N,), restarts (N,), ok (N,))``.
    """
    targets, task, given, table, settings, seeds = batch
    N = targets.shape[0]
    out = _batch_output(N, chain[4].shape[0])
    # Borrowed views (optik._nrt): threads that solve pieces of one batch share the chain,
    # the table and the task, and counting references to a shared array from several
    # threads serialises them. The owners are this call's arguments and ``out``.
    table_q, features, centroids, offsets = table
    table_ = (borrowed(table_q), borrowed(features), borrowed(centroids), borrowed(offsets))
    batch_ = (borrowed(targets), borrowed(task), borrowed(given), table_, settings, borrowed(seeds))
    Q, iters, used, ok = out
    out_ = (borrowed(Q), borrowed(iters), borrowed(used), borrowed(ok))
    chain_ = _borrow_chain(chain)
    for c in range((N + BATCH_CHUNK - 1) // BATCH_CHUNK):
        _solve_chunk(c, chain_, batch_, out_)
    return out
