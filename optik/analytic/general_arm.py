"""Six revolute axes: a spherical wrist after a general arm, by one quartic (from the axes).

The structure (in the product of exponentials of the joint axes at ``q = 0``,
:func:`optik.analytic.geometry.joint_axes`: ``fk(q) = R_1(q_1) ... R_6(q_6) M``): axes
4, 5 and 6 meet at the wrist centre ``W``, and the arm's axes have none of the relations
the other arm kinds use — axes 1 and 2 neither meet nor are parallel, nor do axes 2 and 3
— and axis 3 misses ``W`` (EAIK's "spherical, no parallel, no intersecting"; axes 2 and
3 meeting take :func:`optik.analytic.pair_wrist.second_pair_candidates`).
Pieper's problem: with ``G = T M^-1`` and the wrist centre's target ``W_t = G W``,

``R_2(q_2) X(q_3) = Y(q_1)``, ``X(q_3) = R_3(q_3) W``, ``Y(q_1) = R_1(-q_1) W_t``:

both points run on circles (``X = x_0 + x_c cos q_3 + x_s sin q_3``, ``Y`` alike), and
``R_2`` turns one onto the other exactly when they have the same height along axis 2 and
the same distance from its point ``p_2``. Both conditions are linear in ``u_1 = (cos
q_1, sin q_1)`` and in ``u_3 = (cos q_3, sin q_3)``: ``A u_1 = b_0 + B u_3`` with 2x2
matrices ``A`` (of the target) and ``B`` (of the arm). Eliminating ``q_1`` without
dividing, ``|adj(A) (b_0 + B u_3)|^2 = det(A)^2``, leaves a trig polynomial of degree 2
in ``q_3``, that is a quartic: its real roots by certified subdivision and Newton's
method (:func:`sampled_roots`), or, where a root may hide (a near-double one), the
eigenvalues of the companion matrix of ``z^2 f`` in ``z = e^{i q_3}`` that lie on the
unit circle (:func:`trig2_roots`); then ``q_1`` is the angle of ``adj(A) (b_0 + B u_3)`` times
the sign of ``det A``. Near axis 1 ``A`` shrinks and that quartic's roots pair up (their
gap is ``det A``, squared), so there ``q_3`` is eliminated instead (``B`` stays regular
when axes 2 and 3 are skew): whichever keeps the roots further apart
(:func:`root_separation`). Then ``q_2`` turns ``X`` onto ``Y`` (subproblem 1), and the
wrist follows as in :func:`optik.analytic.pair_wrist.wrist_branches`.

Up to 4 x 2 = 8 branches, the quartic's angle ascending, then the wrist; each is
refined by one Newton step on the robot's chain and checked by FK in the
post-processing. At a singularity a free angle takes the reference: ``q_1`` with ``W_t`` on
axis 1 (then ``q_3`` puts ``X`` at ``W_t``'s height along axis 2; ``det A`` vanishes
there and only there), the wrist's ``q_4`` with axes 4 and 6 aligned.
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import sincos, trig_roots
from optik._numba import jit as _jit
from optik.analytic._compiled import closed_form_tols, mul3
from optik.analytic._subproblems import (
    RootTols,
    Rot9,
    Vec3,
    circle,
    dot,
    plane_angles,
    roots_or_tangent,
    rotation,
    sp1_angle,
    sub,
    turn_point,
    vec_at,
)
from optik.analytic.pair_wrist import (
    REACH_TOL,
    AxesQuery,
    wrist_across,
    wrist_branches,
    wrist_target,
)

CIRCLE_TOL = 1e-6
"""A companion eigenvalue within this of the unit circle (``| |z| - 1 |``) is a root
``q_3 = arg z``: a double root (a stretched or folded arm) splits into a pair about
``sqrt(eps)`` off the circle, which this keeps; a root kept wrongly gives a branch the
FK check rejects."""
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
:data:`optik.analytic._pipeline.NEAR_MISS`)."""
PAIR_LOOSE_TOL = 1e-3
"""...and nearly solves it to this (kept after those that solve it)."""
_NEWTON_STEPS = 3
_TINY = 1e-300
_PIECES = 16
"""Intervals the turn is cut into before :func:`sampled_roots` halves the undecided."""
_STACK = 96
_ROOT_FREE, _ONE_ROOT, _UNDECIDED = 0, 1, 2
"""The verdicts of :func:`_verdict` on an interval."""


