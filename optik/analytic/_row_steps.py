"""The Newton steps of one row of the compiled pipeline (:mod:`._pipeline`).

A row of a closed form of the ideal arm takes one step on the robot's own chain
(:func:`_refine_row`, :mod:`optik.analytic._newton`); a row that misses the FK check by a
little (a tangent rule rounded at a singular pose) takes a few (:func:`_near_miss`); a
row put on a joint limit takes them with that joint held (:func:`_near_miss_or_held`),
and one put there from beyond :data:`~optik.analytic._base.LIMIT_CLIP` is kept only at
rounding (:data:`RESCUE_RATIO`). :func:`optik.analytic._pipeline.postprocess_rows` calls
them; the rare paths are calls of their own, compiled once for every pipeline.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._base import LIMIT_CLIP, LIMIT_STEP
from optik.analytic._compiled import TOL_LIMIT
from optik.analytic._newton import (
    REFINE_ROUNDING,
    REFINE_TRUSTED_STEP,
    newton_step,
    pose_residual,
    restore_row,
)
from optik.analytic._rows import (
    Layout,
    _inside,
    _onto_bounds_fk,
    _pose_verified,
    _row_sines,
    _wrap_row,
    fk_shared,
)

NOT_MOVED, MOVED, MOVED_UNCHECKED = 0, 1, 2
"""Outcomes of :func:`_newton_move` (see there)."""

DROPPED, KEPT, PUT_ON_LIMIT, PUT_FROM_BEYOND = 0, 1, 2, 3
"""Outcomes of :func:`_refine_row` (see there), and how a row came onto its limits."""

RESCUE_RATIO = 1e-3
"""A row put on a limit from beyond :data:`~optik.analytic._base.LIMIT_CLIP` is kept only
if Newton steps bring it within this fraction of the FK check's tolerances of its pose
(1e-12 for the default 1e-9): an exact answer's rounding, not a compromise."""


class RowQuery(NamedTuple):
    """What the Newton steps of a near miss read (:func:`_near_miss`).

    Built by :func:`postprocess_rows` for a row that misses the FK check only (a tuple of
    arrays costs a reference count per array), with run-time (not literal) integers:
    the steps are typed and compiled once, not in each pipeline.

    Attributes:
        params: the parameter vector; ``layout`` says where its blocks sit
            (:data:`optik.analytic._rows.Layout`).
        layout: the blocks of ``params``.
        dof: number of joints of the chain.
        held: the joint that keeps ``held_value`` exactly (``-1``: none).
        held_value: its value (rad or m).
        T: validated world targets of the tool (N, 4, 4); the row's is ``T[k]``.
        k: the target's index.
        ref: references (rad, m); the row's is ``ref[kr]``.
        kr: the reference's index.
        within: whether rows must stay inside the joint limits.
        rows: the rows (joint values, rad or m), then their sines and cosines
            (:func:`postprocess_rows`).
        pre: (dof + 2, 12) FK scratch, the row's FK.
        work: the Newton step's scratch (:mod:`optik.analytic._newton`).
        verify_tol: the FK check's tolerance (rad, and m unless ``position_tol``).
        position_tol: the FK check's position tolerance (m).
    """

    params: np.ndarray
    layout: Layout
    dof: int
    held: int
    held_value: float
    T: np.ndarray
    k: int
    ref: np.ndarray
    kr: int
    within: bool
    rows: np.ndarray
    pre: np.ndarray
    work: np.ndarray
    verify_tol: float
    position_tol: float


