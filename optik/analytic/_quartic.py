"""Real roots of a trigonometric polynomial of degree 2 (a quartic in ``e^{it}``).

``f(t) = k0 + k1 cos t + k2 sin t + k3 cos 2t + k4 sin 2t``: :func:`trig2_roots` finds its
real roots by certified subdivision (:func:`sampled_roots`), or, where a root may hide
(one within rounding of a sample, a near-double one), from the eigenvalues of the
companion matrix of ``z^2 f`` in ``z = e^{it}`` that lie on the unit circle. The pair step
of the joint-axis arms (:func:`optik.analytic._angle_pairs.quartic_pairs`) eliminates one
angle into such a polynomial.
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import sincos, trig_roots
from optik._numba import inline as _inline
from optik._numba import jit as _jit

CIRCLE_TOL = 1e-6
"""A companion eigenvalue within this of the unit circle (``| |z| - 1 |``) is a root
``q_3 = arg z``: a double root (a stretched or folded arm) splits into a pair about
``sqrt(eps)`` off the circle, which this keeps; a root kept wrongly gives a branch the
FK check rejects."""
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
        if verdict == _ONE_ROOT:
            n = _one_root(k, a, a + width, fa, a + 0.5 * width, fm, dm, out, n)
        elif verdict == _UNDECIDED:
            n = _halved_roots(k, a, a + width, fa, fb, bound2, slack, out, n)
        if n < 0:
            return -1
    return n


@_inline
def _one_root(
    k: np.ndarray,
    a: float,
    b: float,
    fa: float,
    m: float,
    fm: float,
    dm: float,
    out: np.ndarray,
    n: int,
) -> int:
    """The one root of ``[a, b]`` into ``out[n]``: ``n + 1``, or -1 for a fifth root.

    ``fa``: ``f(a)``; ``fm``, ``dm``: ``f`` and ``f'`` at ``m``, where the search starts.
    A quartic has four roots: a fifth is rounding, which the caller leaves to the
    eigenvalues.
    """
    if n == 4:
        return -1
    out[n] = _bracketed_root(k, a, b, fa, m, fm, dm)
    return n + 1


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
        if verdict == _ONE_ROOT:
            n = _one_root(k, a, b, fa, m, fm, dm, out, n)
            if n < 0:
                return -1
        elif verdict == _UNDECIDED:
            if w < 1e-6 or top + 2 > _STACK:
                return -1
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = m, b, fm, fb
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = a, m, fa
            stack[top + 1, 3] = fm
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


__all__ = ["CIRCLE_TOL", "sampled_roots", "trig2_roots"]
