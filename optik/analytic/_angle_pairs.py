"""The pair step of the joint-axis arms: ``M (cos a, sin a) = v0 + N (cos b, sin b)``.

Two conditions linear in the sines and cosines of two angles, ``M`` and ``N`` 2x2: the
general arm (:mod:`optik.analytic.general_arm`: the height along axis 2 and the distance
from it) and the inner kind of ``three_parallel``
(:func:`optik.analytic.three_parallel.three_inner_candidates`) reduce to it.
:func:`angle_pairs` solves it: a quartic eliminates the angle whose matrix keeps its roots
further apart (:func:`quartic_pairs`, its roots by
:func:`optik.analytic._quartic.trig2_roots`), the other angle follows from the pair;
with both matrices singular, a left null vector of one leaves one trigonometric equation
in the other angle (:func:`singular_pairs`); rows that are one equation to rounding are a
curve of pairs, a self-motion (:func:`pair_continuum`), where the reference picks a point.
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import atan2, sincos
from optik._numba import jit as _jit
from optik.analytic._quartic import trig2_roots
from optik.analytic._subproblems import RootTols, roots_or_tangent

PAIR_RANK_TOL = 1e-9
"""Both matrices of :func:`angle_pairs` count as singular when neither
:func:`root_separation` exceeds this."""
PAIR_CONTINUUM_TOL = 1e-13
"""Its system's two rows count as one equation (a curve of pairs, :func:`pair_continuum`)
when the sine of their angle is at most this: singular to rounding (about 1e-16 at an
exact self-motion). Poses 1e-10 rad off one are isolated solutions the quartic still
finds to rounding, where the curve's point at the reference misses by up to 1e-9 of the
arm's size (the FK check's tolerance)."""
QUARTIC_VANISH_TOL = 1e-12
""":func:`quartic_pairs`' quartic vanishes identically when its largest coefficient is at
most this times the products it sums (they cancel to rounding)."""
PAIR_RESIDUAL_TOL = 1e-5
"""With both matrices singular, a quartic's pair solves the system when it does so to
this, relative to the coefficients (the FK check's Newton steps mend the rest:
:data:`optik.analytic._row_steps.NEAR_MISS`)."""
PAIR_LOOSE_TOL = 1e-3
"""...and nearly solves it to this (kept after those that solve it)."""
_TINY = 1e-300
Mat2 = tuple[float, float, float, float]
"""A 2x2 matrix ``((m0, m1), (m2, m3))``, row-major, in scalars."""
Vec2 = tuple[float, float]


@_jit
def root_separation(M: Mat2, v0: Vec2, N: Mat2) -> float:
    """How far apart the roots of :func:`quartic_pairs` stay: ``|det M| / (|M| (|v0| + |N|))``.

    At a root ``|adj(M) (v0 + N u)| = |det M|``; the smaller this ratio, the closer the
    quartic comes to a double root there (its value squared is what separates them).
    """
    adj = math.sqrt(M[0] * M[0] + M[1] * M[1] + M[2] * M[2] + M[3] * M[3])
    n2 = N[0] * N[0] + N[1] * N[1] + N[2] * N[2] + N[3] * N[3]
    rest = math.sqrt(_dot2(v0, v0)) + math.sqrt(n2)
    return abs(M[0] * M[3] - M[1] * M[2]) / max(adj * rest, _TINY)


@_jit
def quartic_pairs(
    M: Mat2, v0: Vec2, N: Mat2, trig_tol: float, free: float, angles: np.ndarray
) -> int:
    """The angle pairs ``(b, a)`` of ``M (cos a, sin a) = v0 + N (cos b, sin b)``.

    The roots ``b`` of ``|adj(M) (v0 + N u_b)|^2 = det(M)^2`` go to ``angles[0]``
    (ascending), each ``a`` (the angle of ``adj(M) (v0 + N u_b)`` times the sign of
    ``det M``) to ``angles[1]``. Returns the count (0 to 4). The quartic vanishing
    identically (:func:`quartic_vanishes`: the two conditions share a curve), every ``b``
    is a root: ``free`` and half a turn from it (rad), with their partners.
    """
    k = np.empty(5)
    det, m0, m1, m2, terms = _quartic(M, v0, N, k)
    if _vanishing(k, terms):
        angles[0, 0] = atan2(math.sin(free), math.cos(free))
        angles[0, 1] = atan2(-math.sin(free), -math.cos(free))
        count = 2
    else:
        count = trig2_roots(k, trig_tol, angles[0])
    sign = 1.0 if det >= 0.0 else -1.0
    for i in range(count):
        s, c = sincos(angles[0, i])
        w = (m0[0] + m1[0] * c + m2[0] * s, m0[1] + m1[1] * c + m2[1] * s)
        angles[1, i] = atan2(sign * w[1], sign * w[0])
    return count


@_jit
def _quartic(M: Mat2, v0: Vec2, N: Mat2, k: np.ndarray) -> tuple[float, Vec2, Vec2, Vec2, float]:
    """The coefficients ``k`` (5,) of :func:`quartic_pairs`' quartic in ``b``.

    Returns ``(det M, adj(M) v0, adj(M) N_1, adj(M) N_2, terms)``, ``terms`` the size of
    the products the coefficients sum (what they cancel against).
    """
    det = M[0] * M[3] - M[1] * M[2]
    m0 = _adj(M, v0)
    m1 = _adj(M, (N[0], N[2]))
    m2 = _adj(M, (N[1], N[3]))
    k[0] = 0.5 * (_dot2(m1, m1) + _dot2(m2, m2)) + _dot2(m0, m0) - det * det
    k[1] = 2.0 * _dot2(m0, m1)
    k[2] = 2.0 * _dot2(m0, m2)
    k[3] = 0.5 * (_dot2(m1, m1) - _dot2(m2, m2))
    k[4] = _dot2(m1, m2)
    terms = 0.5 * (_dot2(m1, m1) + _dot2(m2, m2)) + _dot2(m0, m0) + det * det
    return det, m0, m1, m2, terms


@_jit
def _vanishing(k: np.ndarray, terms: float) -> bool:
    """Whether the quartic's coefficients ``k`` cancel to rounding against ``terms``."""
    largest = 0.0
    for i in range(5):
        largest = max(largest, abs(k[i]))
    return terms > 0.0 and largest <= QUARTIC_VANISH_TOL * terms


