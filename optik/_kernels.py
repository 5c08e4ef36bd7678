"""Compiled kinematics kernels: the one implementation of FK and the Jacobian.

A chain is stored as constant transforms ``K`` of shape ``(n + 1, 4, 4)`` and joint
types: ``T = K[0] M(t_1) K[1] M(t_2) ... M(t_n) K[n]``, where ``M(t)`` is a rotation
about z by ``t`` (revolute) or a translation along z by ``t`` (prismatic). Every robot
constructor (DH, modified DH, URDF) produces this form, so every solver, batched or
not, calls these same kernels and cannot drift from ``Robot.fk``.

Numba compiles them on first use (cached on disk); ``benchmarks/bench_kinematics.py``
compares them with a pure-numpy implementation of the same product.
"""

from __future__ import annotations

import numpy as np

from optik._numba import inline, jit
from optik.chain import KernelChain
from optik.task import task_error

Rows12 = tuple[float, float, float, float, float, float, float, float, float, float, float, float]
"""The top three rows of a 4x4 transform, row-major, held in scalars."""


@inline
def _top_rows(K: np.ndarray, j: int) -> Rows12:
    """The top three rows of ``K[j]`` (indexed in place, see :func:`_chain_step`)."""
    return (
        K[j, 0, 0], K[j, 0, 1], K[j, 0, 2], K[j, 0, 3],
        K[j, 1, 0], K[j, 1, 1], K[j, 1, 2], K[j, 1, 3],
        K[j, 2, 0], K[j, 2, 1], K[j, 2, 2], K[j, 2, 3],
    )  # fmt: skip


@inline
def _chain_step(a: Rows12, prismatic: bool, t: float, K: np.ndarray, j: int) -> Rows12:
    """One link of the chain on the top 3x4 rows held in scalars: ``T @ M(t) @ K[j]``.

    Scalars instead of a 4x4 array: this is every solver's inner loop, and it runs about
    twice as fast without the array traffic. ``K`` is indexed in place, not sliced: a
    slice is a new array view, whose reference counting (atomic) costs more than the
    arithmetic here.
    """
    a00, a01, a02, a03, a10, a11, a12, a13, a20, a21, a22, a23 = a
    if prismatic:
        a03 += t * a02
        a13 += t * a12
        a23 += t * a22
    else:
        c = np.cos(t)
        s = np.sin(t)
        a00, a01 = c * a00 + s * a01, c * a01 - s * a00
        a10, a11 = c * a10 + s * a11, c * a11 - s * a10
        a20, a21 = c * a20 + s * a21, c * a21 - s * a20
    return (
        a00 * K[j, 0, 0] + a01 * K[j, 1, 0] + a02 * K[j, 2, 0],
        a00 * K[j, 0, 1] + a01 * K[j, 1, 1] + a02 * K[j, 2, 1],
        a00 * K[j, 0, 2] + a01 * K[j, 1, 2] + a02 * K[j, 2, 2],
        a00 * K[j, 0, 3] + a01 * K[j, 1, 3] + a02 * K[j, 2, 3] + a03,
        a10 * K[j, 0, 0] + a11 * K[j, 1, 0] + a12 * K[j, 2, 0],
        a10 * K[j, 0, 1] + a11 * K[j, 1, 1] + a12 * K[j, 2, 1],
        a10 * K[j, 0, 2] + a11 * K[j, 1, 2] + a12 * K[j, 2, 2],
        a10 * K[j, 0, 3] + a11 * K[j, 1, 3] + a12 * K[j, 2, 3] + a13,
        a20 * K[j, 0, 0] + a21 * K[j, 1, 0] + a22 * K[j, 2, 0],
        a20 * K[j, 0, 1] + a21 * K[j, 1, 1] + a22 * K[j, 2, 1],
        a20 * K[j, 0, 2] + a21 * K[j, 1, 2] + a22 * K[j, 2, 2],
        a20 * K[j, 0, 3] + a21 * K[j, 1, 3] + a22 * K[j, 2, 3] + a23,
    )


@inline
def _store(a: Rows12, out: np.ndarray) -> None:
    """Write the top 3x4 rows held in scalars, and the row ``0 0 0 1``, into ``out`` (4, 4)."""
    for r in range(3):
        for c in range(4):
            out[r, c] = a[4 * r + c]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@inline
def drives_slide(prismatic: np.ndarray, coupling: np.ndarray, identity: bool, a: int) -> bool:
    """Whether joint ``a`` drives a prismatic joint of the chain.

    Args:
        prismatic: (nc,) the chain joints' prismatic flags.
        coupling: (nc, dof) the chain's coupling ``theta = C q``.
        identity: whether ``coupling`` is the identity (joint ``a`` is chain joint ``a``).
        a: the joint's index.
    """
    if identity:
        return bool(prismatic[a])
    for c in range(prismatic.shape[0]):  # noqa: SIM110 (a loop: numba has no any() of this)
        if prismatic[c] and coupling[c, a] != 0.0:
            return True
    return False


@jit
def fk_into(K: np.ndarray, prismatic: np.ndarray, theta: np.ndarray, out: np.ndarray) -> None:
    """Forward kinematics of one chain configuration ``theta`` (n,) into ``out`` (4, 4).

    The running transform lives in scalars (see :func:`fk_jacobian_work`).
    """
    n = prismatic.shape[0]
    a = _top_rows(K, 0)
    for i in range(n):
        a = _chain_step(a, prismatic[i], theta[i], K, i + 1)
    _store(a, out)


