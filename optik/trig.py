"""The trigonometric equation ``a cos t + b sin t = c`` solved with ``atan2`` only.

Seed 000 (section III.B, eq. 19-22) reduces every joint angle of its analytic inverse
kinematics to this one equation. Writing ``a = r cos(phi)``, ``b = r sin(phi)`` with
``r = hypot(a, b)`` and ``phi = atan2(b, a)`` gives ``r cos(t - phi) = c``, so::

    t = atan2(b, a) +/- atan2(sqrt(r^2 - c^2), c)        (eq. 20, verified as printed)

which exists when ``c^2 <= r^2`` (eq. 19). No step divides, and ``atan2`` never meets an
undefined quotient: this is the point of the seed's method. ``c = 0`` gives eq. 22,
``t = atan2(b, a) +/- pi/2``.

Tolerance (``tol``, default :data:`TRIG_TOL` = 1e-12), with ``r = hypot(a, b)``; every
test is linear in the coefficients, so it means the same for a wrist centre 1 m or 1e-7 m
from an axis:

* degenerate coefficients, ``r <= tol``: the equation no longer depends on ``t``.
  If also ``|c| <= tol`` every angle solves it (a free joint, e.g. a shoulder whose wrist
  centre lies on its axis) and the caller's ``free_value`` is returned, wrapped; else
  there is no solution;
* otherwise, with ``gap = (r - |c|) / max(r, 1)``: ``gap < -tol``: no solution;
  ``|gap| <= tol``: one (double, tangent) root ``atan2(b, a) + atan2(0, c)``;
  ``gap > tol``: two roots.

The floor 1 in ``max(r, 1)`` makes the tolerance absolute for coefficients below 1: inputs
are taken to be in SI units (metres), whose rounding errors are absolute at that scale.
Every returned angle then satisfies the equation to a residual
``|a cos t + b sin t - c| <= 2 tol max(1, r)`` (the tangent and degenerate cases; the
two-root case is accurate to a few ulps of ``r + |c|``). Pass ``tol=0`` for exact tests.
(A test on ``r^2`` would take ``r = 1e-7``, ``c = 0`` as free or tangent and answer an
angle a right angle off its two roots ``atan2(b, a) +/- pi/2``.)

The arithmetic is compiled once, in :func:`optik._math.trig_branches` (the closed forms
call the same code); the functions here validate their arguments and call it.
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np

from optik import _math
from optik._checks import FloatArray, as_float_array, check_finite, check_real
from optik.errors import NonFiniteError, ShapeError

__all__ = ["TRIG_TOL", "solve_trig", "solve_trig_batch", "solve_trig_zero", "wrap_angle"]

#: Default tolerance of :func:`solve_trig`, on ``|c| - r`` relative to ``max(r, 1)``.
TRIG_TOL: Final[float] = 1e-12

_TWO_PI: Final[float] = 2.0 * math.pi


def wrap_angle(t: float) -> float:
    """Wrap an angle (rad) into ``(-pi, pi]``.

    Args:
        t: finite angle in radians.

    Returns:
        ``t + 2 pi k`` in ``(-pi, pi]`` for the integer ``k`` that puts it there (the
        exact steps of :func:`optik._math.wrap_angle`: ``fmod`` and one correction).
    """
    return float(_math.wrap_angle(float(t)))


def _scalar(name: str, value: Any) -> float:
    """``value`` as a finite Python float, or an optik error."""
    if isinstance(value, float) and math.isfinite(value):
        return value  # the common case, without the array round trip
    array = as_float_array(name, value)  # rejects bool, complex, strings, None
    if array.shape != ():
        raise ShapeError(name, "() (a scalar)", array.shape)
    x = float(array)
    if not math.isfinite(x):
        raise NonFiniteError(name)
    return x


def _check_tol(tol: Any) -> float:
    """``tol`` as a finite float >= 0 (a bool, complex or string is an error)."""
    return check_real("tol", tol, nonnegative=True)


def solve_trig(
    a: float, b: float, c: float, *, free_value: float = 0.0, tol: float = TRIG_TOL
) -> tuple[float, ...]:
    """Solve ``a cos t + b sin t = c`` for the angle ``t`` (rad), with ``atan2`` only.

    ``t = atan2(b, a) +/- atan2(sqrt(a^2 + b^2 - c^2), c)`` (seed 000, eq. 20); see the
    module docstring for the tolerance rules.

    Args:
        a: coefficient of ``cos t`` (finite).
        b: coefficient of ``sin t`` (finite).
        c: right-hand side (finite), in the units of ``a`` and ``b``.
        free_value: the angle (rad) returned when ``a = b = c = 0`` (within ``tol``),
            where every angle solves the equation: a robotics caller passes its reference
            value (current or mid-range joint angle) to stay there.
        tol: tolerance of the tangent and degenerate tests (>= 0; 0 for exact tests).

    Returns:
        ``()`` when there is no solution (``c^2 > a^2 + b^2``, or ``a = b = 0 != c``);
        one angle for a tangent (double) root or the free case; otherwise two distinct
        angles. Angles are in ``(-pi, pi]``, in ascending order.

    Raises:
        ShapeError: an argument is not a scalar.
        NonFiniteError: an argument is NaN or infinite.
        ArgumentError: ``tol`` is not a finite real number >= 0, or an argument is
            not a real number (bool, complex, string).
    """
    a_f, b_f, c_f = _scalar("a", a), _scalar("b", b), _scalar("c", c)
    free = _math.wrap_angle(_scalar("free_value", free_value))
    count, t1, t2 = _math.trig_roots(a_f, b_f, c_f, free, _check_tol(tol), -1.0, 0.0)
    if count == 0:
        return ()
    if count == 1:
        return (float(t1),)
    return (float(t1), float(t2))


def solve_trig_zero(
    a: float, b: float, *, free_value: float = 0.0, tol: float = TRIG_TOL
) -> tuple[float, ...]:
    """Solve ``a cos t + b sin t = 0`` (seed 000, eq. 21-22): ``t = atan2(b, a) +/- pi/2``.

    The special case ``c = 0`` of :func:`solve_trig`: two angles ``pi`` apart when
    ``hypot(a, b) > tol``, otherwise ``(free_value,)`` (every angle solves it).

    Args:
        a: coefficient of ``cos t``.
        b: coefficient of ``sin t``.
        free_value: the angle (rad) returned when ``a = b = 0`` (within ``tol``).
        tol: tolerance of the degenerate test.

    Returns:
        Two angles in ``(-pi, pi]`` in ascending order, or ``(free_value,)`` wrapped.

    Raises:
        ShapeError: an argument is not a scalar.
        NonFiniteError: an argument is NaN or infinite.
        ArgumentError: ``tol`` is not a finite real number >= 0, or an argument is
            not a real number (bool, complex, string).
    """
    return solve_trig(a, b, 0.0, free_value=free_value, tol=tol)


def solve_trig_batch(
    a: Any, b: Any, c: Any, *, free_value: Any = 0.0, tol: float = TRIG_TOL
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Vectorized :func:`solve_trig`: the two branches ``t+`` and ``t-`` of eq. 20.

    ``a``, ``b``, ``c`` and ``free_value`` broadcast together. Branches keep their sign
    (``t+ = atan2(b, a) + atan2(sqrt(r^2 - c^2), c)``, ``t- = ... - ...``) rather than
    being sorted, so an IK caller can follow one branch along a path. The decisions (no
    root, tangent, free) are exactly those of :func:`solve_trig`.

    Args:
        a: coefficients of ``cos t``, array-like (finite).
        b: coefficients of ``sin t``, array-like (finite).
        c: right-hand sides, array-like (finite).
        free_value: angle(s) returned in both branches where every angle solves it.
        tol: tolerance of the tangent and degenerate tests (>= 0).

    Returns:
        ``(t_plus, t_minus, valid)`` of the broadcast shape: angles in ``(-pi, pi]``
        (``t_plus == t_minus`` for a tangent root or a free joint) and a boolean mask;
        where ``valid`` is False (no solution) both angles are 0, never NaN.

    Raises:
        ShapeError: the arguments do not broadcast together.
        NonFiniteError: an argument holds NaN or infinity.
        ArgumentError: ``tol`` is not a finite real number >= 0, or an argument is
            not a real number (bool, complex, string).
    """
    arrays = [
        check_finite(name, as_float_array(name, value))
        for name, value in (("a", a), ("b", b), ("c", c), ("free_value", free_value))
    ]
    try:
        a_arr, b_arr, c_arr, f_arr = np.broadcast_arrays(*arrays)
    except ValueError as exc:
        shapes = " and ".join(str(x.shape) for x in arrays)
        raise ShapeError("a, b, c", f"shapes that broadcast together, not {shapes}", ()) from exc
    tol = _check_tol(tol)

    # Copies: broadcast views are read-only (and numba warns about passing them).
    a_f, b_f, c_f, free = (
        np.array(x, dtype=np.float64, order="C").reshape(-1) for x in (a_arr, b_arr, c_arr, f_arr)
    )
    out = np.empty((3, a_f.shape[0]))
    _math.trig_branches_batch(a_f, b_f, c_f, free, tol, out)
    shape = a_arr.shape
    valid = (out[0] > 0).reshape(shape)
    return out[1].reshape(shape), out[2].reshape(shape), valid