@_jit
def quartic_vanishes(M: Mat2, v0: Vec2, N: Mat2) -> bool:
    """Whether :func:`quartic_pairs`' quartic vanishes identically either way round.

    The two conditions of ``M u_a = v0 + N u_b`` then share a curve of pairs (a
    self-motion) though their rows are not proportional: axes that turn about one line.
    """
    k = np.empty(5)
    terms = _quartic(M, v0, N, k)[4]
    if _vanishing(k, terms):
        return True
    terms = _quartic(N, (-v0[0], -v0[1]), M, k)[4]
    return _vanishing(k, terms)


@_jit
def angle_pairs(
    M: Mat2, v0: Vec2, N: Mat2, ref_a: float, ref_b: float, roots: RootTols, angles: np.ndarray
) -> int:
    """The angle pairs of ``M (cos a, sin a) = v0 + N (cos b, sin b)``, coefficients of order 1.

    ``a`` goes to ``angles[0]``, ``b`` to ``angles[1]`` (``angles`` (2, >= 4)); returns
    the count (0 to 4). The quartic of :func:`quartic_pairs` eliminates the angle whose
    matrix keeps its roots further apart (:func:`root_separation`). With both matrices
    singular, its pairs that solve the system, then those that nearly do; none solving
    it, also :func:`singular_pairs`; the system one equation (a curve),
    :func:`singular_pairs` alone. ``ref_a``, ``ref_b`` (rad): the reference for an angle
    a singularity leaves free; ``roots`` as
    :func:`optik.analytic._subproblems.roots_or_tangent`'s.
    """
    minus_v0 = (-v0[0], -v0[1])
    keep_a = root_separation(N, minus_v0, M)
    keep_b = root_separation(M, v0, N)
    singular = not max(keep_a, keep_b) > PAIR_RANK_TOL
    sine = pair_sine(M, v0, N) if singular else 1.0
    if not sine > PAIR_CONTINUUM_TOL:  # one equation: pair_continuum, its sine computed once
        return singular_pairs(M, v0, N, ref_a, ref_b, roots, angles)  # the reference's point
    if keep_a > keep_b:
        count = quartic_pairs(N, minus_v0, M, roots[0], ref_a, angles)  # roots a, partners b
    else:
        count = quartic_pairs(M, v0, N, roots[0], ref_b, angles)  # roots b, partners a
        for i in range(count):
            angles[0, i], angles[1, i] = angles[1, i], angles[0, i]
    if not singular:
        return count
    # Both matrices singular: a partner is the angle of a vector that vanishes, rounding
    # decides it. The pairs that solve the system, then those that nearly do (the FK
    # check's Newton steps judge them). None solving it, also the system solved directly:
    # first where its rows are independent (exact there), after the others where they are
    # nearly one equation (its elimination then rests on their near-zero difference).
    scale = _norm4(M) + _norm4(N) + math.sqrt(_dot2(v0, v0))
    loose = np.empty((2, 4))
    good, near = 0, 0
    for i in range(count):
        a, b = angles[0, i], angles[1, i]
        miss = _pair_miss(M, v0, N, a, b)
        if miss <= PAIR_RESIDUAL_TOL * scale:
            angles[0, good], angles[1, good] = a, b
            good += 1
        elif miss <= PAIR_LOOSE_TOL * scale:
            loose[0, near], loose[1, near] = a, b
            near += 1
    direct = np.empty((2, 4))
    found = 0
    if good == 0:
        found = singular_pairs(M, v0, N, ref_a, ref_b, roots, direct)
    direct_first = sine > PAIR_RANK_TOL
    kept = good
    if direct_first:
        kept = _append_pairs(angles, kept, direct, found)
    kept = _append_pairs(angles, kept, loose, near)
    if not direct_first:
        kept = _append_pairs(angles, kept, direct, found)
    return kept