@_inline
def _refine_row(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    held: int,
    held_value: float,
    T: np.ndarray,
    k: int,
    ref: np.ndarray,
    kr: int,
    within: bool,
    rows: np.ndarray,
    r: int,
    pre: np.ndarray,
    depth: int,
    verify_tol: float,
    work: np.ndarray,
    max_step: float,
) -> tuple[int, int]:
    """One Newton step of ``rows[r]`` towards ``T[k]``, its FK in ``pre`` (:mod:`._newton`).

    For a row not at rounding (:data:`optik.analytic._newton.REFINE_ROUNDING`), its
    residual in ``work[:6]`` (:func:`optik.analytic._newton.pose_residual`).
    The step is kept when it lowers the residual (the caller then checks the limits on
    the row as moved). A small step (:data:`optik.analytic._newton.REFINE_TRUSTED_STEP`) from a
    row already within half the FK check's tolerance is kept without a second FK: ``pre``
    keeps the unmoved row's pose, which passes the check, and the moved row's residual is
    at most the unmoved one's plus a second-order term (about 1e-16). Otherwise the moved
    row's pose replaces it in ``pre`` (or the row goes back). A moved row is wrapped again
    where the step took an angle past the half-turn from ``ref[kr]``, and, ``within``,
    checked against the limits. Returns the FK depth valid in ``pre``
    (:func:`optik.analytic._rows.fk_shared`) and whether the row stays: :data:`DROPPED`,
    :data:`KEPT`, or put on its limits from beyond them: by at most
    :data:`~optik.analytic._base.LIMIT_CLIP` (:data:`PUT_ON_LIMIT`) or farther, up to
    :data:`~optik.analytic._base.LIMIT_STEP` (:data:`PUT_FROM_BEYOND`).
    """
    outcome = _newton_move(params, layout, dof, held, rows, r, pre, verify_tol, work, max_step)
    if outcome == MOVED_UNCHECKED:
        depth = _check_moved(params, layout, dof, T, k, rows, r, pre, work)
    strict = params[layout[5] + TOL_LIMIT]
    # One pass: whether the step took an angle past the half-turn from the reference
    # (rare: then wrapped again; the step moves a wrapped row by at most max_step,
    # so only such an angle can change its nearest representative) and whether the row
    # is inside the limits (every row: the first filter let it pass with the step's slack).
    past_half_turn = False
    inside = True
    for j in range(dof):
        v = rows[r, j]
        if abs(v - ref[kr, j]) > math.pi and params[layout[0] + layout[1] * j] == 0.0:
            past_half_turn = True
        if not (params[layout[2] + j] - v <= strict and v - params[layout[3] + j] <= strict):
            inside = False
    if past_half_turn:
        _wrap_row(params, layout, rows, r, ref, kr)
        if held >= 0:
            rows[r, held] = held_value
        inside = _inside(params, layout, dof, rows, r, strict)
    if not within or inside:
        return depth, KEPT
    if not _inside(params, layout, dof, rows, r, LIMIT_STEP):
        return depth, DROPPED
    came = PUT_ON_LIMIT if _inside(params, layout, dof, rows, r, LIMIT_CLIP) else PUT_FROM_BEYOND
    return _onto_bounds_fk(params, layout, dof, held, rows, r, pre), came


@_jit
def _newton_move(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    held: int,
    rows: np.ndarray,
    r: int,
    pre: np.ndarray,
    verify_tol: float,
    work: np.ndarray,
    max_step: float,
) -> int:
    """:func:`_refine_row`'s step: :data:`NOT_MOVED`, :data:`MOVED` or :data:`MOVED_UNCHECKED`.

    The row's residual is in ``work[:6]`` (:func:`optik.analytic._newton.pose_residual`).
    :data:`NOT_MOVED`: every step refused (the row as it was); :data:`MOVED`: a step of at
    most :data:`optik.analytic._newton.REFINE_TRUSTED_STEP` from a row within half the FK
    check's tolerance, kept without a second FK; :data:`MOVED_UNCHECKED`: a step that
    :func:`_check_moved` keeps only if the moved row is closer. A call of its own, apart
    from :func:`_check_moved`: with the rare path's calls in the same compiled function,
    the common path ran about 0.1 us a row slower (the Kinova's batch, 8 rows a pose).
    """
    before = 0.0  # squared, as every comparison here
    for i in range(6):
        before += work[i] * work[i]
    wrist = layout[6]
    if wrist >= 0 and not math.isfinite(params[wrist]):
        wrist = -1
    moved = newton_step(
        params, layout[0], layout[1], dof, held, wrist, pre, rows, r, work, max_step
    )  # fmt: skip
    if moved == 0.0:
        return NOT_MOVED
    if moved <= REFINE_TRUSTED_STEP and before <= 0.25 * verify_tol * verify_tol:
        return MOVED
    return MOVED_UNCHECKED