def _grid(pieces: int) -> np.ndarray:
    """``cos t, sin t, cos 2t, sin 2t`` (2 pieces + 1, 4) at ``t = -pi + i pi / pieces``.

    The ends and middles of :func:`sampled_roots`' first intervals, ``i = 0 .. 2 pieces``.
    """
    t = -math.pi + np.arange(2 * pieces + 1) * (math.pi / pieces)
    grid = np.stack([np.cos(t), np.sin(t), np.cos(2.0 * t), np.sin(2.0 * t)], axis=1)
    grid.flags.writeable = False
    return grid


_GRID = _grid(_PIECES)
Mat2 = tuple[float, float, float, float]
"""A 2x2 matrix ``((m0, m1), (m2, m3))``, row-major, in scalars."""
Vec2 = tuple[float, float]


@_jit
def trig2_roots(k: np.ndarray, trig_tol: float, out: np.ndarray) -> int:
    """Real roots ``t`` (rad) of ``k0 + k1 cos t + k2 sin t + k3 cos 2t + k4 sin 2t = 0``.

    ``k`` (5,), scaled by the caller to order 1; up to four roots go to ``out`` (>= 4,),
    ascending, in ``(-pi, pi]``. All zero (every ``t`` a root, a self-motion): none, and
    the caller's numeric fallback judges. The second harmonic negligible (``|k3|, |k4| <=
    1e-14 max|k|``): the first-degree equation's roots (:func:`optik._math.trig_roots`
    with ``trig_tol``, no free rule). Otherwise :func:`sampled_roots`, and where it cannot
    decide (a root within rounding of a sample, or a near-double one) the eigenvalues
    ``z`` of the companion matrix of ``z^2 f(t)``, ``z = e^{it}`` (a quartic), within
    :data:`CIRCLE_TOL` of the unit circle, each polished by Newton's method on ``f`` (a
    step is kept only when it lowers ``|f|``). Returns the count.
    """
    scale = 0.0
    for i in range(5):
        scale = max(scale, abs(k[i]))
    if not scale > 0.0:
        return 0
    if abs(k[3]) <= 1e-14 * scale and abs(k[4]) <= 1e-14 * scale:
        n, t1, t2 = trig_roots(k[1], k[2], -k[0], 0.0, trig_tol, -1.0, 0.0)
        out[0] = t1
        out[1] = t2
        return n
    n = sampled_roots(k, out)
    if n >= 0:
        return n
    # A root a hair from a sample or a near-double one: the eigenvalues decide.
    # z^2 f = a4 z^4 + a3 z^3 + a2 z^2 + conj(a3) z + conj(a4).
    a4 = complex(0.5 * k[3], -0.5 * k[4])
    a3 = complex(0.5 * k[1], -0.5 * k[2])
    coeffs = (a3 / a4, complex(k[0], 0.0) / a4, a3.conjugate() / a4, a4.conjugate() / a4)
    companion = np.zeros((4, 4), dtype=np.complex128)
    for i in range(4):
        companion[0, i] = -coeffs[i]
    for i in range(3):
        companion[i + 1, i] = 1.0
    n = 0
    for z in np.linalg.eigvals(companion):
        if abs(abs(z) - 1.0) > CIRCLE_TOL:
            continue
        t = _polished(k, math.atan2(z.imag, z.real))
        at = n
        while at > 0 and out[at - 1] > t:  # insertion: ascending
            out[at] = out[at - 1]
            at -= 1
        out[at] = t
        n += 1
    return n


