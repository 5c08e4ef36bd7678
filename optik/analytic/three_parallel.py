"""Six revolute axes with three parallel ones, any twists elsewhere (from the axes).

Two of EAIK's classes without the UR's right angles (``ur`` takes those), in the product
of exponentials of the joint axes at ``q = 0`` (:func:`optik.analytic.geometry.joint_axes`,
``fk(q) = R_1(q_1) ... R_6(q_6) M``, ``G = T M^-1``). Three parallel axes (direction ``h``,
distinct lines) turn about ``h`` and shift across it: together they keep the
``h``-component of every direction and the height along ``h`` of every point.

**Inner** (:func:`three_inner_candidates`; "three inner parallel"): axes 2, 3 and 4
parallel, axes 1 and 5 not parallel to ``h``, axis 6 not parallel to axis 5. Two
conditions tie ``q_5`` to ``q_1`` alone:

- directions: ``h . R_5(q_5) z_6 = h . R_1(q_1)^-1 R_G z_6``;
- heights: ``h . R_5(q_5) p_6 = h . R_1(q_1)^-1 G p_6`` (``p_6`` a point of axis 6,
  chosen off axis 5 by the plan).

Both are linear in ``(cos q_1, sin q_1)`` and ``(cos q_5, sin q_5)``: the system of
:func:`optik.analytic._angle_pairs.angle_pairs`, a quartic, up to 4 pairs. Then ``q_6`` by
subproblem 1 (``R_6 F^T h = R_5^-1 h`` with ``F`` the rotation of ``R_1^-1 G``), the turn
``theta`` from the rest of the rotation, and the planar arm: the point ``p_4`` of axis 4
must reach ``X = R_1^-1 G R_6^-1 R_5^-1 p_4``: ``q_3`` by its distance from axis 2
(subproblem 3, up to two), ``q_2`` by subproblem 1, ``q_4`` the rest of ``theta``.

**Outer** (:func:`three_outer_candidates`; "three parallel, two intersecting"): axes 1, 2
and 3 parallel, axes 5 and 6 meeting at ``C`` off axis 4, axis 4 not parallel to ``h``.
``R_5 R_6`` fix ``C``, so ``h . R_4(q_4) C = h . G C`` (subproblem 4, up to two ``q_4``);
then ``h . R_4 R_5(q_5) z_6 = h . R_G z_6`` (subproblem 4, up to two ``q_5``), ``q_6``
by subproblem 1, ``theta``, and the planar arm on axis 3's point (``q_2`` by its distance
from axis 1, ``q_1`` by subproblem 1, ``q_3`` the rest).

Up to 8 branches each, refined by one Newton step on the chain and checked by FK in the
post-processing; the same read backwards (axes 3, 4, 5 parallel; axes 4, 5, 6 parallel
with axes 1 and 2 meeting). At a singularity a free angle takes the reference; where
the inner kind's two conditions are one equation (a self-motion), ``q_1`` takes the
reference's value and its opposite, or failing those a grid's (:func:`_continuum_rows`).
Where axis 6 lies along the parallel axes (``q_5`` then a double root of the quartic, off
by about sqrt(eps), and ``q_6`` from it ill-conditioned) the solutions are found along
``q_6`` instead (:func:`_wrist_along_triples`): for each ``q_6`` the rotation gives ``(q_1,
q_5)`` by subproblems 4 and 1, well conditioned, and the one condition left, the height
of the elbow's target, is a smooth function of ``q_6`` whose zeros are the branches (a
self-motion where it vanishes along the turn).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._math import wrap_angle
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._angle_pairs import (
    Mat2,
    Vec2,
    angle_pairs,
    pair_continuum,
    quartic_vanishes,
    singular_pairs,
)
from optik.analytic._compiled import MAX_BRANCHES, closed_form_tols, mul3, store_branch
from optik.analytic._subproblems import (
    RootTols,
    Rot9,
    Vec3,
    apply,
    apply_t,
    axpy,
    circle,
    cross,
    dot,
    meeting_point,
    norm,
    plane_angles,
    reach_angles,
    rotation,
    six_rows,
    sp1_angle,
    sub,
    turn_point,
    unit,
    vec_at,
)
from optik.analytic.pair_wrist import REACH_TOL, AxesQuery, target_frame

_ORIGIN = (0.0, 0.0, 0.0)


class AlongQuery(NamedTuple):
    """What the search along ``q_6`` reads (:func:`_wrist_along_rows`; built only there).

    ``z`` (6, 3) and ``p`` (6, 3): the axes' unit directions and points at ``q = 0`` (m);
    ``RG``, ``tG``: the target frame's rotation and translation (m); ``ref`` (6,): the
    reference (rad); ``roots``: the tolerances of the trigonometric roots; ``axis_tol``:
    the relative length under which a point lies on an axis.
    """

    z: np.ndarray
    p: np.ndarray
    RG: Rot9
    tG: Vec3
    ref: np.ndarray
    roots: RootTols
    axis_tol: float


CONTINUUM_TRIES = 8
"""Values of ``q_1`` (each with its opposite) tried on a self-motion of the inner kind:
the reference's, then the rest of an even grid over half a turn, nearest first."""
WRIST_TRIES = 32
"""Values of ``q_6`` in an even grid over the turn from the reference's, where axis 6 lies
along the parallel axes (``q_6`` free in its subproblem but not for the elbow): sampled by
the search along ``q_6`` (:func:`_wrist_along_triples`), tried by the pairs' own grid
(:func:`_grid_triples`)."""
WRIST_ALONG_TOL = 1e-6
"""Axis 6 counts as along the parallel axes for that grid when the sine of their angle
is at most this: a q5 found as a double root is off by about sqrt(eps) = 1.5e-8."""
HEIGHT_TOL = 1e-12
"""A height mismatch (:func:`_pairs_at`) at most this times the arm's size (m) is zero: a
self-motion, whose rows at that ``q_6`` are taken as they are."""
FOLLOW_GAP = 0.5
"""Largest change (rad, ``|dq_1| + |dq_5|``) of a pair between neighbouring values of
``q_6`` still taken as the same pair followed along ``q_6`` (:func:`_follow`); past it a
change of sign of the mismatch is not searched."""
ALONG = -1
"""What :func:`_inner_rows` returns where a pair puts axis 6 along the parallel axes."""
ROOT_STEPS = 64
"""Most steps of the bracketed search for a zero of the height mismatch in ``q_6``
(:func:`_mismatch_zero`); it converges in about ten."""