@jit
def fk_batch(K: np.ndarray, prismatic: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Forward kinematics of a batch ``theta`` (N, n) -> (N, 4, 4)."""
    N = theta.shape[0]
    out = np.empty((N, 4, 4))
    for k in range(N):
        fk_into(K, prismatic, theta[k], out[k])
    return out


@jit
def fk_jacobian_work(
    K: np.ndarray,
    prismatic: np.ndarray,
    theta: np.ndarray,
    T_out: np.ndarray,
    J_out: np.ndarray,
    work: np.ndarray,
) -> None:
    """Tool pose (4, 4) and geometric Jacobian (6, n) of the chain, base frame.

    Column ``i`` of the Jacobian uses the joint's axis ``z_i`` and origin ``o_i`` before
    its motion (the motion is about that same axis, so before or after is equal):
    revolute ``[z_i x (p - o_i); z_i]``, prismatic ``[z_i; 0]``. ``work`` is scratch
    space of shape ``(n, 3)`` for the joint origins, so solvers can call this without
    allocating. The running transform lives in scalars: this is every solver's inner loop.
    """
    n = prismatic.shape[0]
    a = _top_rows(K, 0)
    for i in range(n):
        J_out[3, i] = a[2]
        J_out[4, i] = a[6]
        J_out[5, i] = a[10]
        work[i, 0] = a[3]
        work[i, 1] = a[7]
        work[i, 2] = a[11]
        a = _chain_step(a, prismatic[i], theta[i], K, i + 1)
    _store(a, T_out)
    px, py, pz = a[3], a[7], a[11]
    for i in range(n):
        zx = J_out[3, i]
        zy = J_out[4, i]
        zz = J_out[5, i]
        if prismatic[i]:
            J_out[0, i] = zx
            J_out[1, i] = zy
            J_out[2, i] = zz
            J_out[3, i] = 0.0
            J_out[4, i] = 0.0
            J_out[5, i] = 0.0
        else:
            dx = px - work[i, 0]
            dy = py - work[i, 1]
            dz = pz - work[i, 2]
            J_out[0, i] = zy * dz - zz * dy
            J_out[1, i] = zz * dx - zx * dz
            J_out[2, i] = zx * dy - zy * dx


@jit
def fk_jacobian_into(
    K: np.ndarray,
    prismatic: np.ndarray,
    theta: np.ndarray,
    T_out: np.ndarray,
    J_out: np.ndarray,
) -> None:
    """Tool pose (4, 4) and geometric Jacobian (6, n) into the given arrays."""
    work = np.empty((prismatic.shape[0], 3))
    fk_jacobian_work(K, prismatic, theta, T_out, J_out, work)


@jit
def fk_jacobian_batch(
    K: np.ndarray, prismatic: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Batched :func:`fk_jacobian_into`: ``theta`` (N, n) -> ((N, 4, 4), (N, 6, n))."""
    N = theta.shape[0]
    n = prismatic.shape[0]
    T_out = np.empty((N, 4, 4))
    J_out = np.empty((N, 6, n))
    work = np.empty((n, 3))
    for k in range(N):
        fk_jacobian_work(K, prismatic, theta[k], T_out[k], J_out[k], work)
    return T_out, J_out


@jit
def joint_frames(
    K: np.ndarray, prismatic: np.ndarray, E: np.ndarray, T_base: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """Frames 0..n and the tool, base-relative: (n + 2, 4, 4).

    Frame 0 is ``T_base``; link frame ``i`` is the frame after motion ``i`` times its
    link offset ``E[i - 1]``; the last entry is the tool. The same chain step as
    :func:`fk_into`, taken twice per joint: once onto ``E`` (the link frame), once onto
    ``K`` (the running transform).
    """
    n = prismatic.shape[0]
    out = np.empty((n + 2, 4, 4))
    out[0] = T_base
    a = _top_rows(K, 0)
    for i in range(n):
        _store(_chain_step(a, prismatic[i], theta[i], E, i), out[i + 1])
        a = _chain_step(a, prismatic[i], theta[i], K, i + 1)
    _store(a, out[n + 1])
    return out


@jit
def pose_errors_into(
    chain: KernelChain, Q: np.ndarray, targets: np.ndarray, task: np.ndarray, out: np.ndarray
) -> None:
    """Verify configurations ``Q`` (N, dof) against ``targets`` (N or 1, 4, 4) from FK.

    ``chain`` is :meth:`optik.chain.Chain.kernel_args`: the limits checked are its own.

    Row ``k`` of ``out`` (N, 3) gets the task's judged position error (m) and
    orientation error (rad) (:func:`optik.task.task_error`: for a full pose
    ``||p(q) - p*||`` and the robust ``atan2`` angle of ``R*^T R(q)``) and the largest
    excursion beyond a limit (rad or m, 0 inside). A row with a non-finite entry gets
    ``inf`` for all three.
    """
    K, prismatic, C, identity, lower, upper = chain
    N = Q.shape[0]
    T = np.empty((4, 4))
    e = np.empty(6)
    M = np.empty((3, 4))
    single = targets.shape[0] == 1
    for k in range(N):
        q = Q[k]
        finite = True
        for i in range(q.shape[0]):
            if not np.isfinite(q[i]):
                finite = False
        if not finite:
            out[k, 0] = np.inf
            out[k, 1] = np.inf
            out[k, 2] = np.inf
            continue
        if identity:
            fk_into(K, prismatic, q, T)
        else:
            fk_into(K, prismatic, C @ q, T)
        position, orientation = task_error(T, targets[0] if single else targets[k], task, e, M)
        out[k, 0] = position
        out[k, 1] = orientation
        worst = 0.0
        for i in range(q.shape[0]):
            worst = max(worst, lower[i] - q[i], q[i] - upper[i])
        out[k, 2] = worst