@_jit
def sampled_roots(k: np.ndarray, out: np.ndarray) -> int:
    """The roots of :func:`trig2_roots`' ``f`` by certified subdivision, or -1.

    The turn is cut into :data:`_PIECES` intervals; each is proven root-free (``|f(m)| >
    |f'(m)| w/2 + L2 w^2/8`` at its middle ``m``, ``w`` its width, ``L2 = |k1| + |k2| +
    4 (|k3| + |k4|)`` a bound on ``|f''|``), or to hold exactly one root (a sign change
    with ``|f'(m)| > L2 w/2``: ``f`` monotone), which a safeguarded Newton iteration
    from ``m`` finds to rounding; otherwise it is halved. -1 (the caller takes the
    eigenvalues) when a sample is within rounding of zero or an interval narrower than
    1e-6 rad is still undecided (a near-double root). Roots ascending in ``(-pi, pi)``.
    The first intervals' ends and middles are fixed angles: their sines and cosines come
    from :data:`_GRID`.
    """
    s1 = abs(k[1]) + abs(k[2])
    s2 = abs(k[3]) + abs(k[4])
    bound2 = s1 + 4.0 * s2
    slack = 1e-13 * (abs(k[0]) + s1 + s2)
    width = 2.0 * math.pi / _PIECES
    n = 0
    fb = _grid_value(k, 0)[0]
    for i in range(_PIECES):
        fa = fb
        fb = _grid_value(k, 2 * i + 2)[0]
        if not (abs(fa) > slack and abs(fb) > slack):
            return -1
        fm, dm = _grid_value(k, 2 * i + 1)
        a = -math.pi + i * width
        verdict = _verdict(fa, fb, fm, dm, width, bound2, slack)
        if verdict == _ROOT_FREE:
            continue
        if verdict == _ONE_ROOT:
            if n == 4:
                return -1
            out[n] = _bracketed_root(k, a, a + width, fa, a + 0.5 * width, fm, dm)
            n += 1
            continue
        n = _halved_roots(k, a, a + width, fa, fb, bound2, slack, out, n)
        if n < 0:
            return -1
    return n


@_jit
def _verdict(
    fa: float, fb: float, fm: float, dm: float, w: float, bound2: float, slack: float
) -> int:
    """Whether ``f`` has no root, exactly one, or perhaps more in an interval (a verdict).

    ``fa``, ``fb``: ``f`` at its ends; ``fm``, ``dm``: ``f`` and ``f'`` at its middle;
    ``w`` its width (rad); ``bound2 >= |f''|``; ``slack``: rounding of ``f``.
    """
    if (fa > 0.0) == (fb > 0.0):
        if abs(fm) - 0.5 * w * abs(dm) - 0.125 * w * w * bound2 > slack:
            return _ROOT_FREE
    elif abs(dm) > 0.5 * w * bound2:
        return _ONE_ROOT
    return _UNDECIDED


@_jit
def _halved_roots(
    k: np.ndarray,
    a: float,
    b: float,
    fa: float,
    fb: float,
    bound2: float,
    slack: float,
    out: np.ndarray,
    n: int,
) -> int:
    """:func:`sampled_roots` on ``[a, b]`` by halving.

    Its roots go after ``out[:n]``; returns the new count, or -1 (undecided).
    """
    stack = np.empty((_STACK, 4))
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = a, b, fa, fb
    top = 1
    while top > 0:
        top -= 1
        a, b, fa, fb = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        if not (abs(fa) > slack and abs(fb) > slack):
            return -1
        w = b - a
        m = 0.5 * (a + b)
        fm, dm = _trig2(k, m)
        verdict = _verdict(fa, fb, fm, dm, w, bound2, slack)
        if verdict == _ROOT_FREE:
            continue
        if verdict == _ONE_ROOT:
            if n == 4:
                return -1
            out[n] = _bracketed_root(k, a, b, fa, m, fm, dm)
            n += 1
            continue
        if w < 1e-6 or top + 2 > _STACK:
            return -1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = m, b, fm, fb
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = a, m, fa, fm
        top += 2
    return n