@_jit
def _planar_rest(
    h: Vec3,
    F: Rot9,
    last: Rot9,
    across: Vec3,
) -> float:
    """``theta``: the angle about ``h`` of ``F last^T`` (a turn about ``h``)."""
    last_t = (last[0], last[3], last[6], last[1], last[4], last[7], last[2], last[5], last[8])
    turn = mul3(F, last_t)
    return sp1_angle(h, across, apply(turn, across), 0.0, 0.0)


@_jit
def three_inner_candidates(query: AxesQuery, cand: np.ndarray) -> int:
    """Raw branches of the three-inner-parallel closed form into ``cand`` (>= 8, 6).

    Arguments as :func:`optik.analytic.pair_wrist.pair_wrist_candidates` (``p[5]`` off
    axis 5). Returns the number of rows written (0 to 8): the quartic's pairs, then the
    elbow.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, h, z5, z6 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 4), vec_at(z, 5)
    p1, p5, p6 = vec_at(p, 0), vec_at(p, 4), vec_at(p, 5)
    RG, tG = target_frame(T, M)
    back = (-z1[0], -z1[1], -z1[2])  # R_1(q)^-1 turns by q about -z1
    Gp6 = axpy(1.0, apply(RG, p6), tG)
    xa0, xac, xas = circle(z5, _ORIGIN, z6)
    ya0, yac, yas = circle(back, _ORIGIN, apply(RG, z6))
    xb0, xbc, xbs = circle(z5, p5, p6)
    yb0, ybc, ybs = circle(back, p1, Gp6)
    size = max(norm(sub(p6, p5)), norm(sub(Gp6, p1)), 1e-300)
    inv = 1.0 / size
    A = (dot(h, yac), dot(h, yas), dot(h, ybc) * inv, dot(h, ybs) * inv)
    B = (dot(h, xac), dot(h, xas), dot(h, xbc) * inv, dot(h, xbs) * inv)
    b0 = (dot(h, sub(xa0, ya0)), dot(h, sub(xb0, yb0)) * inv)
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    if pair_continuum(A, b0, B):
        return _continuum_rows(A, b0, B, True, z, p, RG, tG, ref, roots, axis_tol, cand)
    pairs = np.empty((2, 4))
    count = angle_pairs(A, b0, B, ref[0], ref[4], roots, pairs)
    n = _inner_rows(z, p, RG, tG, pairs, count, ref, roots, axis_tol, cand)
    if n == ALONG:
        along = AlongQuery(z, p, RG, tG, ref, roots, axis_tol)
        return _wrist_along_rows(along, pairs, count, cand)
    if n == 0 and quartic_vanishes(A, b0, B):
        return _continuum_rows(A, b0, B, False, z, p, RG, tG, ref, roots, axis_tol, cand)
    return n


@_jit
def _continuum_rows(
    A: Mat2,
    b0: Vec2,
    B: Mat2,
    proportional: bool,
    z: np.ndarray,
    p: np.ndarray,
    RG: Rot9,
    tG: Vec3,
    ref: np.ndarray,
    roots: RootTols,
    axis_tol: float,
    cand: np.ndarray,
) -> int:
    """The rows of :func:`three_inner_candidates` on a self-motion (a curve of pairs).

    ``q_1`` takes the reference's value and the value half a turn from it (the
    shoulder's two sides: parts of the curve the elbow's reach may separate), each with
    its ``q_5`` (:func:`optik.analytic._angle_pairs.singular_pairs`, the conditions'
    rows ``proportional``); or, where they only share the curve
    (:func:`optik.analytic._angle_pairs.quartic_vanishes`), the quartic's eliminated
    angle takes them. Where the elbow reaches its target at neither, the next values of
    an even grid over half a turn, nearest first (:data:`CONTINUUM_TRIES`).
    """
    pairs = np.empty((2, 4))
    for k in range(CONTINUUM_TRIES):
        shift = _grid_shift(k, math.pi / CONTINUUM_TRIES)
        t1 = ref[0] + shift
        if proportional:
            count = singular_pairs(A, b0, B, t1, ref[4], roots, pairs)
            count += singular_pairs(A, b0, B, t1 + math.pi, ref[4], roots, pairs[:, count:])
        else:
            count = angle_pairs(A, b0, B, t1, ref[4] + shift, roots, pairs)
        n = _inner_rows(z, p, RG, tG, pairs, count, ref, roots, axis_tol, cand)
        if n == ALONG:
            along = AlongQuery(z, p, RG, tG, ref, roots, axis_tol)
            return _wrist_along_rows(along, pairs, count, cand)
        if n > 0:
            return n
    return 0


@_jit
def _grid_shift(k: int, step: float) -> float:
    """The ``k``-th offset (rad) of an even grid, nearest first: 0, +step, -step, +2 step..."""
    return ((k + 1) // 2) * step * (1.0 if k % 2 == 1 else -1.0)


@_jit
def _wrist_along_rows(query: AlongQuery, pairs: np.ndarray, count: int, cand: np.ndarray) -> int:
    """The rows where :func:`_inner_rows` returned :data:`ALONG` for its ``count`` ``pairs``.

    Those of the triples of :func:`_wrist_along_triples`; where the search finds none that
    the elbow reaches, those of the pairs themselves with ``q_6`` on a grid
    (:func:`_grid_triples`): a pose where the search's subproblems degenerate too (axis 1
    on axis 5's line, a second self-motion) keeps the pairs of the self-motion rules. A
    call of its own, so that the common path allocates nothing. Returns the number of rows
    written to ``cand``.
    """
    z, p, RG, tG, ref, roots, axis_tol = query
    triples = np.empty((3, MAX_BRANCHES))
    m = _wrist_along_triples(query, triples)
    n = _inner_rows(z, p, RG, tG, triples, m, ref, roots, axis_tol, cand)
    if n > 0:
        return n
    m = _grid_triples(query, pairs, count, triples)
    return _inner_rows(z, p, RG, tG, triples, m, ref, roots, axis_tol, cand)


@_inline
def _wrist_q6(h: Vec3, z6: Vec3, F: Rot9, R5: Rot9, axis_tol: float) -> tuple[float, bool]:
    """``q_6`` by subproblem 1 (NaN where free), and whether axis 6 lies along ``h``.

    ``F`` is the rotation of ``R_1^-1 G`` and ``R5`` that of ``R_5``: ``R_6`` turns ``F^-1
    h`` onto ``R_5^-1 h``. Along (q6 free, or nearly: a double root's q5 is off by
    sqrt(eps), and q6 from it by as much as a turn) within :data:`WRIST_ALONG_TOL`.
    """
    h5 = apply_t(R5, h)
    t6 = sp1_angle(z6, apply_t(F, h), h5, math.nan, axis_tol)
    return t6, math.isnan(t6) or norm(cross(z6, h5)) <= WRIST_ALONG_TOL


@_jit
def _grid_triples(query: AlongQuery, pairs: np.ndarray, count: int, out: np.ndarray) -> int:
    """The pairs ``(q_1, q_5)`` with a ``q_6`` each, into the columns of ``out`` (3, >= count).

    ``q_6`` from subproblem 1; where axis 6 lies along the parallel axes, the first of the
    reference's and an even grid of :data:`WRIST_TRIES` values over the turn (nearest first)
    at which the elbow reaches. Returns ``count``.
    """
    z, p, RG, _, ref, roots, axis_tol = query
    z1, z2, z3, z5, z6 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2), vec_at(z, 4), vec_at(z, 5)
    p2, p3, p4 = vec_at(p, 1), vec_at(p, 2), vec_at(p, 3)
    h = z2
    back = (-z1[0], -z1[1], -z1[2])
    for i in range(count):
        t1, t5 = pairs[0, i], pairs[1, i]
        F = mul3(rotation(back, t1), RG)
        t6, along = _wrist_q6(h, z6, F, rotation(z5, t5), axis_tol)
        tries = WRIST_TRIES if along else 1
        if math.isnan(t6):
            t6 = ref[5]
        for k in range(tries):
            if k > 0:
                t6 = ref[5] + _grid_shift(k, 2.0 * math.pi / WRIST_TRIES)
            d = sub(_elbow_target(query, t1, t5, t6), p2)
            if reach_angles(z2, p2, z3, p3, p4, d, ref[1], ref[2], roots, axis_tol)[0] > 0:
                break
        out[0, i], out[1, i], out[2, i] = t1, t5, t6
    return count


@_jit
def _inner_rows(
    z: np.ndarray,
    p: np.ndarray,
    RG: Rot9,
    tG: Vec3,
    pairs: np.ndarray,
    count: int,
    ref: np.ndarray,
    roots: RootTols,
    axis_tol: float,
    cand: np.ndarray,
) -> int:
    """The rows of :func:`three_inner_candidates` from its ``count`` pairs ``(q_1, q_5)``.

    ``pairs`` (2, >= count): ``q_1`` then ``q_5`` (rad), and ``q_6`` given in a third row
    (else from subproblem 1); ``RG``, ``tG`` the target frame's rotation and translation.
    Writes up to 8 rows of ``cand`` and returns how many, or :data:`ALONG` where a pair
    puts axis 6 along the parallel axes (:func:`_wrist_along_rows` then searches along
    ``q_6``).
    """
    z1, z2, z3, z4, z5, z6 = six_rows(z)
    p1, p2, p3, p4, p5, p6 = six_rows(p)
    h = z2
    back = (-z1[0], -z1[1], -z1[2])
    # A direction across h, to read theta off a rotation about h.
    across = unit(cross(h, z1))
    given = pairs.shape[0] > 2
    n = 0
    for i in range(count):
        t1, t5 = pairs[0, i], pairs[1, i]
        F = mul3(rotation(back, t1), RG)  # the rotation of R_1^-1 G
        R5 = rotation(z5, t5)
        if given:
            t6 = pairs[2, i]
        else:
            t6, along = _wrist_q6(h, z6, F, R5, axis_tol)
            if along:
                return ALONG
        theta = _planar_rest(h, F, mul3(R5, rotation(z6, t6)), across)
        # X = R_1^-1 G R_6^-1 R_5^-1 p_4, by line turns (:func:`_elbow_target`).
        X = turn_point(z6, p6, -t6, turn_point(z5, p5, -t5, p4))
        X = turn_point(back, p1, t1, axpy(1.0, apply(RG, X), tG))
        d = sub(X, p2)
        n3, u1, v1, u2, v2 = reach_angles(z2, p2, z3, p3, p4, d, ref[1], ref[2], roots, axis_tol)
        for i3 in range(n3):
            t2, t3 = (u1, v1) if i3 == 0 else (u2, v2)
            t4 = dot(h, z4) * (theta - dot(h, z2) * t2 - dot(h, z3) * t3)
            if n < MAX_BRANCHES:
                t4 = math.atan2(math.sin(t4), math.cos(t4))
                n = store_branch(cand, n, (t1, t2, t3, t4, t5, t6))
    return n


@_jit
def _elbow_target(query: AlongQuery, t1: float, t5: float, t6: float) -> Vec3:
    """``X = R_1^-1 G R_6^-1 R_5^-1 p_4``: where the planar arm must put ``p_4`` (m)."""
    z, p, RG, tG = query.z, query.p, query.RG, query.tG
    z1, z5, z6 = vec_at(z, 0), vec_at(z, 4), vec_at(z, 5)
    p1, p4, p5, p6 = vec_at(p, 0), vec_at(p, 3), vec_at(p, 4), vec_at(p, 5)
    X = turn_point(z6, p6, -t6, turn_point(z5, p5, -t5, p4))
    return turn_point((-z1[0], -z1[1], -z1[2]), p1, t1, axpy(1.0, apply(RG, X), tG))


@_jit
def _pairs_at(query: AlongQuery, t6: float, out: np.ndarray, col: int) -> int:
    """The pairs ``(q_1, q_5)`` completing the rotation for ``q_6 = t6``, with their mismatch.

    ``R_1 Rot(h, theta) R_5 = F_6`` (``F_6`` the rotation of ``G R_6^-1``) turns ``h``
    to ``R_5^-1 h = F_6^-1 R_1 h``: its component along ``z_5`` gives ``q_1`` (subproblem
    4, up to two), then ``q_5`` turns it onto ``h`` (subproblem 1). The mismatch is the
    height along ``h`` of the elbow's target above ``p_4`` (:func:`_elbow_target`), which
    the planar arm keeps: zero at a branch. Each pair goes to a column of ``out`` (4, >=
    col + 2) from ``col`` on: ``q_1``, ``q_5`` (rad), the mismatch (m), and 1.0 where the
    elbow reaches the target's distance from axis 2 (else 0.0). Returns the number of
    pairs.
    """
    z, p, RG, _, ref, roots, axis_tol = query
    z1, z2, z3, z5, z6 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2), vec_at(z, 4), vec_at(z, 5)
    p2, p3, p4 = vec_at(p, 1), vec_at(p, 2), vec_at(p, 3)
    h = z2
    R6 = rotation(z6, t6)
    a = apply(RG, apply_t(R6, z5))  # F_6 z_5
    count, a1, a2 = plane_angles(z1, _ORIGIN, h, a, dot(z5, h), ref[0], roots)
    for i in range(count):
        t1 = a1 if i == 0 else a2
        w = apply(R6, apply_t(RG, apply(rotation(z1, t1), h)))  # F_6^-1 R_1 h
        t5 = sp1_angle(z5, w, h, ref[4], axis_tol)
        X = _elbow_target(query, t1, t5, t6)
        reach = reach_angles(z2, p2, z3, p3, p4, sub(X, p2), ref[1], ref[2], roots, axis_tol)
        out[0, col + i] = t1
        out[1, col + i] = t5
        out[2, col + i] = dot(h, sub(X, p4))
        out[3, col + i] = 1.0 if reach[0] > 0 else 0.0
    return count


@_jit
def _wrist_along_triples(query: AlongQuery, out: np.ndarray) -> int:
    """The triples ``(q_1, q_5, q_6)`` of the branches where axis 6 lies along the parallel axes.

    Over an even grid of :data:`WRIST_TRIES` values of ``q_6`` from the reference's, the
    pairs of :func:`_pairs_at` and their height mismatch. A self-motion (the mismatch
    zero to :data:`HEIGHT_TOL`) gives the pairs at the grid's ``q_6`` nearest the
    reference where the elbow reaches, as the other free angles do; every change of sign
    of a pair's mismatch between neighbouring grid values (the pair followed by
    continuity, :func:`_follow`; not both values zero) is searched to its zero
    (:func:`_mismatch_zero`), an isolated branch. Writes the triples to the columns of
    ``out`` (3, 8) (rad) and returns how many.
    """
    p, ref = query.p, query.ref
    step = 2.0 * math.pi / WRIST_TRIES
    size = 0.0
    for j in range(1, 6):
        size += norm(sub(vec_at(p, j), vec_at(p, j - 1)))
    flat = HEIGHT_TOL * max(size, 1.0)
    grid = np.empty((4, 2 * (WRIST_TRIES + 1)))
    counts = np.empty(WRIST_TRIES + 1, dtype=np.int64)
    for k in range(WRIST_TRIES + 1):
        counts[k] = _pairs_at(query, ref[5] + k * step, grid, 2 * k)
    m = 0
    for j in range(WRIST_TRIES):
        k = (int(_grid_shift(j, 1.0)) + WRIST_TRIES) % WRIST_TRIES
        for c in range(2 * k, 2 * k + counts[k]):
            if abs(grid[2, c]) <= flat and grid[3, c] > 0.0 and m < out.shape[1]:
                out[0, m], out[1, m], out[2, m] = grid[0, c], grid[1, c], ref[5] + k * step
                m += 1
        if m > 0:
            break
    for k in range(WRIST_TRIES):
        for c in range(2 * k, 2 * k + counts[k]):
            e = _follow(grid, 2 * (k + 1), counts[k + 1], grid[0, c], grid[1, c])
            if e < 0 or (grid[2, c] > 0.0) == (grid[2, e] > 0.0):
                continue
            # Both ends flat: the self-motion above (its rounding changes sign at random);
            # one: a zero near that grid value, where the elbow may reach only beside it.
            if abs(grid[2, c]) <= flat and abs(grid[2, e]) <= flat:
                continue
            t6, t1, t5, g = _mismatch_zero(
                query, ref[5] + k * step, grid[2, c], ref[5] + (k + 1) * step, grid[2, e],
                grid[0, c], grid[1, c],
            )  # fmt: skip
            if abs(g) <= flat and m < out.shape[1]:
                out[0, m], out[1, m], out[2, m] = t1, t5, t6
                m += 1
    return m


@_jit
def _follow(grid: np.ndarray, col: int, count: int, t1: float, t5: float) -> int:
    """The column of ``grid[:, col:col + count]`` whose pair is nearest ``(t1, t5)``, or -1.

    Angles are compared modulo a turn; the nearest counts within :data:`FOLLOW_GAP`.
    """
    best, at = FOLLOW_GAP, -1
    for i in range(count):
        gap = abs(wrap_angle(grid[0, col + i] - t1)) + abs(wrap_angle(grid[1, col + i] - t5))
        if gap <= best:
            best, at = gap, col + i
    return at


@_jit
def _mismatch_zero(
    query: AlongQuery, a: float, ga: float, b: float, gb: float, t1: float, t5: float
) -> tuple[float, float, float, float]:
    """The zero in ``q_6`` of a pair's height mismatch, bracketed by ``a`` and ``b``.

    ``ga`` and ``gb`` (m) have opposite signs; ``(t1, t5)`` is the pair at ``a``, followed
    by continuity (:func:`_follow`). The Illinois rule (regula falsi that halves a stale
    end's value), at most :data:`ROOT_STEPS` steps. Returns ``(q_6, q_1, q_5, mismatch)``
    at the last point evaluated.
    """
    pairs = np.empty((4, 2))
    last, gc = a, ga
    side = 0
    for _ in range(ROOT_STEPS):
        c = b - gb * (b - a) / (gb - ga)
        if not (min(a, b) < c < max(a, b)):
            break  # the bracket is down to rounding
        at = _follow(pairs, 0, _pairs_at(query, c, pairs, 0), t1, t5)
        if at < 0:
            break
        last, t1, t5, gc = c, pairs[0, at], pairs[1, at], pairs[2, at]
        if gc == 0.0:
            break
        if (gc > 0.0) == (gb > 0.0):
            b, gb = c, gc
            if side == -1:
                ga *= 0.5
            side = -1
        else:
            a, ga = c, gc
            if side == 1:
                gb *= 0.5
            side = 1
    return last, t1, t5, gc


@_jit
def three_outer_candidates(query: AxesQuery, cand: np.ndarray) -> int:
    """Raw branches of the three-outer-parallel closed form into ``cand`` (>= 8, 6).

    Arguments as :func:`optik.analytic.pair_wrist.pair_wrist_candidates`. Returns
    the number of rows written (0 to 8): ``q_4``, then ``q_5``, then the elbow ``q_2``.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, z2, z3, z4, z5, z6 = six_rows(z)
    p1, p2, p3, p4, p5, p6 = six_rows(p)
    h = z1
    RG, tG = target_frame(T, M)
    C = meeting_point(z5, p5, z6, p6)
    Ct = axpy(1.0, apply(RG, C), tG)
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    across = unit(cross(h, z4))
    RGz6 = apply(RG, z6)
    n4, a1, a2 = plane_angles(z4, p4, C, h, dot(h, Ct), ref[3], roots)
    n = 0
    for i4 in range(n4):
        t4 = a1 if i4 == 0 else a2
        R4 = rotation(z4, t4)
        n5, b1, b2 = plane_angles(z5, _ORIGIN, z6, apply_t(R4, h), dot(h, RGz6), ref[4], roots)
        for i5 in range(n5):
            t5 = b1 if i5 == 0 else b2
            R45 = mul3(R4, rotation(z5, t5))
            t6 = sp1_angle(z6, apply_t(RG, h), apply_t(R45, h), ref[5], axis_tol)
            theta = _planar_rest(h, RG, mul3(R45, rotation(z6, t6)), across)
            # X = G R_6^-1 R_5^-1 R_4^-1 p_3: where axis 3's point must go.
            X = turn_point(z4, p4, -t4, p3)
            X = turn_point(z6, p6, -t6, turn_point(z5, p5, -t5, X))
            X = axpy(1.0, apply(RG, X), tG)
            d = sub(X, p1)
            n2, u1, v1, u2, v2 = reach_angles(
                z1, p1, z2, p2, p3, d, ref[0], ref[1], roots, axis_tol
            )
            for i2 in range(n2):
                t1, t2 = (u1, v1) if i2 == 0 else (u2, v2)
                t3 = dot(h, z3) * (theta - t1 - dot(h, z2) * t2)
                if n < MAX_BRANCHES:
                    t3 = math.atan2(math.sin(t3), math.cos(t3))
                    n = store_branch(cand, n, (t1, t2, t3, t4, t5, t6))
    return n


__all__ = ["three_inner_candidates", "three_outer_candidates"]
