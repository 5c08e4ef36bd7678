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

import numba as nb
import numpy as np

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _apply_motion(T: np.ndarray, prismatic: bool, t: float) -> None:
    """``T <- T @ M(t)`` in place (only the columns that change)."""
    if prismatic:
        for r in range(3):
            T[r, 3] += t * T[r, 2]
    else:
        c = np.cos(t)
        s = np.sin(t)
        for r in range(3):
            x = T[r, 0]
            y = T[r, 1]
            T[r, 0] = c * x + s * y
            T[r, 1] = -s * x + c * y


@_jit
def _right_multiply(T: np.ndarray, K: np.ndarray, out: np.ndarray) -> None:
    """``out <- T @ K`` for rigid transforms (bottom rows ``0 0 0 1``)."""
    for r in range(3):
        t0 = T[r, 0]
        t1 = T[r, 1]
        t2 = T[r, 2]
        for c in range(4):
            out[r, c] = t0 * K[0, c] + t1 * K[1, c] + t2 * K[2, c]
        out[r, 3] += T[r, 3]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@_jit
def fk_into(K: np.ndarray, prismatic: np.ndarray, theta: np.ndarray, out: np.ndarray) -> None:
    """Forward kinematics of one chain configuration ``theta`` (n,) into ``out`` (4, 4)."""
    n = prismatic.shape[0]
    T = K[0].copy()
    for i in range(n):
        _apply_motion(T, prismatic[i], theta[i])
        _right_multiply(T, K[i + 1], out)
        T[:, :] = out


@_jit
def fk_batch(K: np.ndarray, prismatic: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Forward kinematics of a batch ``theta`` (N, n) -> (N, 4, 4)."""
    N = theta.shape[0]
    out = np.empty((N, 4, 4))
    for k in range(N):
        fk_into(K, prismatic, theta[k], out[k])
    return out


@_jit
def fk_jacobian_into(
    K: np.ndarray,
    prismatic: np.ndarray,
    theta: np.ndarray,
    T_out: np.ndarray,
    J_out: np.ndarray,
) -> None:
    """Tool pose (4, 4) and geometric Jacobian (6, n) of the chain, base frame.

    Column ``i`` of the Jacobian uses the joint's axis ``z_i`` and origin ``o_i`` before
    its motion (the motion is about that same axis, so before or after is equal):
    revolute ``[z_i x (p - o_i); z_i]``, prismatic ``[z_i; 0]``.
    """
    n = prismatic.shape[0]
    axes = np.empty((n, 3))
    origins = np.empty((n, 3))
    T = K[0].copy()
    for i in range(n):
        for r in range(3):
            axes[i, r] = T[r, 2]
            origins[i, r] = T[r, 3]
        _apply_motion(T, prismatic[i], theta[i])
        _right_multiply(T, K[i + 1], T_out)
        T[:, :] = T_out
    px = T_out[0, 3]
    py = T_out[1, 3]
    pz = T_out[2, 3]
    for i in range(n):
        zx = axes[i, 0]
        zy = axes[i, 1]
        zz = axes[i, 2]
        if prismatic[i]:
            J_out[0, i] = zx
            J_out[1, i] = zy
            J_out[2, i] = zz
            J_out[3, i] = 0.0
            J_out[4, i] = 0.0
            J_out[5, i] = 0.0
        else:
            dx = px - origins[i, 0]
            dy = py - origins[i, 1]
            dz = pz - origins[i, 2]
            J_out[0, i] = zy * dz - zz * dy
            J_out[1, i] = zz * dx - zx * dz
            J_out[2, i] = zx * dy - zy * dx
            J_out[3, i] = zx
            J_out[4, i] = zy
            J_out[5, i] = zz


@_jit
def fk_jacobian_batch(
    K: np.ndarray, prismatic: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Batched :func:`fk_jacobian_into`: ``theta`` (N, n) -> ((N, 4, 4), (N, 6, n))."""
    N = theta.shape[0]
    n = prismatic.shape[0]
    T_out = np.empty((N, 4, 4))
    J_out = np.empty((N, 6, n))
    for k in range(N):
        fk_jacobian_into(K, prismatic, theta[k], T_out[k], J_out[k])
    return T_out, J_out


@_jit
def joint_frames(
    K: np.ndarray, prismatic: np.ndarray, E: np.ndarray, T_base: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """Frames 0..n and the tool, base-relative: (n + 2, 4, 4).

    Frame 0 is ``T_base``; link frame ``i`` is the frame after motion ``i`` times its
    link offset ``E[i - 1]``; the last entry is the tool.
    """
    n = prismatic.shape[0]
    out = np.empty((n + 2, 4, 4))
    T = K[0].copy()
    out[0] = T_base
    tmp = np.empty((4, 4))
    for i in range(n):
        _apply_motion(T, prismatic[i], theta[i])
        _right_multiply(T, E[i], out[i + 1])
        _right_multiply(T, K[i + 1], tmp)
        T[:, :] = tmp
    out[n + 1] = T
    return out