@_jit
def _bracketed_root(
    k: np.ndarray, a: float, b: float, fa: float, t: float, f: float, df: float
) -> float:
    """The root of ``f`` in ``[a, b]`` (a sign change there, ``f`` monotone).

    Newton's method from ``t`` inside (``f``, ``df`` its value and slope there),
    bisecting whenever a step leaves the bracket, to rounding.
    """
    for _ in range(100):
        if f == 0.0:
            return t
        if (f > 0.0) == (fa > 0.0):
            a = t
        else:
            b = t
        rounding = 4e-16 * max(1.0, abs(t))
        if b - a <= rounding:
            return t
        step = t - f / df if df != 0.0 else 0.5 * (a + b)
        if abs(step - t) <= rounding:
            # At rounding; tested before the bracket, which a step that rounds to
            # ``t`` (now one of its ends) would leave, bisecting on for nothing.
            return step if a <= step <= b else t
        if not (a < step < b):
            step = 0.5 * (a + b)
        t = step
        f, df = _trig2(k, t)
    return t


@_jit
def _grid_value(k: np.ndarray, i: int) -> tuple[float, float]:
    """``f`` and ``f'`` of :func:`trig2_roots` at the grid angle ``i`` (:data:`_GRID`)."""
    c, s, c2, s2 = _GRID[i, 0], _GRID[i, 1], _GRID[i, 2], _GRID[i, 3]
    f = k[0] + k[1] * c + k[2] * s + k[3] * c2 + k[4] * s2
    df = -k[1] * s + k[2] * c - 2.0 * k[3] * s2 + 2.0 * k[4] * c2
    return f, df


@_jit
def _trig2(k: np.ndarray, t: float) -> tuple[float, float]:
    """``f(t)`` of :func:`trig2_roots` and its derivative."""
    s, c = sincos(t)
    s2, c2 = 2.0 * s * c, c * c - s * s
    f = k[0] + k[1] * c + k[2] * s + k[3] * c2 + k[4] * s2
    df = -k[1] * s + k[2] * c - 2.0 * k[3] * s2 + 2.0 * k[4] * c2
    return f, df


@_jit
def _polished(k: np.ndarray, t: float) -> float:
    """``t`` after up to :data:`_NEWTON_STEPS` Newton steps on ``f``, each lowering ``|f|``."""
    f, df = _trig2(k, t)
    for _ in range(_NEWTON_STEPS):
        if not abs(df) > _TINY or f == 0.0:
            break
        step = t - f / df
        f_new, df_new = _trig2(k, step)
        if not abs(f_new) < abs(f):
            break
        t, f, df = step, f_new, df_new
    return math.atan2(math.sin(t), math.cos(t))


