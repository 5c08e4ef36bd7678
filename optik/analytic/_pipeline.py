"""The compiled IK pipeline of the six-joint families: closed form, then every check.

For a family with a compiled closed form (:class:`optik.analytic._compiled.CompiledFamily`:
``spherical_wrist``, ``ur``), one call runs the post-processing that
:func:`optik.analytic.analytic_ik` applies to every family:

1. raw candidate branches from the closed form (up to :data:`MAX_BRANCHES`);
2. drop non-finite rows; shift revolute angles by multiples of 2 pi into the limits,
   nearest ``q_ref`` (the rule of :func:`optik.analytic.wrap_into_limits`);
3. drop out-of-limit rows (tolerance :data:`optik.limits.LIMIT_TOLERANCE`), unless asked;
   a closed form of the ideal arm (a table that is not exact, ``spherical_axes``, a held
   joint) gives each row one Newton step inside step 4 first (:mod:`optik.analytic._newton`),
   and the limits are applied to the row as moved;
4. verify each row by forward kinematics: the robot's own chain ``_K`` (the kinematics of
   ``Robot.fk``, not the DH rows) multiplied out with the arithmetic of
   :func:`optik._kernels.fk_into`, expression for expression
   (:func:`optik.analytic._rows.fk_shared`, with the other per-row steps in
   :mod:`optik.analytic._rows`; rows that share leading joint values share that part of
   the product); position error (m)
   and orientation error (rad, the robust ``atan2`` angle of
   :func:`optik.spatial.rotation_angle`) both within
   :data:`optik.analytic._base.VERIFY_TOLERANCE`; a row that misses by a little (a
   tangent rule rounded at a singular pose) takes a few Newton steps and is checked
   again, and a row put on a limit is stepped back onto its pose with that joint held
   (:mod:`optik.analytic._row_steps`);
5. drop duplicates (max-abs difference below ``DUPLICATE_TOLERANCE``);
6. with a caller's ``q_ref``, a stable sort by the Euclidean distance to it.

Every step gives what the numpy steps of :func:`optik.analytic.analytic_ik` give on the
same raw branches (a test checks it row for row; after a Newton step, against the same
step in numpy, which agrees to rounding times the Jacobian's condition). One deliberate
difference: sines and cosines come from inline fdlibm kernels (:func:`optik._math.sincos`,
at most 1 ulp and 2e-16 from libm's) rather than libm calls, which cost more than the rest
of the FK check; the FK check then agrees with ``Robot.fk`` to a few 1e-16, far below the
1e-9 it enforces.

The robot comes as its parameter vector (:func:`optik.analytic._compiled.pack_params`).
Hot paths index arrays rather than slicing or reshaping them per pose (a reshape is a C
call, a view a reference count): scratch arrays are made once per call or batch.
Every kernel is serial (``nogil``): callers may run them from several threads.
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import _SINCOS_RANGE, _sincos_core, sincos
from optik._nrt import borrowed
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._base import LIMIT_CLIP, LIMIT_STEP
from optik.analytic._compiled import (
    AT_BASE_INV,
    AT_CHAIN,
    AT_DH,
    AT_FAMILY,
    AT_FLIPPED,
    AT_LOWER,
    AT_REFINE,
    AT_SENSES,
    AT_TOLS,
    AT_TOOL_INV,
    AT_UPPER,
    AT_WRIST,
    COL_PRISMATIC,
    COS_ROWS,
    DOF,
    NCOL,
    SIN_ROWS,
    SPHERICAL_WRIST,
    TOL_DUPLICATE,
    TOL_LIMIT,
    TOL_VERIFY,
    TOL_VERIFY_POSITION,
    UR,
)
from optik.analytic._newton import (
    REFINE_MAX_STEP,
    REFINE_ROUNDING,
    pose_residual,
)
from optik.analytic._pipeline_args import (
    batch_work,
    flag_bits,
    input_code,
    pad_rows,
    scratch_blocks,
    scratch_size,
)
from optik.analytic._row_steps import (
    DROPPED,
    KEPT,
    PUT_FROM_BEYOND,
    PUT_ON_LIMIT,
    RowQuery,
    _near_miss_or_held,
    _refine_row,
)
from optik.analytic._rows import (
    Layout,
    _inside,
    _onto_bounds,
    _onto_bounds_fk,
    _pose_verified,
    _runtime,
    _sort_by_distance,
    _wrap_row,
    fk_shared,
)
from optik.analytic.spherical_wrist import spherical_wrist_candidates
from optik.analytic.ur import ur_candidates

SIX_JOINT_LAYOUT: Layout = (
    AT_DH + COL_PRISMATIC, NCOL, AT_LOWER, AT_UPPER, AT_CHAIN, AT_TOLS, AT_WRIST
)  # fmt: skip
"""The :data:`optik.analytic._rows.Layout` of :func:`optik.analytic._compiled.pack_params`."""


@_jit
def candidates(
    family: int,
    dh: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    kr: int,
    tols: np.ndarray,
    cand: np.ndarray,
) -> int:
    """Raw branches of compiled family ``family`` (:data:`SPHERICAL_WRIST`, :data:`UR`)."""
    if family == SPHERICAL_WRIST:
        return spherical_wrist_candidates(dh, T, ref, kr, tols, cand)
    if family == UR:
        return ur_candidates(dh, T, ref, kr, tols, cand)
    return 0


@_jit
def robot_candidates(
    params: np.ndarray,
    dh: np.ndarray,
    T0: np.ndarray,
    ref: np.ndarray,
    kr: int,
    rows: np.ndarray,
) -> int:
    """Raw branches of the robot's family, in the robot's joint variables, into ``rows``.

    :func:`candidates` on the table (``dh``, the (6, 8) block of ``params``; flange
    target ``T0`` in its frame 0) into ``rows``, the pipeline's (24, 6) scratch of rows,
    sines and cosines. A table variable that is ``-q`` (``params[AT_FLIPPED]``) has its
    reference (held in the last row) and branches turned. A table that is not exact
    (``params[AT_REFINE]``) gives the branches of the ideal arm: the post-processing
    refines them (:func:`postprocess_rows`).
    """
    family = int(params[AT_FAMILY])
    tols = params[AT_TOLS:]
    if params[AT_FLIPPED] != 0.0:
        # The turned reference in the last row of the scratch: the candidates fill only
        # rows[:8], and the sines and cosines come after them (no allocation per target).
        turned = rows[rows.shape[0] - 1 :]
        for j in range(DOF):
            turned[0, j] = params[AT_SENSES + j] * ref[kr, j]
        n = candidates(family, dh, T0, turned, np.int64(0), tols, rows)
        for r in range(n):
            for j in range(DOF):
                rows[r, j] *= params[AT_SENSES + j]
        return n
    return candidates(family, dh, T0, ref, kr, tols, rows)


@_inline
def sincos_block(flat: np.ndarray, n: int, dof: int) -> None:
    """Sines and cosines of the first ``n`` values of the pipeline's scratch block.

    ``flat`` is the (24, dof) block (rows, their sines, their cosines) seen flat: value
    ``i`` gets its sine at ``8 dof + i`` and its cosine at ``16 dof + i``. One
    branch-free loop over contiguous memory when every value is in range; inlined into a
    caller that passes ``dof`` as a constant, the offsets are compile-time constants, so
    LLVM sees that the writes never overlap the reads and vectorises it.
    """
    s0 = SIN_ROWS * dof
    c0 = COS_ROWS * dof
    inside = True
    for i in range(n):
        if not abs(flat[i]) < _SINCOS_RANGE:
            inside = False
    if inside:
        for i in range(n):
            flat[s0 + i], flat[c0 + i] = _sincos_core(flat[i])
    else:
        for i in range(n):
            flat[s0 + i], flat[c0 + i] = sincos(flat[i])


@_jit
def _transform_target(params: np.ndarray, T: np.ndarray, k: int, out: np.ndarray) -> None:
    """``out <- T_base_world @ T[k] @ T_tool_flange``: the flange target in frame 0."""
    B = AT_BASE_INV
    E = AT_TOOL_INV
    for i in range(4):
        b0 = params[B + 4 * i]
        b1 = params[B + 4 * i + 1]
        b2 = params[B + 4 * i + 2]
        b3 = params[B + 4 * i + 3]
        bt0 = b0 * T[k, 0, 0] + b1 * T[k, 1, 0] + b2 * T[k, 2, 0] + b3 * T[k, 3, 0]
        bt1 = b0 * T[k, 0, 1] + b1 * T[k, 1, 1] + b2 * T[k, 2, 1] + b3 * T[k, 3, 1]
        bt2 = b0 * T[k, 0, 2] + b1 * T[k, 1, 2] + b2 * T[k, 2, 2] + b3 * T[k, 3, 2]
        bt3 = b0 * T[k, 0, 3] + b1 * T[k, 1, 3] + b2 * T[k, 2, 3] + b3 * T[k, 3, 3]
        for j in range(4):
            out[i, j] = (
                bt0 * params[E + j]
                + bt1 * params[E + 4 + j]
                + bt2 * params[E + 8 + j]
                + bt3 * params[E + 12 + j]
            )


@_inline
def postprocess_rows(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    held: int,
    held_value: float,
    T: np.ndarray,
    k: int,
    ref: np.ndarray,
    kr: int,
    sort: bool,
    within: bool,
    rows: np.ndarray,
    flat: np.ndarray,
    n: int,
    pre: np.ndarray,
    Q: np.ndarray,
    refine: bool,
    work: np.ndarray,
) -> int:
    """Wrap, filter by the limits, verify by FK, dedupe and sort ``rows[:n]`` into ``Q[k]``.

    The steps of the module docstring for a chain of ``dof`` joints whose data sit in
    ``params`` where ``layout`` says (:data:`optik.analytic._rows.Layout`). Joint
    ``held`` (``-1``: none) keeps exactly ``held_value`` (no 2 pi shift). ``T[k]`` is
    the validated world target of the tool and ``ref[kr]`` the reference; ``rows``
    (24, dof) holds the raw branches in its first 8 rows (wrapped and compacted in
    place), then their sines and cosines, and ``flat`` is the same memory seen flat;
    ``pre`` (dof + 2, 12) is FK scratch. With ``refine`` (a closed form of the ideal
    arm, :mod:`optik.analytic._newton`) each row takes one Newton step on the chain
    before its check (:func:`_refine_row`); ``work`` is that step's scratch. Inlined:
    callers pass ``layout``, ``dof``, ``held`` and ``refine`` as constants where they
    can. Returns the number of rows written to ``Q[k]``.
    """
    tols = layout[5]
    # Rows the Newton step may still move are filtered again once moved: first with the
    # step's bound as slack, so that a branch on a limit is not lost to its rounding.
    strict_tol = params[tols + TOL_LIMIT]
    limit_tol = strict_tol + (REFINE_MAX_STEP if refine else 0.0)
    verify_tol = params[tols + TOL_VERIFY]
    position_tol = params[tols + TOL_VERIFY_POSITION]
    dup_tol = params[tols + TOL_DUPLICATE]
    # 1. Finite rows, wrapped, inside the limits (when asked): compacted to rows[:kept].
    kept = 0
    # Bit r: row r was beyond a limit and is put on it, by rounding (LIMIT_CLIP) or from
    # farther (LIMIT_STEP).
    on_limit_bits = 0
    from_beyond_bits = 0
    for r in range(n):
        finite = True
        for j in range(dof):
            if not math.isfinite(rows[r, j]):
                finite = False
        if not finite:
            continue
        _wrap_row(params, _runtime(layout), rows, r, ref, kr)  # as _refine_row's call
        if held >= 0:
            rows[r, held] = held_value
        if within:
            if not _inside(params, layout, dof, rows, r, limit_tol):
                if not _inside(params, layout, dof, rows, r, max(limit_tol, LIMIT_STEP)):
                    continue
                if not refine:
                    if _inside(params, layout, dof, rows, r, LIMIT_CLIP):
                        on_limit_bits |= 1 << kept
                    else:
                        from_beyond_bits |= 1 << kept
            if not refine:  # a refined row is put on its bounds once moved
                _onto_bounds(params, layout, dof, held, rows, r)
        if kept != r:
            for j in range(dof):
                rows[kept, j] = rows[r, j]
        kept += 1
    # 2. Sines and cosines of every kept joint value at once (a vectorised loop).
    sincos_block(flat, kept * dof, dof)
    # 3. Verify each by the robot's own chain (fk_into's arithmetic), dedupe in order.
    for i in range(12):
        pre[0, i] = params[layout[4] + i]
    depth = np.int64(0)  # not the literal 0: one signature of fk_shared
    m = 0
    for r in range(kept):
        depth = fk_shared(params, _runtime(layout), rows, r, pre, depth)
        clipped = KEPT
        if (on_limit_bits >> r) & 1:
            clipped = PUT_ON_LIMIT
        elif (from_beyond_bits >> r) & 1:
            clipped = PUT_FROM_BEYOND
        if refine:
            # A row already at rounding takes no step (an exact closed form's rows all),
            # but it passed the limits with the step's slack: the strict test here.
            if pose_residual(pre, dof, T, k, work) > REFINE_ROUNDING * REFINE_ROUNDING:
                # Run-time (not literal) arguments: the step and the check it calls are
                # typed and compiled once, not in each of the six pipelines that inline
                # this function (the install compiles them all).
                depth, keep = _refine_row(
                    params, _runtime(layout), np.int64(dof), np.int64(held), held_value, T,
                    k, ref, kr, within, rows, r, pre, depth, verify_tol, work, REFINE_MAX_STEP,
                )  # fmt: skip
                if keep == DROPPED:
                    continue
                clipped = keep
            elif within and not _inside(params, layout, dof, rows, r, strict_tol):
                if not _inside(params, layout, dof, rows, r, LIMIT_STEP):
                    continue
                near = _inside(params, layout, dof, rows, r, LIMIT_CLIP)
                clipped = PUT_ON_LIMIT if near else PUT_FROM_BEYOND
                depth = _onto_bounds_fk(
                    params, _runtime(layout), np.int64(dof), np.int64(held), rows, r, pre
                )
        if clipped != KEPT or not _pose_verified(pre, dof, T, k, verify_tol, position_tol):
            # A near miss (a tangent or free-angle rule rounded at a singular pose), or a
            # row put on a limit.
            query = RowQuery(
                params, _runtime(layout), np.int64(dof), np.int64(held), held_value, T, k,
                ref, kr, within, rows, pre, work, verify_tol, position_tol,
            )  # fmt: skip
            depth, keep = _near_miss_or_held(query, r, depth, Q[k, m], clipped)
            if not keep:
                continue
        duplicate = False
        for other in range(m):
            diff = 0.0
            for j in range(dof):
                diff = max(diff, abs(rows[r, j] - Q[k, other, j]))
            if diff < dup_tol:
                duplicate = True
                break
        if duplicate:
            continue
        for j in range(dof):
            v = rows[r, j]
            if within and j != held:
                # Onto the bound a row passed within the tolerance (rounding of a branch
                # at its limit): an answer inside its limits, not 1e-12 beyond them; the
                # pose moves by that much times the arm's length.
                v = min(max(v, params[layout[2] + j]), params[layout[3] + j])
            Q[k, m, j] = v
        m += 1
    if sort and m > 1:
        # 4. By distance to the reference; the keys go in the (now free) sine rows.
        _sort_by_distance(Q, k, m, ref, kr, flat, SIN_ROWS * dof)
    return m


@_inline
def postprocess_one(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    held: int,
    held_value: float,
    T1: np.ndarray,
    ref1: np.ndarray,
    flags: int,
    rows: np.ndarray,
    flat: np.ndarray,
    n: int,
    pre: np.ndarray,
    out: np.ndarray,
    refine: bool,
    work: np.ndarray,
) -> int:
    """:func:`postprocess_rows` of a single call: target ``T1[0]``, reference ``ref1[0]``.

    ``flags`` as :func:`solve` takes them; the rows go to ``out`` (8, dof). Returns their
    count.
    """
    sort, within = flag_bits(flags)
    k = np.int64(0)  # not the literal 0: the batch's signatures serve this call too
    return postprocess_rows(
        params, layout, dof, held, held_value, T1, k, ref1, k, sort, within, rows, flat, n,
        pre, out[None], refine, work,
    )  # fmt: skip


@_jit
def solve(params: np.ndarray, T: np.ndarray, ref: np.ndarray, flags: int, out: np.ndarray) -> int:
    """The whole pipeline for one target: validate, solve, wrap, filter, verify, sort.

    Five arguments only: the numba dispatcher's cost grows with each (about 0.15 us per
    array), and a single call is meant to take a few microseconds.

    Args:
        params: the robot's parameter vector (:func:`optik.analytic._compiled.pack_params`),
            family included.
        T: (4, 4) world target of the tool.
        ref: (6,) reference configuration (rad, m).
        flags: :data:`SORT` and / or :data:`WITHIN_LIMITS`.
        out: (8, 6) output rows.

    Returns:
        The number of branches written to ``out`` (0 to 8); -1 when ``T`` is not a valid
        pose (see :func:`optik._math.pose_defect`), -2 when ``ref`` is not finite. The caller raises
        the matching optik error.
    """
    T1 = T[None]
    code = input_code(params, AT_TOLS, T1, ref)
    if code != 0:
        return code
    return _solve_one(params, T1, ref[None], flags, out, np.empty(16 + scratch_size(DOF)))


@_jit
def _solve_one(
    params: np.ndarray,
    T1: np.ndarray,
    ref1: np.ndarray,
    flags: int,
    out: np.ndarray,
    scratch: np.ndarray,
) -> int:
    """:func:`solve`'s steps for the validated target ``T1[0]``, on borrowed views.

    As in :func:`_solve_each`, the caller owns every array for the whole call. One
    scratch array, the flange target (4, 4) then the blocks of
    :func:`optik.analytic._pipeline_args.scratch_blocks`, costs one allocation instead
    of four: with the borrowing, a single call of the Kinova (a Newton step on each of
    its 8 rows) takes 0.8 us less, the others about 0.1 us.
    """
    params, T1, ref1, out = borrowed(params), borrowed(T1), borrowed(ref1), borrowed(out)
    scratch = borrowed(scratch)
    T0 = scratch[:16].reshape((4, 4))
    pre, flat, rows, work = scratch_blocks(scratch[16:], DOF)
    k = np.int64(0)  # not the literal 0: the batch's signatures serve this call too
    _transform_target(params, T1, k, T0)
    dh = params[AT_DH:AT_LOWER].reshape((DOF, NCOL))
    n = robot_candidates(params, dh, T0, ref1, k, rows)
    refine = params[AT_REFINE] != 0.0
    return postprocess_one(
        params, SIX_JOINT_LAYOUT, DOF, -1, 0.0, T1, ref1, flags, rows, flat, n, pre, out,
        refine, work,
    )  # fmt: skip


@_jit
def solve_batch(
    params: np.ndarray, T: np.ndarray, ref: np.ndarray, flags: int
) -> tuple[np.ndarray, np.ndarray]:
    """The pipeline of :func:`solve` over validated targets ``T`` (N, 4, 4), serially.

    Args:
        params: the robot's parameter vector (:func:`optik.analytic._compiled.pack_params`),
            family included.
        T: (N, 4, 4) world targets of the tool, already validated
            (:func:`optik._math.first_bad_pose`).
        ref: (1, 6) one reference for every target, or (N, 6) one per target; finite.
        flags: :data:`SORT` and / or :data:`WITHIN_LIMITS`.

    Returns:
        ``Q`` (N, 8, 6): branches, rows past each count filled with NaN; ``counts`` (N,).
    """
    sort, within, pre, flat, rows, work, Q, counts = batch_work(T.shape[0], DOF, flags)
    T0 = np.empty((4, 4))
    _solve_each(params, T, ref, sort, within, T0, pre, flat, rows, work, Q, counts)
    return Q, counts


@_jit
def _solve_each(
    params: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    sort: bool,
    within: bool,
    T0: np.ndarray,
    pre: np.ndarray,
    flat: np.ndarray,
    rows: np.ndarray,
    work: np.ndarray,
    Q: np.ndarray,
    counts: np.ndarray,
) -> None:
    """:func:`solve_batch`'s loop over the targets, on borrowed views of its arrays.

    The caller owns every array for the whole call, so the loop may pass views without
    an owner record (:func:`optik._nrt.borrowed`): numba then counts no references at
    the per-row calls (the FK, the Newton step), which cost as much as the step's
    arithmetic (the Kinova's batch: 253,000 poses/s counted, 337,000 borrowed).
    """
    params, T, ref, T0 = borrowed(params), borrowed(T), borrowed(ref), borrowed(T0)
    pre, flat, rows = borrowed(pre), borrowed(flat), borrowed(rows)
    work, Q = borrowed(work), borrowed(Q)
    shared = ref.shape[0] == 1
    dh = params[AT_DH:AT_LOWER].reshape((DOF, NCOL))
    refine = params[AT_REFINE] != 0.0
    for k in range(T.shape[0]):
        kr = 0 if shared else k
        _transform_target(params, T, k, T0)
        n = robot_candidates(params, dh, T0, ref, kr, rows)
        counts[k] = postprocess_rows(
            params, SIX_JOINT_LAYOUT, DOF, -1, 0.0, T, k, ref, kr, sort, within, rows, flat,
            n, pre, Q, refine, work,
        )  # fmt: skip
        pad_rows(Q, k, counts[k])
