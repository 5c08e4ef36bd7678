"""The per-row steps of the closed forms' compiled pipeline (:mod:`optik.analytic._pipeline`).

Forward kinematics of a row on the robot's own chain, sharing the prefix products of rows
with the same leading joint values (:func:`fk_shared`); the FK check
(:func:`_pose_verified`); the 2 pi shift of a row into the limits nearest a reference
(:func:`_wrap_row`); the limit tests and the projection onto the bounds; the sort by
distance to the reference. Each works on one row of the pipeline's scratch, where the
robot's data sit in its parameter vector as a :data:`Layout` says.
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import atan2, mod_two_pi, sincos
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._compiled import COS_ROWS, SIN_ROWS, mul3tn

_TWO_PI = 2.0 * math.pi

Layout = tuple[int, int, int, int, int, int, int]
"""Where the post-processing finds a robot's data in its parameter vector: offsets of
joint ``j``'s prismatic flag (``kind + kind_stride * j``), the lower and upper limits,
the chain's top rows (``dof + 1`` blocks of 12), the tolerance block and the wrist
centre (the point where axes 4, 5 and 6 meet, in the tool's frame; NaN where they do
not, offset -1 where the vector has no such entry), in that order:
``(kind, kind_stride, lower, upper, chain, tolerances, wrist)``. The six-joint families
use :data:`SIX_JOINT_LAYOUT`; :mod:`optik.analytic.free_joint` has its own."""


@_jit
def fk_shared(
    params: np.ndarray, layout: Layout, block: np.ndarray, r: int, pre: np.ndarray, depth: int
) -> int:
    """Forward kinematics of ``block[r]`` into ``pre[n]``, reusing the previous call's prefix.

    The chain product of :func:`optik._kernels.fk_into`, ``K[0] M(q1) K[1] ... M(qn) K[n]``
    (``K`` the robot's ``_K``, stored in ``params`` where ``layout`` says), with its
    arithmetic expression for
    expression (``_apply_motion`` then ``_right_multiply``), kept in scalars. The sines
    and cosines come precomputed in ``block[8 + r]`` and ``block[16 + r]``: given libm's
    values the pose is ``fk_into``'s bit for bit (a test checks it).

    ``pre`` (n + 2, 12) holds the top three rows of each prefix product, row-major:
    ``pre[i]`` is the product up to joint ``i`` (``pre[0] = K[0]``, set by the caller);
    ``pre[n + 1, :n]`` the joint values of the previous call, whose first ``depth``
    prefixes are valid. Leading joints equal to those are not recomputed (branches share
    their shoulder and arm joints). Returns the new ``depth`` (n).
    """
    n = block.shape[1]
    last = n + 1
    j = 0
    while j < depth and block[r, j] == pre[last, j]:
        j += 1
    a00, a01, a02, a03 = pre[j, 0], pre[j, 1], pre[j, 2], pre[j, 3]
    a10, a11, a12, a13 = pre[j, 4], pre[j, 5], pre[j, 6], pre[j, 7]
    a20, a21, a22, a23 = pre[j, 8], pre[j, 9], pre[j, 10], pre[j, 11]
    for i in range(j, n):
        t = block[r, i]
        pre[last, i] = t
        # _apply_motion(T, prismatic[i], t)
        if params[layout[0] + layout[1] * i] != 0.0:
            a03 += t * a02
            a13 += t * a12
            a23 += t * a22
        else:
            s = block[SIN_ROWS + r, i]
            c = block[COS_ROWS + r, i]
            a00, a01 = c * a00 + s * a01, -s * a00 + c * a01
            a10, a11 = c * a10 + s * a11, -s * a10 + c * a11
            a20, a21 = c * a20 + s * a21, -s * a20 + c * a21
        # _right_multiply(T, K[i + 1], out)
        o = layout[4] + 12 * (i + 1)
        k00, k01, k02, k03 = params[o], params[o + 1], params[o + 2], params[o + 3]
        k10, k11, k12, k13 = params[o + 4], params[o + 5], params[o + 6], params[o + 7]
        k20, k21, k22, k23 = params[o + 8], params[o + 9], params[o + 10], params[o + 11]
        a00, a01, a02, a03 = (
            a00 * k00 + a01 * k10 + a02 * k20,
            a00 * k01 + a01 * k11 + a02 * k21,
            a00 * k02 + a01 * k12 + a02 * k22,
            a00 * k03 + a01 * k13 + a02 * k23 + a03,
        )
        a10, a11, a12, a13 = (
            a10 * k00 + a11 * k10 + a12 * k20,
            a10 * k01 + a11 * k11 + a12 * k21,
            a10 * k02 + a11 * k12 + a12 * k22,
            a10 * k03 + a11 * k13 + a12 * k23 + a13,
        )
        a20, a21, a22, a23 = (
            a20 * k00 + a21 * k10 + a22 * k20,
            a20 * k01 + a21 * k11 + a22 * k21,
            a20 * k02 + a21 * k12 + a22 * k22,
            a20 * k03 + a21 * k13 + a22 * k23 + a23,
        )
        k = i + 1
        pre[k, 0], pre[k, 1], pre[k, 2], pre[k, 3] = a00, a01, a02, a03
        pre[k, 4], pre[k, 5], pre[k, 6], pre[k, 7] = a10, a11, a12, a13
        pre[k, 8], pre[k, 9], pre[k, 10], pre[k, 11] = a20, a21, a22, a23
    return n


@_jit
def _wrap_row(
    params: np.ndarray, layout: Layout, rows: np.ndarray, r: int, ref: np.ndarray, kr: int
) -> None:
    """Revolute angles of ``rows[r]`` into the limits, the representative nearest ``ref[kr]``.

    The steps of :func:`optik.analytic.wrap_into_limits`, bit for bit: numpy's floor-mod,
    ``ceil`` / ``floor`` with 1e-12 slack, round half to even, clamps.
    """
    for j in range(rows.shape[1]):
        if params[layout[0] + layout[1] * j] != 0.0:
            continue
        lower = params[layout[2] + j]
        upper = params[layout[3] + j]
        base = ref[kr, j] + mod_two_pi(rows[r, j] - ref[kr, j] + math.pi) - math.pi
        if abs(ref[kr, j] - base) <= math.pi and lower <= base <= upper:
            # The usual case, without divisions: |ref - base| <= pi makes k_near below
            # exactly 0 (|x / 2 pi| <= 1/2 rounds half to even to 0), and a representative
            # inside the limits gives k_min <= 0 <= k_max, so k stays 0.
            rows[r, j] = base
            continue
        k = np.rint((ref[kr, j] - base) / _TWO_PI)
        k_min = np.ceil((lower - base) / _TWO_PI - 1e-12)
        k_max = np.floor((upper - base) / _TWO_PI + 1e-12)
        if math.isfinite(k_min):
            k = max(k, k_min)
        if math.isfinite(k_max):
            k = min(k, k_max)
        if k_min > k_max or not math.isfinite(k):
            k = 0.0
        rows[r, j] = base + _TWO_PI * k


@_inline
def _pose_verified(
    pre: np.ndarray, i: int, T: np.ndarray, k: int, verify_tol: float, position_tol: float
) -> bool:
    """Whether the pose in ``pre[i]`` (top rows, row-major) reaches ``T[k]``.

    Position error within ``position_tol`` (m, the robot's
    :func:`optik.analytic._base.verify_position_tolerance`) and the robust rotation angle
    of ``R_fk^T R_target`` (rad, the ``atan2`` of :func:`optik.spatial.rotation_angle`)
    within ``verify_tol``.
    """
    dx = pre[i, 3] - T[k, 0, 3]
    dy = pre[i, 7] - T[k, 1, 3]
    dz = pre[i, 11] - T[k, 2, 3]
    if not math.sqrt(dx * dx + dy * dy + dz * dz) <= position_tol:
        return False
    # R_rel = R_fk^T R_target; angle = atan2(|vee(R_rel - R_rel^T)| / 2, (tr - 1) / 2).
    rr = mul3tn(
        (pre[i, 0], pre[i, 1], pre[i, 2], pre[i, 4], pre[i, 5], pre[i, 6],
         pre[i, 8], pre[i, 9], pre[i, 10]),
        (T[k, 0, 0], T[k, 0, 1], T[k, 0, 2], T[k, 1, 0], T[k, 1, 1], T[k, 1, 2],
         T[k, 2, 0], T[k, 2, 1], T[k, 2, 2]),
    )  # fmt: skip
    sx = rr[7] - rr[5]
    sy = rr[2] - rr[6]
    sz = rr[3] - rr[1]
    s = 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)
    c = 0.5 * (rr[0] + rr[4] + rr[8] - 1.0)
    # atan2(s, c) <= s / c for s >= 0 < c: a tiny ratio accepts without the atan2.
    return s <= 0.5 * verify_tol * c or atan2(s, c) <= verify_tol


@_inline
def _sort_by_distance(
    Q: np.ndarray, k: int, m: int, ref: np.ndarray, kr: int, scratch: np.ndarray, at: int
) -> None:
    """Stable insertion sort of ``Q[k, :m]`` by ``||q - ref[kr]||``.

    The keys go in ``scratch[at:at + m]``. Python's ``list.sort`` is stable too, so ties
    keep the family's order.
    """
    dof = Q.shape[2]
    for r in range(m):
        acc = 0.0
        for j in range(dof):
            acc += (Q[k, r, j] - ref[kr, j]) ** 2
        scratch[at + r] = math.sqrt(acc)
    for r in range(1, m):
        key = scratch[at + r]
        p = r - 1
        while p >= 0 and scratch[at + p] > key:
            p -= 1
        if p + 1 < r:
            # Rotate rows p+1..r right by one (row r moves to p + 1).
            for j in range(dof):
                moved = Q[k, r, j]
                for i in range(r, p + 1, -1):
                    Q[k, i, j] = Q[k, i - 1, j]
                Q[k, p + 1, j] = moved
            for i in range(r, p + 1, -1):
                scratch[at + i] = scratch[at + i - 1]
            scratch[at + p + 1] = key


@_jit
def _row_sines(rows: np.ndarray, r: int, dof: int) -> None:
    """Sines and cosines of ``rows[r]`` into its rows of the scratch block."""
    for j in range(dof):
        rows[SIN_ROWS + r, j], rows[COS_ROWS + r, j] = sincos(rows[r, j])


@_inline
def _inside(
    params: np.ndarray, layout: Layout, dof: int, rows: np.ndarray, r: int, tol: float
) -> bool:
    """Whether ``rows[r]`` lies inside the limits, each widened by ``tol``."""
    for j in range(dof):
        v = rows[r, j]
        # The differences, as optik.limits.limit_violation forms them: the same verdict
        # to the last bit as the verification of every answer.
        if not (params[layout[2] + j] - v <= tol and v - params[layout[3] + j] <= tol):
            return False
    return True


@_inline
def _onto_bounds(
    params: np.ndarray, layout: Layout, dof: int, held: int, rows: np.ndarray, r: int
) -> None:
    """``rows[r]`` clipped onto its limits (the held joint keeps its value)."""
    for j in range(dof):
        if j != held:
            rows[r, j] = min(max(rows[r, j], params[layout[2] + j]), params[layout[3] + j])


@_inline
def _onto_bounds_fk(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    held: int,
    rows: np.ndarray,
    r: int,
    pre: np.ndarray,
) -> int:
    """:func:`_onto_bounds`, then the row's sines and its FK anew into ``pre``: the depth."""
    _onto_bounds(params, layout, dof, held, rows, r)
    _row_sines(rows, r, dof)
    return fk_shared(params, layout, rows, r, pre, np.int64(0))


@_inline
def _runtime(layout: Layout) -> Layout:
    """``layout`` with run-time entries: a constant tuple is typed by its values."""
    return (
        np.int64(layout[0]), np.int64(layout[1]), np.int64(layout[2]), np.int64(layout[3]),
        np.int64(layout[4]), np.int64(layout[5]), np.int64(layout[6]),
    )  # fmt: skip