@_jit
def general_arm_candidates(query: AxesQuery, cand: np.ndarray) -> int:
    """Raw branches of the general arm and spherical wrist into ``cand`` (>= 8, 6).

    Arguments as :func:`optik.analytic.pair_wrist.pair_wrist_candidates`. Returns the
    number of rows written (0 to 8), in the order of the module docstring.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    p1, p2, p3 = vec_at(p, 0), vec_at(p, 1), vec_at(p, 2)
    W, Wt, RG = wrist_target(z, p, T, M)
    across = wrist_across(z)
    back = (-z1[0], -z1[1], -z1[2])  # R_1(q)^-1 turns by q about -z1
    x0, xc, xs = circle(z3, p3, W)
    y0, yc, ys = circle(back, p1, Wt)
    dx, dy = sub(x0, p2), sub(y0, p2)
    size = max(math.sqrt(dot(dx, dx) + dot(xc, xc)), math.sqrt(dot(dy, dy) + dot(yc, yc)))
    n = 0
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    if not math.sqrt(dot(yc, yc)) > axis_tol * size:
        # W_t on axis 1: q_1 free; X must reach W_t's height along axis 2.
        count, e1, e2 = plane_angles(z3, p3, W, z2, dot(z2, Wt), ref[2], roots)
        for i3 in range(count):
            t3 = e1 if i3 == 0 else e2
            n = _branch(z, p, RG, W, Wt, ref[0], t3, across, ref, tols, cand, n)
        return n
    # The height (row 1, / size) and squared distance (row 2, / size^2) conditions:
    # A (cos q_1, sin q_1) = b0 + B (cos q_3, sin q_3), B's columns b1, b2.
    inv, inv2 = 1.0 / size, 1.0 / (size * size)
    A = (dot(z2, yc) * inv, dot(z2, ys) * inv, 2.0 * dot(dy, yc) * inv2, 2.0 * dot(dy, ys) * inv2)
    spread = dot(dx, dx) + dot(xc, xc) - dot(dy, dy) - dot(yc, yc)
    b0 = (dot(z2, sub(x0, y0)) * inv, spread * inv2)
    B = (dot(z2, xc) * inv, dot(z2, xs) * inv, 2.0 * dot(dx, xc) * inv2, 2.0 * dot(dx, xs) * inv2)
    angles = np.empty((2, 4))
    # The quartic eliminates the angle whose matrix keeps its roots apart: near axis 1 (A
    # small) q_3's quartic has near-double roots, q_1's (B constant, regular when axes 2
    # and 3 are skew) does not.
    count = angle_pairs(A, b0, B, ref[0], ref[2], roots, angles)
    for i in range(count):
        n = _branch(z, p, RG, W, Wt, angles[0, i], angles[1, i], across, ref, tols, cand, n)
    return n


@_jit
def _branch(
    z: np.ndarray,
    p: np.ndarray,
    RG: Rot9,
    W: Vec3,
    Wt: Vec3,
    t1: float,
    t3: float,
    across: Vec3,
    ref: np.ndarray,
    tols: np.ndarray,
    cand: np.ndarray,
    n: int,
) -> int:
    """``q_2`` turning ``X(q_3)`` onto ``Y(q_1)`` about axis 2, then the wrist's rows.

    ``W`` is the wrist centre, ``W_t`` its target (:func:`optik.analytic.pair_wrist.wrist_target`).
    """
    axis_tol = closed_form_tols(tols)[3]
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    p1, p2, p3 = vec_at(p, 0), vec_at(p, 1), vec_at(p, 2)
    X = turn_point(z3, p3, t3, W)
    Y = turn_point(z1, p1, -t1, Wt)
    t2 = sp1_angle(z2, sub(X, p2), sub(Y, p2), ref[1], axis_tol)
    R123 = mul3(mul3(rotation(z1, t1), rotation(z2, t2)), rotation(z3, t3))
    return wrist_branches(z, RG, R123, (t1, t2, t3), across, ref, tols, cand, n)


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
        angles[0, 0] = math.atan2(math.sin(free), math.cos(free))
        angles[0, 1] = math.atan2(-math.sin(free), -math.cos(free))
        count = 2
    else:
        count = trig2_roots(k, trig_tol, angles[0])
    sign = 1.0 if det >= 0.0 else -1.0
    for i in range(count):
        s, c = sincos(angles[0, i])
        w = (m0[0] + m1[0] * c + m2[0] * s, m0[1] + m1[1] * c + m2[1] * s)
        angles[1, i] = math.atan2(sign * w[1], sign * w[0])
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
    if singular and pair_continuum(M, v0, N):
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
    direct_first = pair_sine(M, v0, N) > PAIR_RANK_TOL
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
        b = math.atan2(n[1], n[0])
        if m[0] * co + m[1] * s - c < 0.0:
            b = math.atan2(-n[1], -n[0])
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
    "CIRCLE_TOL",
    "PAIR_CONTINUUM_TOL",
    "PAIR_RANK_TOL",
    "angle_pairs",
    "general_arm_candidates",
    "pair_continuum",
    "pair_sine",
    "quartic_pairs",
    "quartic_vanishes",
    "root_separation",
    "sampled_roots",
    "singular_pairs",
    "trig2_roots",
]