@_jit
def _check_moved(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    T: np.ndarray,
    k: int,
    rows: np.ndarray,
    r: int,
    pre: np.ndarray,
    work: np.ndarray,
) -> int:
    """The FK of a row :func:`_newton_move` moved; the row goes back unless it is closer.

    ``work[:6]`` still holds the unmoved row's residual. Returns the new FK depth.
    """
    before = 0.0
    for i in range(6):
        before += work[i] * work[i]
    _row_sines(rows, r, dof)
    start = np.int64(0)  # not the literal 0: one signature of fk_shared
    depth = fk_shared(params, layout, rows, r, pre, start)
    if pose_residual(pre, dof, T, k, work) < before:
        return depth
    restore_row(dof, rows, r, work)
    _row_sines(rows, r, dof)
    return fk_shared(params, layout, rows, r, pre, start)


NEAR_MISS = 1e5
"""A row that misses the FK check by at most this many times its tolerance (1e-4 m or
rad for the default 1e-9) takes Newton steps (:func:`_near_miss`). At a singular pose a
closed form's tangent rule merges two roots ``2 sqrt(2 band / r)`` apart (``band`` the
rule's, ``r`` the equation's size): the UR10's shoulder (``r`` = 0.17 m) is then 1e-5 rad
off, and its tool 1.3e-5 m, which the check refuses."""

NEAR_MISS_STEPS = 4
"""Most Newton steps of a near miss (:func:`_near_miss`); each must lower its residual."""

NEAR_MISS_MAX_STEP = 1e-2
"""Largest component (rad or m) of a near miss's Newton step: the UR10's above moves its
wrist joints 1.3e-4 rad; a larger step is a search, not a polish."""


@_jit
def _near_miss(query: RowQuery, r: int, depth: int, polish: bool) -> tuple[int, bool, bool]:
    """Newton steps of ``rows[r]``, which failed the FK check in ``pre``, towards ``T[k]``.

    Only a near miss (residual within :data:`NEAR_MISS` times the larger tolerance) is
    moved, by :func:`_refine_row`'s steps (wrapped and limited as there), at most
    :data:`NEAR_MISS_STEPS`, each lowering the residual. Returns the FK depth valid in
    ``pre``, whether the moved row passes the check (then kept as any other), and whether
    a step put it on a limit from beyond :data:`~optik.analytic._base.LIMIT_CLIP` (the
    caller then asks more, :func:`_near_miss_or_held`). With ``polish`` the steps go on
    after the row passes, to rounding while they help (the caller asks for it); without,
    the first row that passes is kept. A call of its own: it runs only at singular
    poses, off the common path.
    """
    dof, T, k, pre, work = query.dof, query.T, query.k, query.pre, query.work
    verify_tol, position_tol = query.verify_tol, query.position_tol
    band = NEAR_MISS * max(verify_tol, position_tol)
    residual = pose_residual(pre, dof, T, k, work)
    verified = False
    beyond = False
    for _ in range(NEAR_MISS_STEPS):
        if not residual <= band * band:
            return depth, False, beyond
        depth, keep = _refine_row(
            query.params, query.layout, dof, query.held, query.held_value, T, k, query.ref,
            query.kr, query.within, query.rows, r, pre, depth, verify_tol, work,
            NEAR_MISS_MAX_STEP,
        )  # fmt: skip
        if keep == DROPPED:
            return depth, False, beyond
        beyond = beyond or keep == PUT_FROM_BEYOND
        after = pose_residual(pre, dof, T, k, work)
        if _pose_verified(pre, dof, T, k, verify_tol, position_tol):
            # Passed; polished, the steps go on to rounding while they help (a row put
            # on a limit passed by a margin only, 9e-10 of 1e-9, and the next step
            # took it to 1e-15).
            verified = True
            if not polish or after <= REFINE_ROUNDING * REFINE_ROUNDING:
                return depth, True, beyond
        if not after < residual:
            return depth, verified, beyond  # the step was refused or did not help
        residual = after
    return depth, verified, beyond