@_jit
def _append_pairs(angles: np.ndarray, kept: int, extra: np.ndarray, count: int) -> int:
    """``extra``'s first ``count`` pairs after ``angles``' first ``kept``: the new count.

    Up to 4 pairs in all (the callers' 8 rows, two per pair).
    """
    n = min(count, 4 - kept)
    for i in range(n):
        angles[0, kept + i], angles[1, kept + i] = extra[0, i], extra[1, i]
    return kept + n


@_jit
def _pair_miss(M: Mat2, v0: Vec2, N: Mat2, a: float, b: float) -> float:
    """``|M u_a - v0 - N u_b|`` (max norm) of the pair ``(a, b)`` (rad)."""
    sa, ca = sincos(a)
    sb, cb = sincos(b)
    e0 = M[0] * ca + M[1] * sa - v0[0] - N[0] * cb - N[1] * sb
    e1 = M[2] * ca + M[3] * sa - v0[1] - N[2] * cb - N[3] * sb
    return max(abs(e0), abs(e1))


@_jit
def singular_pairs(
    M: Mat2, v0: Vec2, N: Mat2, ref_a: float, ref_b: float, roots: RootTols, angles: np.ndarray
) -> int:
    """:func:`angle_pairs` when neither ``M`` nor ``N`` is regular (no quartic).

    The rows ``(M_i, -N_i, -v0_i)`` of the system proportional (one equation, a curve of
    pairs: a self-motion): ``a`` takes ``ref_a`` (:func:`_one_equation`). Otherwise a
    left null vector ``l`` of one matrix, ``l^T M = 0`` say, leaves one equation in the
    other angle, ``l^T N u_b = -l^T v0`` (up to two ``b``), and each ``b`` one row of ``M``
    (up to two ``a``): up to 4 pairs, the better conditioned of the two eliminations.
    """
    if pair_continuum(M, v0, N):
        r0 = (M[0], M[1], -N[0], -N[1], -v0[0])
        r1 = (M[2], M[3], -N[2], -N[3], -v0[1])
        row = r0 if _norm5(r0) >= _norm5(r1) else r1
        return _one_equation(
            (row[0], row[1]), (-row[2], -row[3]), -row[4], ref_a, ref_b, roots, angles
        )
    lm, ln = _left_null(M), _left_null(N)
    lm_n = (lm[0] * N[0] + lm[1] * N[2], lm[0] * N[1] + lm[1] * N[3])
    ln_m = (ln[0] * M[0] + ln[1] * M[2], ln[0] * M[1] + ln[1] * M[3])
    if _dot2(lm_n, lm_n) >= _dot2(ln_m, ln_m):
        # b from l^T N u_b = -l^T v0, then a from M's larger row.
        return _eliminated(lm_n, -_dot2(lm, v0), M, v0, N, ref_a, ref_b, roots, angles, 1)
    # a from l^T M u_a = l^T v0, then b from N's larger row (N u_b = -v0 + M u_a).
    minus_v0 = (-v0[0], -v0[1])
    return _eliminated(ln_m, _dot2(ln, v0), N, minus_v0, M, ref_b, ref_a, roots, angles, 0)


