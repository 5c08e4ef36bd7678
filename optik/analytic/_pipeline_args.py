"""Arguments and scratch of the compiled closed-form pipelines (:mod:`._pipeline`).

The flags of a call (:data:`SORT`, :data:`WITHIN_LIMITS`), the check of a single call's
inputs, and the scratch arrays made once per call or batch. Inlined into each pipeline.
"""

from __future__ import annotations

import numpy as np

from optik._checks import MAX_LENGTH_M
from optik._math import pose_defect
from optik._numba import inline as _inline
from optik.analytic._compiled import MAX_BRANCHES, TOL_BOTTOM_ROW, TOL_ROTATION
from optik.analytic._newton import newton_work_size


@_inline
def input_code(params: np.ndarray, tols: int, T1: np.ndarray, ref: np.ndarray) -> int:
    """The inputs of a single call checked: 0 valid, -1 or -2 as a pipeline's ``solve``.

    -1 when ``T1[0]`` is not a valid pose (:func:`optik._math.pose_defect`, with the
    tolerances of the block at offset ``tols`` of ``params``), -2 when an entry of ``ref``
    (dof,) is not finite or beyond :data:`~optik._checks.MAX_LENGTH_M` (as
    :meth:`optik.Robot.check_q` refuses it). The caller raises the matching optik error.
    """
    k = np.int64(0)  # not the literal 0: first_bad_pose's signature serves this call too
    if pose_defect(T1, k, params[tols + TOL_ROTATION], params[tols + TOL_BOTTOM_ROW]) != 0:
        return -1
    for j in range(ref.shape[0]):
        if not abs(ref[j]) <= MAX_LENGTH_M:  # NaN fails too
            return -2
    return 0


@_inline
def scratch_size(dof: int) -> int:
    """Length of the flat scratch :func:`scratch_blocks` carves for ``dof`` joints."""
    return (dof + 2) * 12 + 3 * MAX_BRANCHES * dof + newton_work_size(dof)


@_inline
def scratch_blocks(
    scratch: np.ndarray, dof: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scratch of ``postprocess_rows`` for ``dof`` joints carved from one flat array.

    ``(pre, flat, rows, work)``: ``pre`` (dof + 2, 12) for the FK, ``rows`` (24, dof) for
    the raw branches and their sines and cosines, ``flat`` the same memory seen flat,
    ``work`` the Newton step's (:func:`optik.analytic._newton.newton_work_size`).
    ``scratch`` holds at least :func:`scratch_size` values; one array costs one
    allocation instead of three.
    """
    pre_end = (dof + 2) * 12
    flat_end = pre_end + 3 * MAX_BRANCHES * dof
    flat = scratch[pre_end:flat_end]
    return (
        scratch[:pre_end].reshape((dof + 2, 12)),
        flat,
        flat.reshape((3 * MAX_BRANCHES, dof)),
        scratch[flat_end:],
    )


@_inline
def work_rows(dof: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`scratch_blocks` of a new array, made once per call or batch."""
    return scratch_blocks(np.empty(scratch_size(dof)), dof)


@_inline
def batch_work(
    n: int, dof: int, flags: int
) -> tuple[bool, bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Flags and scratch of a batch of ``n`` targets for ``dof`` joints, made once.

    ``(sort, within, pre, flat, rows, work, Q, counts)``: the :data:`SORT` and
    :data:`WITHIN_LIMITS` bits of ``flags``, :func:`work_rows`' scratch, then the outputs
    ``Q`` (n, 8, dof) and ``counts`` (n,) of a ``solve_batch``.
    """
    pre, flat, rows, work = work_rows(dof)
    Q = np.empty((n, MAX_BRANCHES, dof))
    counts = np.zeros(n, dtype=np.int64)
    sort, within = flag_bits(flags)
    return sort, within, pre, flat, rows, work, Q, counts


@_inline
def pad_rows(Q: np.ndarray, k: int, m: int) -> None:
    """Fill the rows of ``Q[k]`` past its ``m`` branches with NaN."""
    for r in range(m, Q.shape[1]):
        for j in range(Q.shape[2]):
            Q[k, r, j] = np.nan


SORT = 1
"""Flag of a pipeline's ``solve`` / ``solve_batch``: sort the branches by distance to ``ref``."""
WITHIN_LIMITS = 2
"""Flag of a pipeline's ``solve`` / ``solve_batch``: drop branches outside the limits."""


@_inline
def flag_bits(flags: int) -> tuple[bool, bool]:
    """``(sort, within)``: the :data:`SORT` and :data:`WITHIN_LIMITS` bits of ``flags``."""
    return (flags & SORT) != 0, (flags & WITHIN_LIMITS) != 0


__all__ = [
    "SORT",
    "WITHIN_LIMITS",
    "batch_work",
    "flag_bits",
    "input_code",
    "pad_rows",
    "scratch_blocks",
    "scratch_size",
    "work_rows",
]