@_jit
def _near_miss_or_held(
    query: RowQuery, r: int, depth: int, saved: np.ndarray, clipped: int
) -> tuple[int, bool]:
    """:func:`_near_miss`, and within the limits the same steps with a joint on a limit held.

    For a row that failed the FK check (``clipped`` :data:`KEPT`), or that was beyond a
    limit and is put on it: by at most :data:`~optik.analytic._base.LIMIT_CLIP`
    (:data:`PUT_ON_LIMIT`, the closed form's rounding) or farther, up to
    :data:`LIMIT_STEP` (:data:`PUT_FROM_BEYOND`); ``query.held`` -1. Next to a singularity
    the closed form splits two nearly parallel joints only to ``eps / sin(q5)``: one lands
    beyond its limit and is put on it, and the other must turn by as much for the pose to
    hold, which a step free to move the first one does not find. Each joint exactly on a
    limit is held in turn, each try from the row as it came (``saved`` (dof,), free
    scratch: the row's output slot); a try is taken if it passes the check nearer the
    pose than the row came.

    A row from beyond a limit (put there before the steps, or by one of them) is kept
    only where it reaches the pose to rounding (:data:`RESCUE_RATIO` of the check's
    tolerances): its own branch lies outside the limits, and an answer inside them must
    be that branch's twin on a singular set, not a compromise that the check's tolerance
    lets pass (a Puma branch 1e-8 below its limit came back on it, 8e-10 m off the pose).
    A row put on a limit by rounding that passed the check as it came is kept as it came
    if no try is better. Returns as ``_near_miss``.
    """
    params, layout, dof, rows, pre = query.params, query.layout, query.dof, query.rows, query.pre
    T, k, verify_tol, position_tol = query.T, query.k, query.verify_tol, query.position_tol
    work = query.work
    for j in range(dof):
        saved[j] = rows[r, j]
    passed = _pose_verified(pre, dof, T, k, verify_tol, position_tol)
    before = pose_residual(pre, dof, T, k, work) if passed else math.inf
    exact = RESCUE_RATIO * min(verify_tol, position_tol)
    holding = query.within and query.held < 0
    if clipped == KEPT or not holding or (clipped == PUT_ON_LIMIT and not passed):
        depth, keep, beyond = _near_miss(query, r, depth, clipped == PUT_FROM_BEYOND)
        if keep and (beyond or clipped == PUT_FROM_BEYOND):
            depth = _fk_again(params, layout, dof, rows, r, pre)
            keep = pose_residual(pre, dof, T, k, work) <= exact * exact
        if keep or not holding:
            return depth, keep
    for h in range(dof):
        v = saved[h]
        if not (v == params[layout[2] + h] or v == params[layout[3] + h]):
            continue
        depth = _restored(params, layout, dof, rows, r, pre, saved)
        held = RowQuery(
            params, layout, dof, np.int64(h), v, T, k, query.ref, query.kr,
            query.within, rows, pre, work, verify_tol, position_tol,
        )  # fmt: skip
        # `holding` (True here), not the literal: one signature of _near_miss.
        depth, keep, beyond = _near_miss(held, r, depth, holding)
        if keep:
            # The row's own FK (a trusted last step leaves the unmoved pose in pre).
            depth = _fk_again(params, layout, dof, rows, r, pre)
            after = pose_residual(pre, dof, T, k, work)
            if beyond or clipped == PUT_FROM_BEYOND:
                keep = after <= exact * exact
            if keep and after < before and _pose_verified(pre, dof, T, k, verify_tol, position_tol):
                return depth, True
    depth = _restored(params, layout, dof, rows, r, pre, saved)
    return depth, clipped == PUT_ON_LIMIT and passed


@_jit
def _fk_again(
    params: np.ndarray, layout: Layout, dof: int, rows: np.ndarray, r: int, pre: np.ndarray
) -> int:
    """The sines and the FK of ``rows[r]`` anew into ``pre``: the FK depth.

    A call, not inlined: the rare path of :func:`_near_miss_or_held` reaches it from four
    places, and inlined each copy of the sines was compiled again.
    """
    _row_sines(rows, r, dof)
    return fk_shared(params, layout, rows, r, pre, np.int64(0))


@_inline
def _restored(
    params: np.ndarray,
    layout: Layout,
    dof: int,
    rows: np.ndarray,
    r: int,
    pre: np.ndarray,
    saved: np.ndarray,
) -> int:
    """``rows[r]`` set back to ``saved`` (dof,), with its sines and its FK: the FK depth."""
    for j in range(dof):
        rows[r, j] = saved[j]
    return _fk_again(params, layout, dof, rows, r, pre)