@_jit
def pair_continuum(M: Mat2, v0: Vec2, N: Mat2) -> bool:
    """Whether the two rows of :func:`angle_pairs`' system are one equation (a curve of pairs).

    Their :func:`pair_sine` at most :data:`PAIR_CONTINUUM_TOL`.
    """
    return not pair_sine(M, v0, N) > PAIR_CONTINUUM_TOL


@_jit
def pair_sine(M: Mat2, v0: Vec2, N: Mat2) -> float:
    """The sine of the angle between the two rows of :func:`angle_pairs`' system.

    The rows ``(M_i, -N_i, -v0_i)``, from their 2x2 minors; 0 where a row vanishes.
    """
    r0 = (M[0], M[1], -N[0], -N[1], -v0[0])
    r1 = (M[2], M[3], -N[2], -N[3], -v0[1])
    wedge = 0.0
    for i in range(5):
        for j in range(i + 1, 5):
            minor = r0[i] * r1[j] - r0[j] * r1[i]
            wedge += minor * minor
    lengths = _norm5(r0) * _norm5(r1)
    if not lengths > 0.0:
        return 0.0
    return math.sqrt(wedge) / lengths


@_jit
def _eliminated(
    k: Vec2,
    c: float,
    P: Mat2,
    w0: Vec2,
    Q: Mat2,
    ref_p: float,
    ref_q: float,
    roots: RootTols,
    angles: np.ndarray,
    row_q: int,
) -> int:
    """Pairs of ``P u_p = w0 + Q u_q`` given ``k . u_q = c`` (``P`` singular, rank 1).

    Each root ``q`` of ``k . u_q = c``, then the roots ``p`` of ``P``'s larger row. ``q``
    goes to ``angles[row_q]``, ``p`` to the other row.
    """
    count, q1, q2 = _scaled_roots(k, c, ref_q, roots)
    row = 0 if P[0] * P[0] + P[1] * P[1] >= P[2] * P[2] + P[3] * P[3] else 1
    pk = (P[2 * row], P[2 * row + 1])
    n = 0
    for i in range(count):
        q = q1 if i == 0 else q2
        s, co = sincos(q)
        rhs = w0[row] + Q[2 * row] * co + Q[2 * row + 1] * s
        found, p1, p2 = _scaled_roots(pk, rhs, ref_p, roots)
        for j in range(found):
            angles[row_q, n] = q
            angles[1 - row_q, n] = p1 if j == 0 else p2
            n += 1
    return n


@_jit
def _one_equation(
    m: Vec2, n: Vec2, c: float, ref_a: float, ref_b: float, roots: RootTols, angles: np.ndarray
) -> int:
    """Pairs of ``m . u_a = c + n . u_b`` (a curve): ``a = ref_a`` where it can be.

    ``a = ref_a`` and its ``b`` roots; where ``n . u_b`` cannot reach ``m . u_a - c`` there,
    ``b`` at the nearest extreme of ``n . u_b`` (``ref_b`` if ``n`` vanishes) and the
    ``a`` roots for it. Pairs into ``angles`` as :func:`angle_pairs`.
    """
    s, co = sincos(ref_a)
    count, b1, b2 = _scaled_roots(n, m[0] * co + m[1] * s - c, ref_b, roots)
    if count > 0:
        angles[0, 0], angles[1, 0] = ref_a, b1
        angles[0, 1], angles[1, 1] = ref_a, b2
        return count
    if _dot2(n, n) > 0.0:
        b = atan2(n[1], n[0])
        if m[0] * co + m[1] * s - c < 0.0:
            b = atan2(-n[1], -n[0])
    else:
        b = ref_b
    s, co = sincos(b)
    count, a1, a2 = _scaled_roots(m, c + n[0] * co + n[1] * s, ref_a, roots)
    angles[0, 0], angles[1, 0] = a1, b
    angles[0, 1], angles[1, 1] = a2, b
    return count


@_jit
def _scaled_roots(k: Vec2, c: float, ref: float, roots: RootTols) -> tuple[int, float, float]:
    """:func:`optik.analytic._subproblems.roots_or_tangent` of ``k . (cos t, sin t) = c``.

    Divided by ``|k| + |c|`` first (coefficients of order 1); all zero: ``t`` free, ``ref``.
    """
    scale = math.sqrt(_dot2(k, k)) + abs(c)
    if not scale > 0.0:
        return 1, ref, ref
    return roots_or_tangent(k[0] / scale, k[1] / scale, c / scale, ref, roots)


@_jit
def _left_null(M: Mat2) -> Vec2:
    """A unit ``l`` with ``l^T M`` as small as it gets for a rank-1 ``M`` ((0, 0) for ``M = 0``).

    Of the two normals ``(-m2, m0)`` and ``(-m3, m1)`` to ``M``'s columns, the longer.
    """
    a = (-M[2], M[0])
    b = (-M[3], M[1])
    if _dot2(b, b) > _dot2(a, a):
        a = b
    length = math.sqrt(_dot2(a, a))
    if not length > 0.0:
        return (0.0, 0.0)
    return (a[0] / length, a[1] / length)


@_jit
def _norm4(m: Mat2) -> float:
    return math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2] + m[3] * m[3])


@_jit
def _norm5(r: tuple[float, float, float, float, float]) -> float:
    return math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3] + r[4] * r[4])


@_jit
def _adj(A: Mat2, b: Vec2) -> Vec2:
    """``adj(A) b`` for ``A = ((A0, A1), (A2, A3))``."""
    return (A[3] * b[0] - A[1] * b[1], A[0] * b[1] - A[2] * b[0])


@_jit
def _dot2(a: Vec2, b: Vec2) -> float:
    return a[0] * b[0] + a[1] * b[1]


__all__ = [
    "PAIR_CONTINUUM_TOL",
    "PAIR_LOOSE_TOL",
    "PAIR_RANK_TOL",
    "PAIR_RESIDUAL_TOL",
    "QUARTIC_VANISH_TOL",
    "Mat2",
    "Vec2",
    "angle_pairs",
    "pair_continuum",
    "pair_sine",
    "quartic_pairs",
    "quartic_vanishes",
    "root_separation",
    "singular_pairs",
]
